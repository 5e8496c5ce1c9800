"""``amb-bag``: record, info, check, play and plot MCAP bags in rosbag2 layout.

    amb-bag record -o DIR [--topics T ...] [--compression zstd|lz4|none] [--split-size MB] [--split-duration S]
                          [--chunk-size BYTES] [--flush-interval S] [--duration S]
    amb-bag info BAG [--json]
    amb-bag check BAG [--dry-run] [--json]     exit 0: intact, 2: damaged (recovered unless --dry-run)
    amb-bag play BAG [--rate R] [--topics T ...] [--loop] [--clock [HZ]]
    amb-bag plot BAG --out run.png [--config rotor.yaml]
    amb-bag sensitivity BAG --axis amb1_y [--config F] [--set K=V] [--band lo:hi] [--json] [--out S.png]

User errors (missing, empty, truncated or foreign files, bad options) print one line and exit 2; a write
error (disk full) prints one line and exits 1.
"""

from __future__ import annotations

import argparse
import json
import sys

from .errors import BagError

EXIT_DAMAGED = 2
EXIT_BAD_INPUT = 2


def _cmd_record(args) -> int:
    from .record_options import options_from_args
    from .recorder import record

    record(options_from_args(args))
    return 0


def _cmd_info(args) -> int:
    from .info import bag_info, format_info

    info = bag_info(args.bag)
    print(json.dumps({"schema_version": 1, **info}, indent=2) if args.json else format_info(info))
    return 0


def _cmd_check(args) -> int:
    from .recover import check

    report = check(args.bag, repair=not args.dry_run)
    if args.json:
        print(json.dumps({"schema_version": 1, **report}, indent=2))
    else:
        print(_format_check(report))
    return 0 if report["status"] == "ok" else EXIT_DAMAGED


def _format_check(report: dict) -> str:
    verb = {"ok": "intact", "recovered": "recovered", "damaged": "damaged (not repaired: --dry-run)"}
    lines = [f"{report['bag']}: {verb[report['status']]}"]
    for name, f in report["files"].items():
        lines.append(f"  {name}: {f['messages']} messages" + (f" ({f['problem']})" if f["problem"] else ""))
    if report["status"] != "ok":
        lines.append(f"  {'topic':<32} {'recovered':>9} {'received':>9} {'published':>9} {'lost>=':>7}")
        for topic, r in report["topics"].items():
            rec, pub = r["received"], r["published"]
            lines.append(f"  {topic:<32} {r['recovered']:>9} {'?' if rec is None else rec:>9} "
                         f"{'?' if pub is None else pub:>9} {r['lost_at_least']:>7}")  # fmt: skip
        lines.append(f"recovered {report['recovered_messages']} messages; lost at least {report['lost_at_least']}")
    return "\n".join(lines)


def _cmd_play(args) -> int:
    from .player import PlayOptions, play

    play(PlayOptions(args.bag, rate=args.rate, topics=args.topics, loop=args.loop, clock_hz=args.clock,
                     wait_subscribers_s=args.wait_for_subscribers, start_delay_s=args.delay))  # fmt: skip
    return 0


def _cmd_plot(args) -> int:
    from .plot import plot_bag

    out = plot_bag(args.bag, args.out, config=args.config)
    print(f"wrote {out}")
    return 0


def _cmd_sensitivity(args) -> int:
    from .sensitivity import run_bag_sensitivity

    return run_bag_sensitivity(args)


def build_parser() -> argparse.ArgumentParser:
    from .record_options import add_record_arguments

    parser = argparse.ArgumentParser(prog="amb-bag", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    rec = sub.add_parser("record", help="record topics to a new bag")
    add_record_arguments(rec)
    rec.set_defaults(func=_cmd_record)
    info = sub.add_parser("info", help="topics, types, counts, duration (like ros2 bag info)")
    info.add_argument("bag")
    info.add_argument("--json", action="store_true")
    info.set_defaults(func=_cmd_info)
    chk = sub.add_parser("check", help="verify a bag; recover a crashed recording")
    chk.add_argument("bag")
    chk.add_argument("--dry-run", action="store_true", help="report only, change nothing")
    chk.add_argument("--json", action="store_true")
    chk.set_defaults(func=_cmd_check)
    ply = sub.add_parser("play", help="publish the recorded topics with their timing and QoS")
    ply.add_argument("bag")
    ply.add_argument("--rate", type=float, default=1.0, help="playback speed factor (default 1)")
    ply.add_argument("--topics", nargs="+", metavar="TOPIC")
    ply.add_argument("--loop", action="store_true")
    ply.add_argument("--clock", nargs="?", type=float, const=100.0, metavar="HZ",
                     help="publish /clock from bag time at HZ (default 100), not a recorded /clock")  # fmt: skip
    ply.add_argument("--wait-for-subscribers", type=float, default=0.0, metavar="S",
                     help="wait up to S s until every topic has a subscriber")  # fmt: skip
    ply.add_argument("--delay", type=float, default=0.2, metavar="S", help="pause before the first message")
    ply.set_defaults(func=_cmd_play)
    plt = sub.add_parser("plot", help="displacements vs air gap, currents, base attitude, rho over time")
    plt.add_argument("bag")
    plt.add_argument("--out", required=True, help="PNG file to write")
    plt.add_argument(
        "--config",
        help="rotor config for the air gap (default: the run's own, recorded in the bag on "
        "/amb_plant/config, else the default config)",
    )
    plt.set_defaults(func=_cmd_plot)
    sen = sub.add_parser("sensitivity", help="measured sensitivity S_jj of a recorded injection (ISO 14839-3)")
    sen.add_argument("bag")
    sen.add_argument("--axis", required=True, help="AMB axis of the injection, e.g. amb1_y")
    sen.add_argument("--resolution", type=float, default=0.5, help="frequency resolution (Hz) = 1/segment length")
    sen.add_argument("--settle", type=float, default=1.0, help="s after the injection's start left out (transient)")
    sen.add_argument("--band", default=None, help="lo:hi (Hz); default: every bin the injection excites")
    sen.add_argument(
        "--config",
        help="rotor config of the run: the model of the digital loop is shown beside "
        "(default: the run's own, recorded in the bag on /amb_plant/config)",
    )
    sen.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="config override of the run")
    sen.add_argument("--json", action="store_true")
    sen.add_argument("--out", help="PNG: measured and model |S| with the zone bands, coherence")
    sen.set_defaults(func=_cmd_sensitivity)
    return parser


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(sys.argv[1:] if argv is None else argv)
    try:
        rc = args.func(args)
    except BagError as exc:  # bad input or refusal: one line, exit 2 (docs/exit-codes.md)
        print(f"amb-bag {args.command}: {exc}", file=sys.stderr)
        rc = EXIT_BAD_INPUT
    except OSError as exc:  # the disk filled or vanished under a command that writes
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        print(f"amb-bag {args.command}: {where}{exc.strerror or exc}", file=sys.stderr)
        rc = 1
    except BrokenPipeError:  # `amb-bag info | head`
        rc = 0
    raise SystemExit(rc)


if __name__ == "__main__":
    main()
