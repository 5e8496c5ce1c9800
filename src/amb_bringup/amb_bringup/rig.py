"""amb-rig: run the node suite as separate processes (no launch system) and summarise the run.

    amb-rig run --duration 5 --motion pitch --amplitude 0.3 --frequency 24.5 [--mode lockstep|realtime]
                [--set key=value]... [--config F] [--param NODE:NAME=VALUE]... [--json] [--no-plant] [--bag DIR]
    amb-rig sensitivity --axis amb1_y [--band 5:50] [--duration 20] ... (amb_bringup.sensitivity_cmd)

Sequence: reserve a DDS domain (localhost unless --discovery or the environment says otherwise), start
amb-rig's diagnostics collector, refuse to start if the domain already carries the topics this run publishes
(another rig, an orphan, a player), start the processes (extras, base_motion, controller, plant), wait (bounded
by --start-timeout) until every node reports on /diagnostics and the plant reports that it runs (the plant itself
waits until controller and base motion are matched), then wait for the plant to finish its --duration (or, with
--no-plant, for --duration of wall time; a run split across two hosts ends with its other side:
amb_bringup.split), stop everything cleanly and print the summary.  Exit code 0 only if every process ran and
ended as expected, then the summary's verdict line.  Exit codes: docs/exit-codes.md (0 ran as asked, whatever
the result; 1 failed or untrustworthy; 2 bad arguments; 3 a --fail-on result; 128+n signal n).
"""

from __future__ import annotations

import argparse
import json
import os
import secrets
import shutil
import signal
import sys
import tempfile
import time
from pathlib import Path

from amb_dynamics.config import load_config
from amb_dynamics.errors import AmbError
from amb_dynamics.preflight import rig_preflight
from amb_ros.discovery import DiscoveryError, apply_choice
from amb_ros.env import DdsEnvError, child_env, ensure_localhost_dds, hold_run_lock
from amb_ros.fastdds import init_rclpy
from amb_ros.shm_clean import clean_stale_shm

from . import live, paramfile, split
from .domain import Watch, describe, foreign_publishers, topics_of
from .liveness import DeathWatch
from .processes import all_specs
from .rig_args import check_rig_args, refuse
from .summary import build_summary, format_summary
from .supervisor import Supervisor, describe_exit
from .verdict import add_arguments as add_verdict_arguments
from .verdict import judge_verdict

EXIT_FAILED, EXIT_USAGE = 1, 2
LOCK_WAIT_S = 10.0  # for the domain's previous run to end: its nodes may still be exiting (bounded ack waits)


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="amb-rig", description="Run the AMB rig node suite.")
    sub = ap.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run", help="start the nodes, run, stop, summarise")
    r.add_argument("--duration", type=float, default=5.0, help="run length: simulated s (lockstep), wall s (realtime)")
    r.add_argument("--motion", choices=("none", "roll", "pitch", "yaw", "combined"), help="base motion kind")
    r.add_argument("--amplitude", type=float, help="base motion amplitude (rad)")
    r.add_argument("--frequency", type=float, help="base motion angular frequency (rad/s)")
    r.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep")
    r.add_argument(
        "--initial-displacement",
        type=float,
        default=0.0,
        metavar="M",
        help="initial lateral displacement of the disk (m), e.g. 1e-3 as in the paper",
    )
    r.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="config override (repeatable)")
    r.add_argument("--config", help="rotor config YAML (default: the seed rotor)")
    r.add_argument("--param", action="append", default=[], metavar="NODE:NAME=VALUE",
                   help="node parameter, NODE one of base_motion, controller, plant, monitor (repeatable)")  # fmt: skip
    r.add_argument(
        "--rt-priority",
        type=int,
        default=None,
        choices=range(100),
        metavar="N",
        help="SCHED_FIFO priority of base_motion, plant and controller (0 = normal scheduling; default 20 in "
        "realtime, 0 in lockstep; lockstep only with --no-monitor and without --bag, whose consumers would "
        "starve; without permission the nodes run normally and say so)",
    )
    r.add_argument("--json", action="store_true", help="print the summary as JSON")
    r.add_argument("--force", action="store_true", help="run even if the digital loop is unstable at rest (warns)")
    r.add_argument("--no-plant", action="store_true", help="no plant: a real rig supplies /amb/displacement")
    r.add_argument("--bag", help="record the run with amb-bag into this folder")
    r.add_argument("--no-monitor", action="store_true", help="do not start the stability monitor")
    split.add_arguments(r)  # --discovery, --only plant
    r.add_argument("--log-dir", help="folder for the node logs and params file (default: a new temp folder)")
    r.add_argument("--keep-logs", action="store_true", help="keep the temp log folder of a run that went well")
    add_verdict_arguments(r)
    r.add_argument("--start-timeout", type=float, default=60.0, help="bound on start-up and connection (s)")
    r.add_argument("--timeout", type=float, help="bound on the whole run (wall s; default from the duration)")
    r.add_argument("--lock-wait", type=float, default=LOCK_WAIT_S, metavar="S",
                   help=f"wait up to S s for another run on this ROS_DOMAIN_ID to end before giving up (default "
                   f"{LOCK_WAIT_S:g}; 0: at once)")  # fmt: skip
    paramfile.add_arguments(r)
    r.add_argument("--live", action="store_true", help="serve the run to Foxglove (amb-live; docs/live-view.md)")
    live.add_arguments(r, prefix="live-")
    from .sensitivity_cmd import add_parser as add_sensitivity_parser  # ISO 14839-3 measurement (own module)

    add_sensitivity_parser(sub)
    from .report import add_parser as add_report_parser  # the HTML commissioning report (own module)

    add_report_parser(sub)
    return ap


def _waiting_note(wait_s: float):
    """The one line printed when a run waits for the domain's other run."""

    def say(holder: str) -> None:
        print(f"amb-rig: waiting up to {wait_s:g} s for the domain's other run ({holder}) to end", file=sys.stderr)

    return say


class Interrupted:
    def __init__(self):
        self.signum: int | None = None

    def __call__(self, signum, _frame) -> None:
        self.signum = signum


def main(argv: list[str] | None = None) -> None:
    args = parser().parse_args(argv)
    if args.command == "sensitivity":
        from .sensitivity_cmd import main_sensitivity

        sys.exit(main_sensitivity(args))
    if args.command == "report":
        from .report import main_report

        sys.exit(main_report(args))
    try:  # amb-rig's own arguments, then every node's parameters, before anything starts
        check_rig_args(args)  # docs/exit-codes.md: 2
        params = paramfile.prepare(args)
    except AmbError as exc:
        print(f"amb-rig: {exc}", file=sys.stderr)
        sys.exit(EXIT_USAGE)
    if args.print_params:
        paramfile.print_params(args, *params)
        sys.exit(0)
    try:
        apply_choice(args.discovery, os.environ)
        ensure_localhost_dds()  # one warning line when discovery is wider than localhost
        bad = split.check(args)
    except (DiscoveryError, DdsEnvError) as exc:
        bad = str(exc)
    if bad:
        print(f"amb-rig: {bad}", file=sys.stderr)
        sys.exit(EXIT_USAGE)
    try:
        cfg = load_config(args.config, args.set)  # validate before starting anything
        stable, line = rig_preflight(cfg)  # the digital loop at rest, before any node starts
        args.preflight = line  # and its delay margin: in the summary
        if not stable and not args.force:
            refuse(f"amb-rig: refusing to run: {line} (or --force)")
        if not stable:
            print(f"amb-rig: WARNING (--force): {line}", file=sys.stderr)
    except (AmbError, DdsEnvError) as exc:
        refuse(f"amb-rig: {exc}")
    if args.rt_priority is None:
        args.rt_priority = 20 if args.mode == "realtime" else 0
    if args.rt_priority and args.mode == "lockstep" and (args.bag or not args.no_monitor):
        # measured: the loop then runs ~40 % faster, and the monitor and recorder fall behind and lose samples
        refuse(
            "amb-rig: --rt-priority in lockstep needs --no-monitor and no --bag (a SCHED_FIFO loop "
            "starves them: they would lose samples)"
        )
    try:
        lock = split.hold_locks(hold_run_lock, os.environ["ROS_DOMAIN_ID"], args, args.lock_wait,
                                _waiting_note(args.lock_wait))  # fmt: skip
    except (AmbError, DdsEnvError) as exc:  # the domain is in use: not bad input, a run that could not happen
        raise SystemExit(f"amb-rig: {exc}") from None
    clean_stale_shm()  # a killed run's Fast DDS segments (nobody holds their locks); a live run's stay
    sys.exit(run(args, cfg, lock))


def run(args, cfg, lock) -> int:
    """One run; ``lock`` is the domain's run locks (open files), passed on to every child."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    from .collector import DiagnosticsCollector

    log_dir = Path(args.log_dir) if args.log_dir else Path(tempfile.mkdtemp(prefix="amb-rig-"))
    log_dir.mkdir(parents=True, exist_ok=True)
    # the nodes' final reports wait for this collector by name: one per run, also on either side of a split
    args.collector_name = f"amb_rig_{secrets.token_hex(4)}"
    try:
        specs = all_specs(args, log_dir)
    except (FileNotFoundError, ValueError) as exc:
        print(f"amb-rig: {exc}", file=sys.stderr)
        return EXIT_USAGE
    interrupted = Interrupted()
    signal.signal(signal.SIGINT, interrupted)
    signal.signal(signal.SIGTERM, interrupted)
    domain = os.environ["ROS_DOMAIN_ID"]  # set by ensure_localhost_dds
    init_rclpy(args=[], signal_handler_options=SignalHandlerOptions.NO)
    collector = DiagnosticsCollector(args.collector_name)
    topics = topics_of(spec.name for spec in specs)
    found = foreign_publishers(collector.node, topics)
    if found:  # before anything starts: the other run must not see this one's nodes either
        collector.close()
        rclpy.try_shutdown()
        if not args.log_dir:
            shutil.rmtree(log_dir, ignore_errors=True)
        print(f"amb-rig: {describe(found, domain)}", file=sys.stderr)
        return EXIT_FAILED
    watch = Watch(collector.node, topics, domain, collector)
    sup = Supervisor(
        log_dir, child_env(OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1"), tuple(fh.fileno() for fh in lock)
    )
    collector.accept_pids = lambda: {c.pid for c in sup.children}  # only this run's reports (not a replay's)
    if args.no_plant or getattr(args, "only", None):  # a split run: the other side's nodes report from its host
        collector.peer_names = (
            {"amb_plant"} if args.no_plant else {"amb_controller", "base_motion", "stability_monitor"}
        )
    errors: list[str] = []
    peer = split.PeerEnd(collector.node, collector, args)
    t0 = time.monotonic()
    try:
        for spec in specs:
            child = sup.start(spec)
            print(f"amb-rig: started {spec.name} (pid {child.pid}), log {child.log}", file=sys.stderr, flush=True)
        if not errors:
            errors += wait_run(args, sup, collector, interrupted, watch, peer)
    finally:
        sup.stop_all()
        time.sleep(0.2)  # final diagnostics were acknowledged before the nodes exited; let the thread store them
        collector.close()
        rclpy.try_shutdown()
    dead = tuple(e.split(" died (")[0] + " " for e in errors if " died (" in e)  # named by the death watch
    errors += [e for e in judge(sup, collector, interrupted) if not (dead and e.startswith(dead))]  # say it once
    errors += watch.final()  # a publisher matched in the run's last moments
    errors, notes = split.forgive_final_loss(errors, peer)
    motion = (args.motion or cfg.base_motion.kind, args.amplitude, args.frequency)
    run_info = {
        "mode": args.mode,
        "motion": "static base"
        if motion[0] == "none"
        else f"{motion[0]} A={_g(motion[1], cfg.base_motion.amplitude)} rad "
        f"w={_g(motion[2], cfg.base_motion.frequency)} rad/s",
        "duration_s": args.duration,
        "rate_hz": load_config(args.config, args.set).controller.rate_hz,
        "run_wall_s": round(time.monotonic() - t0, 3),
        "preflight": getattr(args, "preflight", ""),  # amb-rig sensitivity calls run() without the preflight
        "log_dir": str(log_dir),
        "interrupted": interrupted.signum is not None,
        "discovery": os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "")
        + (f" + peers {os.environ['ROS_STATIC_PEERS']}" if os.environ.get("ROS_STATIC_PEERS") else ""),
        **({"ended_by": peer.reason} if peer.reason else {}),
        **({"notes": notes} if notes else {}),
    }
    summary = build_summary(run_info, sup.children, collector, errors)
    if collector.foreign:
        summary["foreign_diagnostics"] = dict(collector.foreign)
    verdict = judge_verdict(summary, args)  # the whole run's verdict and exit code (docs/exit-codes.md)
    summary.update(ok=not verdict.failures, errors=verdict.failures, verdict=verdict.to_dict())
    print(
        json.dumps({"schema_version": 1, **summary}, indent=2)
        if args.json
        else f"{format_summary(summary)}\n{verdict.line}",
        flush=True,
    )
    if not args.log_dir and not args.keep_logs and verdict.exit_code == 0 and interrupted.signum is None:
        shutil.rmtree(log_dir, ignore_errors=True)  # a clean run leaves no /tmp/amb-rig-* behind
    if interrupted.signum is not None:
        return 128 + interrupted.signum
    return verdict.exit_code


def _g(value, default) -> str:
    return f"{value if value is not None else default:g}"


def default_timeout(args) -> float:
    """Wall-time bound of a run: generous (100 lockstep steps/s would still finish), never endless."""
    if args.mode == "realtime" or (args.no_plant and args.mode != "lockstep"):
        return 60.0 + args.duration
    rate = load_config(args.config, args.set).controller.rate_hz
    return 120.0 + args.duration * rate / 100.0


def plant_running_for(collector, plant) -> float:
    """Wall time the plant's loop has run, from its latest diagnostic (0 if unknown).

    The plant starts as soon as its own peers are matched, which can be seconds before every other node (the
    monitor, the recorder) has reported: a realtime run of --duration is timed from the plant's start, not from
    the moment amb-rig has heard from everyone (the diagnostic is at most one diagnostics period old).
    """
    diag = collector.get(plant.spec.node) if plant is not None else None
    try:
        return max(0.0, float(diag["values"].get("wall time (s)", 0.0))) if diag else 0.0
    except (TypeError, ValueError):
        return 0.0


def wait_run(args, sup: Supervisor, collector, interrupted, watch: Watch, peer=None) -> list[str]:
    """Wait for start-up, then for the end of the run; return error messages (empty: all went well)."""
    plant = sup.find("plant")
    nodes = [c for c in sup.children if c.spec.node]
    start_deadline = time.monotonic() + args.start_timeout
    while interrupted.signum is None:  # start-up: every node reports, the plant is past its connection wait
        if plant is not None and plant.poll() is not None:
            break
        if sup.died_early():
            break
        if intruder := watch.check():
            return [intruder]
        silent = [c.spec.name for c in nodes if not collector.seen(c.spec.node)]
        plant_diag = collector.get(plant.spec.node) if plant is not None else None
        waiting = plant is not None and (plant_diag is None or plant_diag["values"].get("steps") in (None, "0"))
        waiting = waiting and not (plant_diag and plant_diag["message"].startswith(("running", "finished")))
        if not silent and not waiting:
            break
        if time.monotonic() > start_deadline:
            who = ", ".join(silent) if silent else "the plant (still waiting for its peers)"
            return [f"start-up timed out after {args.start_timeout:g} s: no report from {who}"]
        time.sleep(0.05)
    run_start = time.monotonic() - plant_running_for(collector, plant)
    limit = args.timeout if args.timeout else default_timeout(args)
    deaths = DeathWatch(sup)  # a node's death is the run's first error, noticed at once (liveness.py)
    while interrupted.signum is None:
        if deaths.poll():  # first: a plant killed by a signal is a death, not the run's end
            return [deaths.first]
        if plant is not None and plant.poll() is not None and not deaths.first:
            break
        if intruder := watch.check():
            return [intruder]
        if peer is not None and peer.ended():
            break  # a split run: the other side has ended (amb_bringup.split)
        if peer is not None and peer.owns_end:
            pass  # --no-plant in lockstep: the plant (on the other side) ends the run
        elif (plant is None or not plant.spec.ends_run) and time.monotonic() - run_start >= args.duration:
            break  # realtime or --no-plant: amb-rig ends the run after --duration of wall time
        if time.monotonic() - run_start > limit:
            return [f"run timed out after {limit:g} s of wall time (--timeout)"]
        time.sleep(0.05)
    return []


def judge(sup: Supervisor, collector, interrupted) -> list[str]:
    """Errors from exit codes and final diagnostics, plant first (its message says why a run stopped)."""
    errors = []
    ordered = sorted(sup.children, key=lambda c: not c.spec.ends_run)
    for c in ordered:
        code = c.popen.returncode
        diag = collector.get(c.spec.node) if c.spec.node else None
        if c.spec.ends_run and interrupted.signum is None and (c.stopped_by_us or code != 0):
            reason = diag["message"] if diag and diag["level"] == "ERROR" else c.last_line()
            errors.append(f"{c.spec.name} did not finish ({describe_exit(code)})" + (f": {reason}" if reason else ""))
        elif not c.spec.ends_run and not c.stopped_by_us and c.spec.required:
            errors.append(f"{c.spec.name} exited unexpectedly ({describe_exit(code)}): {c.last_line()}")
        elif c.stopped_by_us and code == -signal.SIGINT and not (c.spec.node and collector.seen(c.spec.node)):
            pass  # stopped while still importing, before it could install its handlers: nothing to clean up
        elif c.stopped_by_us and code not in (0, None):
            errors.append(f"{c.spec.name} did not stop cleanly ({describe_exit(code)}): {c.last_line()}")
        elif diag is not None and diag["level"] == "ERROR" and not c.spec.verdict_only:
            errors.append(f"{c.spec.name} reported ERROR: {diag['message']}")
        elif c.spec.node and diag is None:
            errors.append(f"{c.spec.name} published no diagnostics (see {c.log})")
    return errors


if __name__ == "__main__":
    main()
