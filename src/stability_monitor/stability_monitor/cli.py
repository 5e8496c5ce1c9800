"""``amb-monitor``: the monitor node (``ros2 run stability_monitor monitor``), or ``amb-monitor analyze <bag>``.

    amb-monitor [--ros-args -p input:=displacement ...]      run the node (same as the ``monitor`` executable)
    amb-monitor analyze BAG [--json] [--plot rho.png] [--sensor-only] [--period S] [--config F] [--set k=v]

``analyze`` runs the node's estimator over a recorded bag and prints the multipliers over time and the final
verdict (JSON with ``--json``), and with ``--plot`` draws rho(t) against the model value.  Bad, missing or
truncated bags and bad options exit non-zero with one line.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from amb_dynamics.errors import AmbError
from amb_dynamics.estimator.fit import METHODS

from .pipeline import FORCING_CHOICES, MonitorSettings, synchronous_harmonics

D = MonitorSettings()  # the defaults, typed once (pipeline.py, from the estimator's)

ROWS = 20  # estimates shown in the human-readable table


def analyze_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="amb-monitor analyze", description="Re-run the stability monitor on a bag.")
    p.add_argument("bag", type=Path, help="bag folder (metadata.yaml + .mcap) or a .mcap file")
    p.add_argument("--json", action="store_true", help="print one JSON document")
    p.add_argument("--plot", type=Path, help="write rho(t) against the model value to this PNG")
    p.add_argument("--sensor-only", action="store_true", help="use /amb/displacement instead of /amb_plant/state")
    p.add_argument("--period", type=float, default=0.0, help="period of A(t) in s (default: from /base/imu)")
    p.add_argument("--forcing", default="auto", choices=FORCING_CHOICES)
    p.add_argument("--synchronous", type=int, default=-1, metavar="H", help="spin harmonics of the synchronous "
                   "response removed with /amb/spin_speed's angle; -1 (default): 1 if --config has unbalance or "
                   "runout and the bag has the tachometer")  # fmt: skip
    p.add_argument("--velocities", action="store_true", help="full state: fit the velocities too (default: the "
                   "positions only)")  # fmt: skip
    p.add_argument("--phases", type=int, default=D.phases)
    p.add_argument("--window", type=int, default=D.window, help="periods in the moving window (moving base)")
    p.add_argument("--static-window", type=int, default=D.static_window, help="periods of 0.1 s in the window "
                   "(static base)")  # fmt: skip
    p.add_argument("--updates-per-period", type=int, default=D.updates_per_period)
    p.add_argument(
        "--method",
        default=D.method,
        choices=METHODS,
        help="opt: LS refined by variable projection (default); ls: least squares; tls: total least squares",
    )
    p.add_argument("--noise-std", type=float, default=D.noise_std, help="measurement noise std (negative: estimate)")
    p.add_argument("--margin", type=float, default=D.margin)
    p.add_argument("--hysteresis", type=float, default=D.hysteresis)
    p.add_argument("--confidence-z", type=float, default=D.z)
    p.add_argument("--confirm", type=int, default=D.confirm)
    p.add_argument("--top", type=int, default=6, help="multipliers listed per estimate")
    p.add_argument(
        "--config",
        help="rotor config of the run: base_forcing and the model value (default: the one the run's "
        "plant recorded in the bag on /amb_plant/config, else the seed rotor)",
    )
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="config override")
    p.add_argument("--no-model", action="store_true", help="skip the model value")
    return p


def analyze(argv: list[str]) -> int:
    args = analyze_parser().parse_args(argv)
    from .analyze import analyze_bag, try_model_value

    for name in ("phases", "window", "static_window", "updates_per_period", "top"):
        if getattr(args, name) < 1:
            raise AmbError(f"--{name.replace('_', '-')} must be >= 1")
    cfg, config_note = run_config(args.bag, args.config, args.set)
    if not -1 <= args.synchronous <= 8:
        raise AmbError("--synchronous must be -1 (auto) or 0..8")
    settings = MonitorSettings(
        sensor_only=args.sensor_only,
        base_forcing=cfg.base_forcing,
        gravity=cfg.gravity.enabled,
        synchronous=synchronous_harmonics(args.synchronous, cfg),
        velocities=args.velocities,
        period=args.period,
        forcing=args.forcing,
        phases=args.phases,
        window=args.window,
        static_window=args.static_window,
        updates_per_period=args.updates_per_period,
        method=args.method,
        noise_std=args.noise_std,
        margin=args.margin,
        hysteresis=args.hysteresis,
        z=args.confidence_z,
        confirm=args.confirm,
    )
    result = analyze_bag(args.bag, settings, auto_synchronous=args.synchronous < 0)
    result.notes.insert(0, config_note)
    if not args.no_model:
        result.model = try_model_value(result, cfg)
    plot_path = None
    if args.plot:
        from .plot import plot_rho

        plot_path = plot_rho(result, args.plot, args.margin, args.confidence_z)
    doc = result.to_dict(args.top)
    if args.json:
        print(json.dumps({"schema_version": 1, **doc}, indent=1))
    else:
        print_report(doc, plot_path)
    return 0


def run_config(bag: Path, config: str | None, overrides: list[str]):
    """(config, a note saying where it came from): --config's file, else the run's own config recorded in the bag
    (/amb_plant/config), else the default; --set overrides apply to either."""
    from amb_bag.reader import Bag
    from amb_bag.runconfig import recorded_config
    from amb_dynamics.config import apply_override, config_from_dict, load_config, to_dict

    if config is None and (recorded := recorded_config(Bag(bag))) is not None:
        data = to_dict(recorded)
        for item in overrides:
            apply_override(data, item)
        return config_from_dict(data, f"{bag} (recorded config)"), "rotor config: the run's own, recorded in the bag"
    note = f"rotor config: {config}" if config else "rotor config: the default (the bag has no /amb_plant/config)"
    return load_config(config, overrides), note


def print_report(doc: dict, plot_path: Path | None) -> None:
    print(f"bag {doc['bag']}: {doc['samples']} samples of {doc['input_topic']}, {doc['refits']} refits")
    if doc["period_s"]:
        print(f"period T = {doc['period_s']:.9g} s (base {doc['base_period_s']:.9g} s), forcing {doc['forcing']}, "
              f"synchronous harmonics {doc['synchronous']}")  # fmt: skip
    for note in doc["notes"]:
        print(f"note: {note}")
    est = doc["estimates"]
    step = max(1, len(est) // ROWS)
    print(f"{'t (s)':>10} {'periods':>7} {'rho':>9} {'std':>8} {'rank':>4}  verdict")
    for e in est[::step] + ([est[-1]] if est and (len(est) - 1) % step else []):
        rho = f"{e['rho']:.5f}" if e["rho"] is not None else "-"
        sd = f"{e['rho_std']:.2g}" if e["rho_std"] is not None else "-"
        print(f"{e['time_s']:10.4f} {e['periods']:7d} {rho:>9} {sd:>8} {e['rank']:4d}  {e['verdict']}")
    flag = f" (flag raised at t = {doc['flag_time_s']:.4f} s)" if doc["flag_time_s"] is not None else ""
    print(f"verdict: {doc['verdict']}{flag}")
    model = doc["model"]
    if model and "rho" in model:
        mo = model["motion"]
        print(f"model rho = {model['rho']:.6f} ({model['method']}; {mo['kind']} {mo['amplitude_rad']:.4g} rad at "
              f"{mo['frequency_rad_s']:.6g} rad/s)")  # fmt: skip
    elif model:
        print(f"model: {model['error']}")
    if plot_path:
        print(f"plot: {plot_path}")


def main(argv: list[str] | None = None) -> None:
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] == "analyze":
        try:
            sys.exit(analyze(argv[1:]))
        except AmbError as exc:  # bad input: one line, exit 2 (docs/exit-codes.md)
            print(f"amb-monitor analyze: {exc}", file=sys.stderr)
            sys.exit(2)
    if argv and argv[0] in ("-h", "--help"):
        print(__doc__)
        sys.exit(0)
    from .node import main as node_main

    node_main([sys.argv[0], *argv])
