"""Test publisher: the rig's topic mix as raw CDR, paced or flat out, logging every message it sent.

    python tests/bagtools/publisher.py --steps 2000 --rate 1000 --log sent.pkl [--wait-subscribers 10]

Publishes /stability/unstable once (latched), then per step the lockstep mix of :mod:`mix`, and /diagnostics
every ``--diag-every`` steps plus once at the end, with ``published <topic>`` counts.  Writes the log
(pickled list of ``(topic, bytes)`` in publish order) and prints ``publisher: done <n>``.
"""

from __future__ import annotations

import argparse
import pickle
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import mix


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--steps", type=int, default=1000)
    p.add_argument("--rate", type=float, default=1000.0, help="steps/s; 0 = flat out")
    p.add_argument("--diag-every", type=int, default=100, help="steps between /diagnostics (0 = none at all)")
    p.add_argument("--log", type=Path)
    p.add_argument("--wait-subscribers", type=float, default=0.0, help="wait up to S s for a subscriber per topic")
    p.add_argument("--best-effort", action="store_true")
    p.add_argument("--depth", type=int, default=1000)
    p.add_argument("--name", default="bag_test_publisher", help="node name, also the diagnostics status name")
    p.add_argument(
        "--settle-first",
        type=float,
        default=0.0,
        help="after step 0: wait until every reader has acknowledged it, then S s (a slow reader takes it)",
    )
    p.add_argument("--linger", type=float, default=0.5, help="seconds to stay alive after the last message")
    args = p.parse_args()

    from amb_ros.env import ensure_localhost_dds

    ensure_localhost_dds()
    import rclpy
    from rclpy.duration import Duration
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    from amb_bag.msgdefs import message_class

    rclpy.init()
    node = rclpy.create_node(args.name, enable_rosout=False)
    rel = ReliabilityPolicy.BEST_EFFORT if args.best_effort else ReliabilityPolicy.RELIABLE
    pubs = {}
    for topic, type_name in mix.TOPICS.items():
        latched = topic == "/stability/unstable"
        qos = QoSProfile(
            depth=1 if latched else args.depth,
            reliability=ReliabilityPolicy.RELIABLE if latched else rel,
            durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
        )
        pubs[topic] = node.create_publisher(message_class(type_name), topic, qos)
    end = time.monotonic() + args.wait_subscribers
    while time.monotonic() < end and any(p.get_subscription_count() == 0 for p in pubs.values()):
        time.sleep(0.02)
    print(f"publisher: subscribed {sum(p.get_subscription_count() > 0 for p in pubs.values())}", flush=True)

    sent: list[tuple[str, bytes]] = []
    counts = dict.fromkeys(mix.TOPICS, 0)

    def publish(topic, msg):
        data = mix.serialize(msg, mix.TOPICS[topic])
        pubs[topic].publish(data)
        counts[topic] += 1
        sent.append((topic, data))

    def publish_diagnostics(k):
        counts["/diagnostics"] += 1  # the count includes this message
        msg = mix.diagnostics_message(k, counts, name=args.name)
        counts["/diagnostics"] -= 1
        publish("/diagnostics", msg)

    publish("/stability/unstable", mix.unstable_message(False))
    t0 = time.monotonic()
    for k in range(args.steps):
        for topic, _, msg in mix.step_messages(k):
            publish(topic, msg)
        if k == 0 and args.settle_first > 0:
            for pub in pubs.values():
                pub.wait_for_all_acked(Duration(seconds=5))
            time.sleep(args.settle_first)
        if args.diag_every and k % args.diag_every == args.diag_every - 1:
            publish_diagnostics(k)
        if args.rate > 0:
            delay = t0 + (k + 1) / args.rate - time.monotonic()
            if delay > 0:
                time.sleep(delay)
    if args.diag_every:  # 0: a publisher that never reports a count
        publish_diagnostics(args.steps)
    for pub in pubs.values():
        pub.wait_for_all_acked(Duration(seconds=5))
    if args.log:
        args.log.write_bytes(pickle.dumps(sent))
    print(f"publisher: done {len(sent)}", flush=True)
    time.sleep(args.linger)
    node.destroy_node()
    rclpy.try_shutdown()


if __name__ == "__main__":
    main()
