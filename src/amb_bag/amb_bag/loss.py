"""Loss accounting: messages the recorder received vs messages the publishers say they published.

Convention (docs/bags.md): every node publishes on /diagnostics a ``diagnostic_msgs/DiagnosticStatus`` whose
``values`` include, for each topic it publishes, ``KeyValue(key="published <topic>", value="<count>")``: the
integer number of messages published on that topic so far.  The recorder keeps the latest count per
(status name, topic) and sums over statuses; per topic

    lost = max(0, published - received),     extra = max(0, received - published)

``extra`` counts messages received after the last report (or from publishers that do not report).  A topic
that nobody reports has ``published = None`` and unknown loss.  Counts published before the recorder subscribed
are counted as lost: start the recorder first.  The recorder's own /diagnostics reports are recorded but left
out of the /diagnostics row.
"""

from __future__ import annotations

import json

DIAGNOSTICS_TOPIC = "/diagnostics"
DIAGNOSTICS_TYPE = "diagnostic_msgs/msg/DiagnosticArray"
KEY_PREFIX = "published "
CUSTOM_KEY = "amb_bag.loss"
CUSTOM_TOTAL_KEY = "amb_bag.lost_total"
RECORDER_NAME = "amb_bag_recorder"  # the recorder's node name and the name of its /diagnostics status


def _topic(name: str) -> str:
    name = name.strip()
    return name if name.startswith("/") else "/" + name


class LossTracker:
    """Latest ``published <topic>`` count per (status name, topic), from /diagnostics messages."""

    def __init__(self):
        self.reported: dict[tuple[str, str], int] = {}
        self.reports = 0

    def update_from_cdr(self, data: bytes, own_name: str | None = None) -> bool:
        """Parse one serialized DiagnosticArray (bad messages are ignored: they are recorded anyway).

        Returns True if every status in it is named ``own_name`` (the recorder's own report).
        """
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.serialization import deserialize_message

        try:
            msg = deserialize_message(data, DiagnosticArray)
        except Exception:  # rclpy raises plain RuntimeError-like errors for undecodable CDR
            return False
        self.update((s.name, ((kv.key, kv.value) for kv in s.values)) for s in msg.status)
        return bool(msg.status) and all(s.name == own_name for s in msg.status)

    def update(self, statuses) -> None:
        """``statuses``: iterable of (status name, iterable of (key, value)) pairs."""
        for name, values in statuses:
            for key, value in values:
                if not key.startswith(KEY_PREFIX):
                    continue
                try:
                    count = int(value)
                except ValueError:
                    continue
                if count >= 0:
                    self.reported[(name, _topic(key[len(KEY_PREFIX) :]))] = count
                    self.reports += 1

    def published(self) -> dict[str, int]:
        """Sum over reporting statuses of the latest count, per topic."""
        total: dict[str, int] = {}
        for (_, topic), count in self.reported.items():
            total[topic] = total.get(topic, 0) + count
        return total

    def table(self, received: dict[str, int], gaps: dict[str, int] | None = None) -> dict[str, dict]:
        """Per topic: received, published (None if unreported), lost and extra (None if unknown)."""
        return loss_table(received, self.published(), gaps)


def loss_table(received: dict[str, int], published: dict[str, int], gaps: dict[str, int] | None = None) -> dict:
    """Per-topic loss rows from received and published counts (see the module docstring).

    ``gaps``: the recorder's own count of samples missing from the stamp grid of a per-step topic
    (:mod:`amb_bag.stamp_gaps`); a row's ``lost`` is the larger of the two counts, and with no published count
    it is the gap count (a lower bound: losses after the last stamp received are not seen).
    """
    rows = {}
    gaps = gaps or {}
    for topic in sorted(set(received) | set(published)):
        got, sent, gap = received.get(topic, 0), published.get(topic), gaps.get(topic)
        lost = None if sent is None else max(0, sent - got)
        if gap is not None:
            lost = gap if lost is None else max(lost, gap)
        rows[topic] = {
            "received": got,
            "published": sent,
            "lost": lost,
            "extra": None if sent is None else max(0, got - sent),
        }
        if gap:  # only when the recorder saw a gap of its own
            rows[topic]["stamp_gaps"] = gap
    return rows


def total_lost(rows: dict[str, dict]) -> int:
    """Sum of the known losses; see :func:`unknown_topics` for the rows whose loss nobody can tell."""
    return sum(r["lost"] or 0 for r in rows.values())


def unknown_topics(rows: dict[str, dict]) -> list[str]:
    """Topics whose loss is unknown (no publisher reports a count, no stamp grid): never summed as 0."""
    return [t for t, r in rows.items() if r["lost"] is None]


def total_text(rows: dict[str, dict]) -> str:
    """``lost in total: N``, and which topics' loss is unknown (instead of counting them as 0)."""
    unknown = unknown_topics(rows)
    if not unknown:
        return f"lost in total: {total_lost(rows)}"
    shown = ", ".join(unknown[:6]) + (", ..." if len(unknown) > 6 else "")
    if len(unknown) == len(rows):
        return f"lost in total: unknown (no count for {shown})"
    return (
        f"lost in total: {total_lost(rows)} on {len(rows) - len(unknown)} topics; unknown on {len(unknown)} "
        f"without a count ({shown})"
    )


def custom_data(rows: dict[str, dict]) -> dict[str, str]:
    """The metadata.yaml custom_data entries (strings, as rosbag2 requires) for the loss rows."""
    total = str(total_lost(rows)) if not unknown_topics(rows) else f"at least {total_lost(rows)} (some unknown)"
    return {CUSTOM_KEY: json.dumps(rows, separators=(",", ":")), CUSTOM_TOTAL_KEY: total}


def format_table(rows: dict[str, dict]) -> str:
    """Human-readable loss table."""
    if not rows:
        return "loss: no topics"
    width = max(len(t) for t in rows)
    lines = [f"{'topic':<{width}}  {'received':>9}  {'published':>9}  {'lost':>7}  {'extra':>6}"]
    for topic, r in rows.items():
        sent = "?" if r["published"] is None else str(r["published"])
        lost = "?" if r["lost"] is None else str(r["lost"])
        extra = "?" if r["extra"] is None else str(r["extra"])
        lines.append(f"{topic:<{width}}  {r['received']:>9}  {sent:>9}  {lost:>7}  {extra:>6}")
    lines.append(total_text(rows))
    return "\n".join(lines)
