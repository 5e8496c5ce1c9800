"""``amb-bag play``: publish a bag's topics with their recorded timing (scaled by ``--rate``) and QoS.

Messages are published raw (the recorded CDR bytes, never deserialized), in log-time order, each at
``t0 + (log_time - start) / rate``.  Publishers offer the recorded QoS (reliability and durability of the
recorded offers when all publishers agreed, as rosbag2 does) with a deep KEEP_LAST history.

Time: a recorded /clock (the lockstep plant's simulated time) is replayed like any topic, so nodes with
``use_sim_time`` see the same times as in the live run.  ``--clock HZ`` instead publishes /clock from the bag's
log time at about HZ (and drops a recorded /clock), for bags without one.
"""

from __future__ import annotations

import signal
import time
from dataclasses import dataclass
from pathlib import Path

from . import msgdefs
from .errors import BagError
from .qos import offer_for_playback
from .reader import Bag

CLOCK_TOPIC = "/clock"
CLOCK_TYPE = "rosgraph_msgs/msg/Clock"
ACK_TIMEOUT_S = 5.0


@dataclass
class PlayOptions:
    bag: Path
    rate: float = 1.0
    topics: list[str] | None = None
    loop: bool = False
    clock_hz: float | None = None
    wait_subscribers_s: float = 0.0
    start_delay_s: float = 0.2


def play(opts: PlayOptions) -> int:
    """Play the bag; returns the number of messages published (stops cleanly on SIGINT/SIGTERM)."""
    if not 1e-3 <= opts.rate <= 1e6:  # also refuses NaN; 1e-300 would ask to sleep past the end of time
        raise BagError(f"--rate must be in 0.001..1e6, got {opts.rate}")
    if opts.clock_hz is not None and not 0 < opts.clock_hz <= 1e5:
        raise BagError(f"--clock must be in (0, 1e5] Hz, got {opts.clock_hz}")
    for name, value in (("--delay", opts.start_delay_s), ("--wait-for-subscribers", opts.wait_subscribers_s)):
        if not 0 <= value <= 3600:
            raise BagError(f"{name} must be in 0..3600 s, got {value}")
    bag = Bag(opts.bag)
    topics = [t for t in bag.select(opts.topics) if bag.topics[t].message_count]  # nothing to publish otherwise
    if opts.clock_hz is not None:
        topics = [t for t in topics if t != CLOCK_TOPIC]
    for t in topics:
        msgdefs.message_class(bag.topics[t].type)  # fail before starting DDS if a type is not installed
    if bag.message_count == 0:
        raise BagError(f"{opts.bag} holds no messages")

    from amb_ros.env import ensure_localhost_dds
    from amb_ros.fastdds import init_rclpy

    ensure_localhost_dds()
    import rclpy
    from rclpy.duration import Duration
    from rclpy.qos import ReliabilityPolicy
    from rclpy.signals import SignalHandlerOptions

    init_rclpy(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("amb_bag_player", enable_rosout=False, start_parameter_services=False)
    stop = {"now": False}

    def request_stop(_signum, _frame):
        stop["now"] = True

    previous = {s: signal.signal(s, request_stop) for s in (signal.SIGINT, signal.SIGTERM)}
    published = 0
    try:
        pubs = {}
        for t in topics:
            info = bag.topics[t]
            pubs[t] = node.create_publisher(msgdefs.message_class(info.type), t, offer_for_playback(
                info.offered_qos_profiles))  # fmt: skip
        clock_pub = None
        if opts.clock_hz is not None:
            clock_cls = msgdefs.message_class(CLOCK_TYPE)
            clock_pub = node.create_publisher(clock_cls, CLOCK_TOPIC, offer_for_playback([]))
        _wait_for_subscribers(pubs, opts.wait_subscribers_s, stop)
        time.sleep(opts.start_delay_s)
        while not stop["now"]:
            published += _play_once(bag, topics, pubs, clock_pub, opts, stop)
            if not opts.loop:
                break
        for pub in pubs.values():
            if pub.qos_profile.reliability == ReliabilityPolicy.RELIABLE:
                pub.wait_for_all_acked(Duration(seconds=ACK_TIMEOUT_S))
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        node.destroy_node()
        rclpy.try_shutdown()
    print(f"amb-bag play: published {published} messages", flush=True)
    return published


def _wait_for_subscribers(pubs: dict, timeout_s: float, stop: dict) -> None:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end and not stop["now"] and any(p.get_subscription_count() == 0 for p in pubs.values()):
        time.sleep(0.02)


def _play_once(bag: Bag, topics, pubs, clock_pub, opts: PlayOptions, stop: dict) -> int:
    """One pass over the bag with the original spacing scaled by the rate."""
    start_ns = bag.start_ns
    t0 = time.monotonic()
    clock_period_ns = int(1e9 / opts.clock_hz) if opts.clock_hz else None
    next_clock_ns = start_ns
    n = 0
    for topic, _type, log_ns, _pub_ns, data in bag.messages(topics):
        if stop["now"]:
            break
        delay = t0 + (log_ns - start_ns) * 1e-9 / opts.rate - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        if clock_pub is not None and log_ns >= next_clock_ns:
            clock_pub.publish(_clock(clock_pub.msg_type, log_ns))
            next_clock_ns = log_ns + clock_period_ns
        pubs[topic].publish(data)
        n += 1
    return n


def _clock(cls, ns: int):
    msg = cls()
    msg.clock.sec, msg.clock.nanosec = ns // 1_000_000_000, ns % 1_000_000_000
    return msg
