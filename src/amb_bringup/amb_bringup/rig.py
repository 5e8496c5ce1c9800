"""amb-rig: run the node suite as separate processes (no launch system) and summarise the run.

    amb-rig run --duration 5 --motion pitch --amplitude 0.3 --frequency 24.5 [--mode lockstep|realtime]
                [--set key=value]... [--config F] [--param NODE:NAME=VALUE]... [--json] [--no-plant] [--bag DIR]

Sequence: reserve a DDS domain (localhost only), start amb-rig's diagnostics collector, refuse to start if the
domain already carries the topics this run publishes (another rig, an orphan, a player), start the processes
(extras, base_motion, controller, plant), wait (bounded by --start-timeout) until every node reports on
/diagnostics and the plant reports that it runs (the plant itself waits until controller and base motion are
matched), then wait for the plant to finish its --duration (or, with --no-plant, for --duration of wall time),
stop everything cleanly and print the summary.  Exit code 0 only if every process ran and ended as expected
and no node ended with an ERROR diagnostic; 1 otherwise; 2 for bad arguments; 130/143 when interrupted.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import sys
import tempfile
import time
from pathlib import Path

from amb_dynamics.config import load_config
from amb_dynamics.errors import AmbError
from amb_dynamics.preflight import rig_preflight
from amb_ros.env import DdsEnvError, child_env, ensure_localhost_dds, hold_run_lock

from .domain import Watch, describe, foreign_publishers, topics_of
from .processes import all_specs
from .summary import build_summary, format_summary
from .supervisor import Supervisor, describe_exit

EXIT_FAILED, EXIT_USAGE = 1, 2
# after a node died, the plant may take its command timeout (10 s) and then up to 2 s for each of its three data
# writers and 2 s for its final diagnostics to be acknowledged before it exits on its own: 18 s at most
PEER_DEATH_GRACE_S = 20.0
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
        "realtime, 0 in lockstep; lockstep only with --no-monitor and without --bag, whose SCHED_IDLE consumers would "
        "starve; without permission the nodes run normally and say so)",
    )
    r.add_argument("--json", action="store_true", help="print the summary as JSON")
    r.add_argument("--force", action="store_true", help="run even if the digital loop is unstable at rest (warns)")
    r.add_argument("--no-plant", action="store_true", help="no plant: a real rig supplies /amb/displacement")
    r.add_argument("--bag", help="record the run with amb-bag into this folder")
    r.add_argument("--no-monitor", action="store_true", help="do not start the stability monitor")
    r.add_argument("--log-dir", help="folder for the node logs and params file (default: a new temp folder)")
    r.add_argument("--start-timeout", type=float, default=60.0, help="bound on start-up and connection (s)")
    r.add_argument("--timeout", type=float, help="bound on the whole run (wall s; default from the duration)")
    return ap


def _say_waiting(holder: str) -> None:
    print(f"amb-rig: waiting up to {LOCK_WAIT_S:g} s for the domain's other run ({holder}) to end", file=sys.stderr)


class Interrupted:
    def __init__(self):
        self.signum: int | None = None

    def __call__(self, signum, _frame) -> None:
        self.signum = signum


def main(argv: list[str] | None = None) -> None:
    args = parser().parse_args(argv)
    try:
        ensure_localhost_dds()
        cfg = load_config(args.config, args.set)  # validate before starting anything
        stable, line = rig_preflight(cfg)  # the digital loop at rest, before any node starts
        if not stable and not args.force:
            print(f"amb-rig: refusing to run: {line} (or --force)", file=sys.stderr)
            sys.exit(EXIT_USAGE)
        if not stable:
            print(f"amb-rig: WARNING (--force): {line}", file=sys.stderr)
        lock = hold_run_lock(os.environ["ROS_DOMAIN_ID"], LOCK_WAIT_S, _say_waiting)
    except (AmbError, DdsEnvError) as exc:
        raise SystemExit(f"amb-rig: {exc}") from None
    if args.duration <= 0 and not args.no_plant:
        raise SystemExit("amb-rig: --duration must be > 0 s")
    if args.rt_priority is None:
        args.rt_priority = 20 if args.mode == "realtime" else 0
    if args.rt_priority and args.mode == "lockstep" and (args.bag or not args.no_monitor):
        # measured: the loop then runs ~40 % faster, and the monitor and recorder fall behind and lose samples
        raise SystemExit(
            "amb-rig: --rt-priority in lockstep needs --no-monitor and no --bag (a SCHED_FIFO loop "
            "starves them: they would lose samples)"
        )
    sys.exit(run(args, cfg, lock))


def run(args, cfg, lock) -> int:
    """One run; ``lock`` is the domain's run lock (an open file), passed on to every child."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    from .collector import DiagnosticsCollector

    log_dir = Path(args.log_dir) if args.log_dir else Path(tempfile.mkdtemp(prefix="amb-rig-"))
    log_dir.mkdir(parents=True, exist_ok=True)
    try:
        specs = all_specs(args, log_dir)
    except (FileNotFoundError, ValueError) as exc:
        print(f"amb-rig: {exc}", file=sys.stderr)
        return EXIT_USAGE
    interrupted = Interrupted()
    signal.signal(signal.SIGINT, interrupted)
    signal.signal(signal.SIGTERM, interrupted)
    domain = os.environ["ROS_DOMAIN_ID"]  # set by ensure_localhost_dds
    rclpy.init(args=[], signal_handler_options=SignalHandlerOptions.NO)
    collector = DiagnosticsCollector()
    topics = topics_of(spec.name for spec in specs)
    found = foreign_publishers(collector.node, topics)
    if found:  # before anything starts: the other run must not see this one's nodes either
        collector.close()
        rclpy.try_shutdown()
        if not args.log_dir:
            shutil.rmtree(log_dir, ignore_errors=True)
        print(f"amb-rig: {describe(found, domain)}", file=sys.stderr)
        return EXIT_FAILED
    watch = Watch(collector.node, topics, domain)
    sup = Supervisor(log_dir, child_env(OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1"), (lock.fileno(),))
    errors: list[str] = []
    t0 = time.monotonic()
    try:
        for spec in specs:
            child = sup.start(spec)
            print(f"amb-rig: started {spec.name} (pid {child.pid}), log {child.log}", file=sys.stderr, flush=True)
        if not errors:
            errors += wait_run(args, sup, collector, interrupted, watch)
    finally:
        sup.stop_all()
        time.sleep(0.2)  # final diagnostics were acknowledged before the nodes exited; let the thread store them
        collector.close()
        rclpy.try_shutdown()
    errors += judge(sup, collector, interrupted)
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
        "log_dir": str(log_dir),
        "interrupted": interrupted.signum is not None,
    }
    summary = build_summary(run_info, sup.children, collector, errors)
    print(json.dumps(summary, indent=2) if args.json else format_summary(summary), flush=True)
    if interrupted.signum is not None:
        return 128 + interrupted.signum
    return 0 if summary["ok"] else EXIT_FAILED


def _g(value, default) -> str:
    return f"{value if value is not None else default:g}"


def default_timeout(args) -> float:
    """Wall-time bound of a run: generous (100 lockstep steps/s would still finish), never endless."""
    if args.mode == "realtime" or args.no_plant:
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


def wait_run(args, sup: Supervisor, collector, interrupted, watch: Watch) -> list[str]:
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
    grace_end = None
    while interrupted.signum is None:
        if plant is not None and plant.poll() is not None:
            break
        if intruder := watch.check():
            return [intruder]
        if sup.died_early():
            # a peer died: give the plant time to notice (command timeout) and report it before stopping it
            grace_end = grace_end or time.monotonic() + (PEER_DEATH_GRACE_S if plant is not None else 0.0)
            if time.monotonic() >= grace_end:
                break
        if (plant is None or not plant.spec.ends_run) and time.monotonic() - run_start >= args.duration:
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
            errors.append(f"{c.spec.name} did not finish ({describe_exit(code)}): {reason}")
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
