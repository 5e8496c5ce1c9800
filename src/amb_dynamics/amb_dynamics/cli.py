"""``amb-dynamics``: modes | campbell | floquet | chart | sweep | simulate | sensitivity | unbalance.

Data to stdout (``--json``), logs to stderr.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from .errors import AmbError
from .threads import limit_blas_threads


def grid(text: str):
    """'lo:hi:n' -> linspace(lo, hi, n); 'a,b,c' or 'a' -> values (np.ndarray)."""
    import numpy as np  # not at module level: main() limits the BLAS threads before numpy loads

    try:
        if ":" in text:
            lo, hi, n = text.split(":")
            if not 1 <= int(n) <= 1_000_000:
                raise ValueError
            return np.linspace(float(lo), float(hi), int(n))
        return np.array([float(v) for v in text.split(",")])
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a grid: use lo:hi:n (e.g. 1:40:101) or a,b,c") from None


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", type=Path, default=None, help="rotor YAML (default: the seed rotor)")
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a config key, e.g. --set controller.rate_hz=10000 (repeatable)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON document on stdout")


def harmonic(text: str):
    """'axis:A:omega[:phase]' -> (axis, A rad, omega rad/s, phase rad)."""
    parts = text.split(":")
    try:
        if len(parts) not in (3, 4) or parts[0] not in ("roll", "pitch", "yaw"):
            raise ValueError
        values = [float(v) for v in parts[1:]] + [0.0] * (4 - len(parts))
        return (parts[0], *values)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"'{text}' is not a harmonic: use axis:A:omega[:phase], e.g. pitch:0.3:24.5"
        ) from None


def _motion(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--motion",
        choices=("none", "roll", "pitch", "yaw", "combined"),
        default=None,
        help="base motion about X (roll), Z (pitch) or Y (yaw), or combined harmonics (default: the config's)",
    )
    p.add_argument(
        "--harmonic",
        type=harmonic,
        action="append",
        default=[],
        metavar="AXIS:A:OMEGA[:PHASE]",
        help="with --motion combined: one harmonic beta = A sin(omega t + phase) (repeatable)",
    )
    p.add_argument("--amplitude", type=float, default=0.0, help="A (rad) in beta = A sin(omega t)")
    p.add_argument("--frequency", type=float, default=0.0, help="omega (rad/s)")
    p.add_argument("--formulation", choices=("derived", "seed"), default=None, help="override config formulation")


def build_parser() -> argparse.ArgumentParser:
    # these import numpy: only once main() has limited the BLAS threads
    from . import unbalance_report
    from .chart_cli import add_chart_args
    from .sweep import add_sweep_parser

    ap = argparse.ArgumentParser(prog="amb-dynamics", description=__doc__)
    sub = ap.add_subparsers(dest="verb", required=True)
    p = sub.add_parser("modes", help="closed-loop modes at constant spin speeds (base at rest)")
    _common(p)
    p.add_argument("--speed-rpm", type=float, nargs="+", default=[0.0, 1000.0])
    p.add_argument("--max-frequency", type=float, default=None, help="only list modes below this (rad/s)")
    p = sub.add_parser("campbell", help="Campbell diagram PNG (frequencies and damping vs speed)")
    _common(p)
    p.add_argument("--speeds", type=grid, default=grid("0:3000:61"), help="rpm grid lo:hi:n")
    p.add_argument("--max-frequency", type=float, default=1500.0, help="upper frequency of the plot (rad/s)")
    p.add_argument("--out", type=Path, default=Path("out/campbell.png"))
    p = sub.add_parser("floquet", help="Floquet multipliers of one base motion")
    _common(p)
    _motion(p)
    p.add_argument("--controller", choices=("continuous", "sampled"), default="continuous")
    p.add_argument("--snap", action="store_true", help="sampled: set Ts = T/round(T/Ts) if T/Ts is not rational")
    about = ("sampled: the bearing law linearised at the centre (default), at the levitated point on a level base "
             "(the monitor's model), or along the forced orbit of gravity on the moving base")  # fmt: skip
    p.add_argument("--about", choices=("centre", "rest", "orbit"), default="centre", help=about)
    p.add_argument("--top", type=int, default=12, help="multipliers to print (largest first)")
    p.add_argument("--horizon", type=float, default=20.0, help="aperiodic motion: Lyapunov horizon (s)")
    p = sub.add_parser("chart", help="stability chart of max|mu| over (omega, A)")
    _common(p)
    p.add_argument("--motion", choices=("roll", "pitch", "yaw"), required=True)
    p.add_argument("--amplitude", type=grid, required=True, help="lo:hi:n (rad)")
    p.add_argument("--frequency", type=grid, required=True, help="lo:hi:n (rad/s)")
    p.add_argument("--formulation", choices=("derived", "seed"), default=None)
    p.add_argument("--out", type=Path, default=Path("out/chart.png"))
    p.add_argument(
        "--json-out",
        "--json-file",
        dest="json_out",
        type=Path,
        default=None,
        help="write the grid of max|mu| as JSON to this file",
    )
    add_chart_args(p)
    add_sweep_parser(sub, _common, grid)
    p = sub.add_parser("simulate", help="Newmark-beta time response from the paper's 1 mm disk displacement")
    _common(p)
    _motion(p)
    p.add_argument("--duration", type=float, default=20.0, help="s")
    p.add_argument("--steps-per-period", type=int, default=200)
    p.add_argument(
        "--sampled",
        action="store_true",
        help="the digital loop on the rig plant (every effect of the config; the plant node's code) instead of Newmark",
    )
    p.add_argument("--fail-at-s", type=float, default=None, help="--sampled: zero control current from this time (s)")
    p.add_argument("--out", type=Path, default=Path("out/response.png"))
    p = sub.add_parser("sensitivity", help="model sensitivity S_jj per AMB axis with its ISO 14839-3 zone")
    _common(p)
    p.add_argument("--speed-rpm", type=float, nargs="+", default=[0.0, 1000.0])
    p.add_argument("--controller", choices=("continuous", "sampled"), default="continuous")
    p.add_argument("--band", default="1:500", help="lo:hi (Hz), default 1:500")
    p.add_argument("--points", type=int, default=2000, help="log-spaced frequencies in the band")
    p.add_argument("--axis", action="append", default=None, help="only this AMB axis, e.g. amb1_y (repeatable)")
    p.add_argument("--out", type=Path, default=None, help="PNG: Bode magnitude per axis with the zone bands")

    unbalance_report.add_parser(sub, _common, grid)
    return ap


def run_args(args: argparse.Namespace) -> tuple[dict, str]:
    """Run one parsed verb: (JSON-able result, text).  AmbError (one line) on bad input."""
    from . import analysis, guards, unbalance_report  # import numpy

    runners = {"unbalance": unbalance_report.run_unbalance}  # verbs outside analysis.py
    guards.check_args(args)
    return runners.get(args.verb, getattr(analysis, f"run_{args.verb}", None))(args)


def run(argv: list[str]) -> tuple[dict, str]:
    """``amb-dynamics ARGV`` in this process (for reports that gather several analyses)."""
    return run_args(build_parser().parse_args(argv))


def main(argv: list[str] | None = None) -> int:
    limit_blas_threads()  # first: BLAS reads its thread count when numpy loads (amb_dynamics/threads.py)
    from . import guards
    from .dask_exec import Interrupted

    args = build_parser().parse_args(argv)
    # the chart writes its own JSON file; --json there also prints the summary
    try:
        result, text = run_args(args)
    except AmbError as exc:
        print(f"amb-dynamics {args.verb}: error: {exc}", file=sys.stderr)
        return 2
    except Interrupted as exc:  # first Ctrl-C / SIGTERM of a chart or sweep: workers killed, nothing half-written
        print(f"\namb-dynamics {args.verb}: stopped by signal {exc.signum}", file=sys.stderr)
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(128 + exc.signum)  # workers are killed; skip the cluster's atexit close (seconds)
    if args.json:
        result, replaced = guards.finite_json(result)  # JSON has no NaN: null, and say where
        if replaced:
            result["non_finite"] = replaced
        json.dump({"schema_version": 1, **result}, sys.stdout, indent=1, allow_nan=False)
        print()
    else:
        print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
