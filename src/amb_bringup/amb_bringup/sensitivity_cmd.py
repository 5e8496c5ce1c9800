"""``amb-rig sensitivity``: measure S_jj of one AMB axis on the running loop (ISO 14839-3), model beside it.

    amb-rig sensitivity --axis amb1_y [--band 5:50] [--duration 20] [--amplitude 1e-5] [--kind multisine]
                        [--resolution 0.5] [--mode lockstep|realtime] [--no-plant] [--config F] [--set K=V]
                        [--force] [--json] [--out S.png]

Runs the rig (`amb-rig run` machinery, static base, no monitor) with the controller's injection on ``--axis``,
records /amb/injection into a bag, estimates S = y_m/E (H1, coherence; :mod:`amb_bag.sensitivity`) and puts the
model of the digital loop (:mod:`amb_dynamics.sensitivity`, same config) beside it.  Everything that can be
checked before starting (axis, band, Nyquist, amplitude vs current and slew limits) is, with one line and exit 2.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import sys
import tempfile
from pathlib import Path

from amb_dynamics.errors import AmbError

EXIT_FAILED, EXIT_USAGE = 1, 2


def add_parser(sub) -> None:
    s = sub.add_parser("sensitivity", help="measure the sensitivity S_jj of one AMB axis (ISO 14839-3)")
    s.add_argument("--axis", required=True, help="AMB axis, e.g. amb1_y")
    s.add_argument("--band", default="5:50", help="injection band lo:hi (Hz)")
    s.add_argument("--duration", type=float, default=20.0, help="injection length (s): simulated in lockstep")
    s.add_argument("--amplitude", type=float, default=1e-5, help="peak of the injected disturbance E (m)")
    s.add_argument("--kind", choices=("multisine", "swept", "stepped"), default="multisine")
    s.add_argument("--resolution", type=float, default=0.5, help="frequency resolution (Hz) = multisine spacing")
    s.add_argument("--settle", type=float, default=2.0, help="s of the injection's start left out (transient)")
    s.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep")
    s.add_argument("--no-plant", action="store_true", help="no plant: a real rig supplies /amb/displacement")
    s.add_argument("--config", help="rotor config YAML (default: the seed rotor)")
    s.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="config override (repeatable)")
    s.add_argument("--force", action="store_true", help="inject even if the predicted current exceeds the limit")
    s.add_argument("--keep-bag", help="keep the recorded bag in this folder")
    s.add_argument("--json", action="store_true")
    s.add_argument("--out", help="PNG: measured and model |S| with the zone bands, coherence")


def check(args):
    """Validate before starting anything: returns (cfg, model, axis index, band); AmbError with one line."""
    from amb_dynamics.analysis_sensitivity import parse_band
    from amb_dynamics.config import load_config
    from amb_dynamics.errors import InputError
    from amb_dynamics.injection import Injection, InjectionSpec, overload, predicted_load
    from amb_dynamics.structure import build_structure

    cfg = load_config(args.config, args.set)
    model = build_structure(cfg)
    if args.axis not in model.channels:
        raise InputError(f"--axis {args.axis!r} does not exist (axes: {', '.join(model.channels)})")
    band = parse_band(args.band)
    if args.settle < 0 or args.settle >= args.duration:
        raise InputError(f"--settle {args.settle:g} s must be >= 0 and shorter than --duration {args.duration:g} s")
    spec = InjectionSpec(args.kind, args.amplitude, band, args.duration, 0.0, args.resolution)
    inj = Injection(spec, cfg.controller.rate_hz)
    j = model.channels.index(args.axis)
    why = overload(predicted_load(model, cfg, j, inj), cfg)
    if why is not None and not args.force:
        raise InputError(
            f"--amplitude {args.amplitude:g} m would drive {why} on {args.axis} (model of the digital loop): "
            "lower it or use --force"
        )
    return cfg, model, j, band


def run_args(args, bag: Path, log_dir: Path):
    """The `amb-rig run` arguments of this measurement."""
    from .rig import parser

    argv = ["run", "--duration", repr(args.duration + 0.05), "--motion", "none", "--mode", args.mode]
    argv += ["--no-monitor", "--bag", str(bag), "--log-dir", str(log_dir)]
    argv += [f"--set={s}" for s in args.set] + (["--config", args.config] if args.config else [])
    argv += ["--no-plant"] if args.no_plant else []
    lo, hi = args.band.split(":")
    for name, value in (
        ("kind", args.kind),
        ("axis", args.axis),
        ("amplitude", repr(args.amplitude)),
        ("band_lo_hz", repr(float(lo))),
        ("band_hi_hz", repr(float(hi))),
        ("duration_s", repr(args.duration)),
        ("resolution_hz", repr(args.resolution)),
        ("force", "true" if args.force else "false"),
    ):
        argv += ["--param", f"controller:injection_{name}={value}"]
    return parser().parse_args(argv)


def main_sensitivity(args) -> int:
    from amb_ros.env import DdsEnvError, ensure_localhost_dds, hold_run_lock

    from .rig import LOCK_WAIT_S, _waiting_note, run

    try:
        ensure_localhost_dds()
        cfg, model, j, band = check(args)
        lock = hold_run_lock(os.environ["ROS_DOMAIN_ID"], LOCK_WAIT_S, _waiting_note(LOCK_WAIT_S))
    except (AmbError, DdsEnvError) as exc:
        print(f"amb-rig sensitivity: {exc}", file=sys.stderr)
        return EXIT_USAGE
    work = Path(tempfile.mkdtemp(prefix="amb-rig-sensitivity-"))
    bag = Path(args.keep_bag) if args.keep_bag else work / "bag"
    keep = False
    try:
        rargs = run_args(args, bag, work / "logs")
        with contextlib.redirect_stdout(sys.stderr):  # the run's summary goes to stderr, the result to stdout
            rc = run(rargs, cfg, lock)
        if rc != 0:
            keep = True
            print(f"amb-rig sensitivity: the run failed (exit {rc}); logs in {work / 'logs'}", file=sys.stderr)
            return EXIT_FAILED
        report = analyse(args, cfg, model, j, band, bag)
    except AmbError as exc:
        print(f"amb-rig sensitivity: {exc}", file=sys.stderr)
        return EXIT_FAILED
    finally:
        if not keep:
            shutil.rmtree(work, ignore_errors=True)
    print(json.dumps(report, indent=1) if args.json else text(report))
    return 0


def analyse(args, cfg, model, j: int, band, bag: Path) -> dict:
    """Measured S_jj from the bag, the model's curve at the same frequencies and the model's peak and zone."""
    from amb_bag.sensitivity import (
        add_fitted_model,
        measured_sensitivity,
        model_abs_at,
        read_injection,
        sensitivity_report,
    )
    from amb_dynamics.analysis_sensitivity import model_sensitivity

    t, e, ym = read_injection(bag, args.axis)
    m, notes = measured_sensitivity(t, e, ym, args.resolution, args.settle, band)
    report = sensitivity_report(m, notes, args.axis, cfg.iso14839.sensitivity_zone_limits,
                                model_abs_at(cfg, args.axis, m.frequency_hz))  # fmt: skip
    add_fitted_model(report, m, cfg, args.axis)
    mod = model_sensitivity(model, cfg, cfg.spin_speed_rpm, "sampled", band, 2000, [args.axis])
    report["model_peak"] = mod["axes"][args.axis]
    report.update(mode=args.mode, kind=args.kind, amplitude_m=args.amplitude, band_hz=list(band),
                  rate_hz=cfg.controller.rate_hz, speed_rpm=cfg.spin_speed_rpm, samples=int(t.size))  # fmt: skip
    if args.out:
        from amb_dynamics.plots_sensitivity import measured_figure

        report["png"] = str(measured_figure(report, cfg.iso14839.sensitivity_zone_limits, f"{args.axis}", args.out))
    return report


def text(r: dict) -> str:
    from amb_bag.sensitivity import format_report

    mp = r["model_peak"]
    return (
        format_report(r)
        + f"\nmodel peak in the band: |S| {mp['peak_abs']:.4g} ({mp['peak_db']:.2f} dB) at {mp['peak_hz']:.4g} Hz, "
        f"zone {mp['zone']}"
    )
