"""Recorder node: every topic (or a list) to a rosbag2-layout MCAP bag, raw, with loss accounting.

``amb-bag record -o DIR`` here, ``ros2 run amb_bag record -o DIR`` with a ROS install.  The recorder

- scans the ROS graph every ``--discovery-interval`` seconds and subscribes to each new topic that has a
  publisher (late publishers are found the same way);
- subscribes **raw** (serialized CDR bytes, never deserialized) with a QoS matched to the offered profiles
  (reliable / transient-local only if every publisher is, as rosbag2 does) and KEEP_ALL history, so that a
  reliable publisher is slowed down rather than a sample dropped when the recorder falls behind;
- does not use an rclpy executor: one wait set over all subscriptions, and each ready subscription is drained
  with ``take_message`` (about 7x faster than executor callbacks, measured); messages go straight into the
  chunked MCAP writer, with log_time = DDS reception time and publish_time = DDS source time (as rosbag2);
- reads /diagnostics ``published <topic>`` counts for the loss table (:mod:`amb_bag.loss`);
- every ``--flush-interval`` seconds finishes the open chunk, so that a ``kill -9`` loses at most that
  interval or one chunk (``amb-bag check`` recovers the rest), and every ``--progress-interval`` seconds
  writes a small progress file (counts received, on disk, published), from which ``amb-bag check`` tells how
  many received messages a crash lost;
- on SIGINT/SIGTERM (or after ``--duration``) drains what is pending, writes the last chunk, the summary and
  metadata.yaml, prints the loss table, and exits 0.

Its stdout lines ``amb-bag record: subscribed <topic> [<type>]`` tell a supervisor (``amb-rig``) when a topic
is being recorded.  Node ``amb_bag_recorder`` reports on /diagnostics every second (received counts, total lost)
and once more, ``final``, after the bag is closed.
"""

from __future__ import annotations

import argparse
import contextlib
import re
import signal
import sys
import time
from dataclasses import dataclass

from . import msgdefs
from .errors import BagError
from .loss import DIAGNOSTICS_TOPIC, RECORDER_NAME, LossTracker, custom_data, format_table
from .qos import RECORD_DEPTH, profile_to_dict, request_for_offers
from .record_options import PRIORITIES, RecordOptions, add_record_arguments, options_from_args
from .stamp_gaps import GRID_TOPICS, StampGaps
from .writer import BagWriter

DRAIN_BATCH = 2000  # messages taken from one subscription before the others get a turn
BUSY_DRAIN = 1000  # a drain this large means the recorder is behind: take the next batch without pausing
WAIT_MAX_S = 0.05  # longest wait, so that signals, discovery and checkpoints are served promptly
PREFIX = "amb-bag record:"
NODE_NAME = RECORDER_NAME
DIAGNOSTICS_PERIOD_S = 1.0


def _hidden(topic: str) -> bool:
    return any(part.startswith("_") for part in topic.split("/"))


class Recorder:
    """Subscriptions, the drain loop and the writer of one recording (needs an initialised rclpy context)."""

    def __init__(self, node, opts: RecordOptions, writer: BagWriter, log=print, diagnostics=None):
        from rclpy.impl.implementation_singleton import rclpy_implementation

        self._rclpy = rclpy_implementation
        self.node, self.opts, self.writer, self.log = node, opts, writer, log
        self.diagnostics = diagnostics  # amb_ros.diagnostics.Diagnostics or None
        self.loss = LossTracker()
        self.gaps = StampGaps()  # the recorder's own count of missed samples on the per-step topics
        self.own_reports = 0  # this recorder's /diagnostics messages that it recorded
        self.subs: list[_Sub] = []
        self.by_topic: dict[str, _Sub] = {}
        self.ignored: set[str] = set()
        self.stop_requested = False
        self._wait_set = None
        self._wanted = {_normalise(t) for t in opts.topics} if opts.topics else None
        self._exclude = [re.compile(p) for p in opts.exclude]
        self.scheduling = "normal"
        self._cpu0 = time.process_time()  # after start-up: the CPU the recording takes (all threads, DDS's too)

    # -- discovery ------------------------------------------------------------------------------------------
    def wanted(self, topic: str) -> bool:
        if self._wanted is not None:
            return topic in self._wanted
        if _hidden(topic) and not self.opts.include_hidden:
            return False
        return not any(p.search(topic) for p in self._exclude)

    def discover(self) -> None:
        """Subscribe to new topics that have publishers; widen QoS if an incompatible publisher joined."""
        for topic, types in self.node.get_topic_names_and_types():
            if topic in self.ignored or not self.wanted(topic):
                continue
            sub = self.by_topic.get(topic)
            if sub is not None:
                if self.node.count_publishers(topic) != sub.publishers:
                    self._revisit(sub)
                continue
            if len(types) != 1:
                self._ignore(topic, f"has several types {types}")
                continue
            infos = self._publishers(topic)
            if infos:
                self._subscribe(topic, types[0], infos)

    def _publishers(self, topic: str) -> list:
        """Publishers of ``topic`` other than this recorder's own node (its /parameter_events)."""
        me = (self.node.get_name(), self.node.get_namespace())
        return [i for i in self.node.get_publishers_info_by_topic(topic) if (i.node_name, i.node_namespace) != me]

    def _ignore(self, topic: str, why: str) -> None:
        self.ignored.add(topic)
        self.log(f"{PREFIX} not recording {topic}: {why}", file=sys.stderr)

    def _subscribe(self, topic: str, type_name: str, infos) -> None:
        try:
            cls = msgdefs.message_class(type_name)
            msgdefs.full_text(type_name)
        except BagError as exc:
            self._ignore(topic, str(exc))
            return
        profiles = [profile_to_dict(i.qos_profile) for i in infos]
        type_hash = str(infos[0].topic_type_hash)
        tid = self.writer.add_topic(topic, type_name, profiles, type_hash if type_hash.startswith("RIHS") else "")
        sub = _Sub(topic, type_name, cls, tid, topic == DIAGNOSTICS_TOPIC, profiles, on_grid=topic in GRID_TOPICS)
        sub.publishers = self.node.count_publishers(topic)
        self._create(sub)
        self.subs.append(sub)
        self.by_topic[topic] = sub
        self._wait_set = None
        self.log(f"{PREFIX} subscribed {topic} [{type_name}]", flush=True)

    def _create(self, sub: _Sub) -> None:
        qos = request_for_offers(
            sub.offers, keep_all=self.opts.qos_depth is None, depth=self.opts.qos_depth or RECORD_DEPTH
        )
        sub.rel_dur = (qos.reliability, qos.durability)
        sub.handle_owner = self.node.create_subscription(sub.cls, sub.topic, _ignore_message, qos, raw=True)
        sub.handle = sub.handle_owner.handle

    def _revisit(self, sub: _Sub) -> None:
        infos = self._publishers(sub.topic)
        sub.publishers = self.node.count_publishers(sub.topic)
        offers = sub.offers + [profile_to_dict(i.qos_profile) for i in infos]
        qos = request_for_offers(offers, keep_all=True)
        if (qos.reliability, qos.durability) == sub.rel_dur:
            return
        # A publisher joined that the current subscription cannot match: widen the QoS (the bag keeps the
        # channel's original offered profiles, as rosbag2 does). Messages pending in the old one are kept.
        self._drain(sub, limit=None)
        self.node.destroy_subscription(sub.handle_owner)
        sub.offers = offers
        self._create(sub)
        self._wait_set = None
        self.log(f"{PREFIX} {sub.topic}: new publisher QoS, subscription widened", file=sys.stderr)

    # -- the hot path -----------------------------------------------------------------------------------------
    def _drain(self, sub: _Sub, limit: int | None = DRAIN_BATCH) -> int:
        take, cls, write, tid = sub.handle.take_message, sub.cls, self.writer.write, sub.tid
        delay, n = self.opts.debug_delay_s, 0
        while limit is None or n < limit:
            taken = take(cls, True)
            if taken is None:
                break
            data, info = taken
            recv = info["received_timestamp"] or time.time_ns()
            write(tid, recv, data, info["source_timestamp"] or recv, info["publication_sequence_number"] & 0xFFFFFFFF)
            if sub.is_diagnostics and self.loss.update_from_cdr(data, self.node.get_name()):
                self.own_reports += 1
            elif sub.on_grid:
                self.gaps.add(sub.topic, data)
            n += 1
            if delay:
                time.sleep(delay)
        return n

    def _wait_and_drain(self, timeout_s: float) -> int:
        if not self.subs:
            time.sleep(timeout_s)
            return 0
        if self._wait_set is None:
            self._wait_set = self._rclpy.WaitSet(len(self.subs), 0, 0, 0, 0, 0, self.node.context.handle)
        ws = self._wait_set
        ws.clear_entities()
        for sub in self.subs:
            ws.add_subscription(sub.handle)
        ws.wait(int(timeout_s * 1e9))
        ready = ws.get_ready_entities("subscription")
        return sum(self._drain(sub) for sub in self.subs if sub.handle.pointer in ready)

    # -- loop, checkpoints, summary -------------------------------------------------------------------------
    def received(self) -> dict[str, int]:
        return {t.name: t.message_count for t in self.writer.topics}

    def received_from_others(self) -> dict[str, int]:
        """Received counts for the loss table: without the recorder's own /diagnostics reports."""
        counts = self.received()
        if DIAGNOSTICS_TOPIC in counts:
            counts[DIAGNOSTICS_TOPIC] -= self.own_reports
        return counts

    def write_progress(self) -> None:
        self.writer.write_progress({"received": self.received_from_others(), "published": self.loss.published(),
                                    "time_ns": time.time_ns()})  # fmt: skip

    def spin(self) -> None:
        """Record until :attr:`stop_requested` (set by a signal) or the duration elapses."""
        now = time.monotonic()
        end = now + self.opts.duration_s if self.opts.duration_s else float("inf")
        next_scan = next_flush = next_progress = now
        while not self.stop_requested and now < end:
            if now >= next_scan:
                self.discover()
                next_scan = now + self.opts.discovery_interval_s
            if now >= next_flush:
                self.writer.flush()
                next_flush = now + self.opts.flush_interval_s
            if now >= next_progress:
                self.write_progress()
                next_progress = now + self.opts.progress_interval_s
            if self.diagnostics is not None and self.diagnostics.due():
                self.publish_status()
            timeout = min(WAIT_MAX_S, next_scan - now, next_flush - now, next_progress - now, end - now)
            taken = self._wait_and_drain(max(0.0, timeout))
            if 0 < taken < BUSY_DRAIN and self.opts.batch_s:
                time.sleep(self.opts.batch_s)  # let messages gather: one wake-up per batch, not per message
            now = time.monotonic()
        # Take what is already delivered, then a last short wait for messages still in flight.
        while self._wait_and_drain(0.02):
            pass

    def status(self, rows: dict | None = None) -> tuple[int, str, dict]:
        """(level, message, values) of the recorder's /diagnostics status; levels as diagnostic_msgs (0 OK, 1 WARN)."""
        rows = self.loss.table(self.received_from_others(), self.gaps.missing()) if rows is None else rows
        lost = sum(r["lost"] or 0 for t, r in rows.items() if self.wanted(t))
        values = {f"received {t}": str(n) for t, n in sorted(self.received().items())}
        values.update({"messages written": str(self.writer.message_count), "lost total": str(lost),
                       "cpu time (s)": f"{time.process_time() - self._cpu0:.3f}", "scheduling": self.scheduling,
                       "bag": str(self.opts.output)})  # fmt: skip
        message = f"{self.writer.message_count} messages on {len(self.writer.topics)} topics, lost {lost}"
        return (1 if lost else 0), message, values

    def publish_status(self, rows: dict | None = None, final: bool = False) -> None:
        level, message, values = self.status(rows)
        if final:
            self.diagnostics.publish_final(bytes([level]), message, values)
        else:
            self.diagnostics.publish(bytes([level]), message, values)

    def report_write_error(self, exc: OSError) -> None:
        """Publish the final status as an ERROR: the error, what reached the disk, the loss known so far."""
        rows = self.loss.table(self.received_from_others(), self.gaps.missing())
        received = sum(self.received_from_others().values())
        on_disk = sum(self.writer._on_disk)  # messages in chunks already on disk (what `check` will recover)
        values = {"write error": f"{exc.strerror or exc} ({getattr(exc, 'filename', '') or self.opts.output})",
                  "received": str(received), "lost total": str(sum(r["lost"] or 0 for r in rows.values()))}  # fmt: skip
        values["messages on disk"] = str(on_disk)
        message = (f"write error: {exc.strerror or exc}; the bag is incomplete: {on_disk} of {received} messages "
                   f"received reached the disk, lost at least {received - on_disk}; run `amb-bag check`")  # fmt: skip
        if self.diagnostics is not None:
            with contextlib.suppress(Exception):
                self.diagnostics.publish_final(bytes([2]), message, values)

    def finish(self) -> dict:
        """Close the bag with the loss table in custom_data; returns the loss rows."""
        table = self.loss.table(self.received_from_others(), self.gaps.missing())
        rows = {t: r for t, r in table.items() if self.wanted(t)}
        self.writer.close(custom_data(rows))
        return rows


@dataclass(eq=False)
class _Sub:
    topic: str
    type_name: str
    cls: type
    tid: int
    is_diagnostics: bool
    offers: list[dict]
    publishers: int = 0
    rel_dur: tuple = ()
    handle_owner: object = None
    handle: object = None
    on_grid: bool = False  # a per-step topic: stamp gaps counted


def _ignore_message(_msg) -> None:
    """Callback of the raw subscriptions; never called (no executor spins them)."""


def _normalise(topic: str) -> str:
    return topic if topic.startswith("/") else "/" + topic


def record(opts: RecordOptions) -> dict:
    """Run a recording until SIGINT/SIGTERM or ``duration``; returns the loss rows."""
    from amb_ros.env import ensure_localhost_dds
    from amb_ros.fastdds import init_rclpy

    ensure_localhost_dds()
    if opts.priority not in PRIORITIES:
        raise BagError(f"unknown priority {opts.priority!r} (choose {', '.join(PRIORITIES)})")
    writer = BagWriter(
        opts.output, opts.compression, opts.chunk_size,
        split_size=int(opts.split_size_mb * 1e6) if opts.split_size_mb else None,
        split_duration_ns=int(opts.split_duration_s * 1e9) if opts.split_duration_s else None,
    )  # fmt: skip
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    from amb_ros.diagnostics import Diagnostics
    from amb_ros.scheduling import consumer_priority

    init_rclpy(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(NODE_NAME, enable_rosout=False, start_parameter_services=False)
    # a named collector (amb-rig's) must hear the final report, an error's too: it waits for that reader
    collector = opts.diagnostics_collector
    diagnostics = Diagnostics(
        node, period_s=DIAGNOSTICS_PERIOD_S, min_readers=int(bool(collector)), collector=collector
    )
    recorder = Recorder(node, opts, writer, diagnostics=diagnostics)
    recorder.scheduling = consumer_priority(opts.priority)  # after the node exists: its DDS threads are included

    def request_stop(_signum, _frame):
        recorder.stop_requested = True

    previous = {s: signal.signal(s, request_stop) for s in (signal.SIGINT, signal.SIGTERM)}
    rows = None
    try:
        print(f"{PREFIX} recording to {opts.output}", flush=True)
        recorder.spin()
        rows = recorder.finish()
        recorder.publish_status(rows, final=True)  # after the bag is closed: amb-rig's summary reads it
    except OSError as exc:  # disk full, folder gone: the row is an ERROR with what is lost, then one line
        recorder.report_write_error(exc)
        raise OSError(
            exc.errno, f"{exc.strerror}; the bag is incomplete, run `amb-bag check`", str(opts.output)
        ) from None
    finally:
        if rows is None:  # a bug stopped the recording: still finish the file rather than leave it open
            with contextlib.suppress(Exception):
                writer.close()
        for s, handler in previous.items():
            signal.signal(s, handler)
        node.destroy_node()
        rclpy.try_shutdown()
    total = writer.message_count
    print(f"{PREFIX} wrote {total} messages on {len(writer.topics)} topics to {opts.output}")
    print(format_table(rows), flush=True)
    return rows


def main(argv: list[str] | None = None) -> None:
    """ROS executable ``record`` (``ros2 run amb_bag record -o DIR ...``)."""
    from rclpy.utilities import remove_ros_args

    argv = remove_ros_args(sys.argv if argv is None else ["record", *argv])[1:]
    parser = argparse.ArgumentParser(prog="record", description="Record topics to a rosbag2-layout MCAP bag.")
    add_record_arguments(parser)
    try:
        record(options_from_args(parser.parse_args(argv)))
    except BagError as exc:
        raise SystemExit(f"amb-bag record: {exc}") from None


if __name__ == "__main__":
    main()
