"""``amb-rig report``: one self-contained HTML commissioning report for a design review (ISO 14839).

The model part comes from the ``amb-dynamics`` verbs run in this process (modes, Campbell, sensitivity of the
digital loop the rig runs, unbalance response, stability chart), the run part from a recorded bag (``--bag``):
the monitor's verdict, the plant's vibration zones and, when the run had a sensor-signal injection, the measured
sensitivity beside the model.  Figures are PNGs embedded in the file (:mod:`.report_html`).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from amb_dynamics.errors import AmbError, InputError

EXIT_USAGE = 2
MONITOR_KEYS = ("verdict", "unstable", "rho", "rho std", "rho scatter", "model rho", "model mismatch",
                "flag raised at (s)", "periods used", "base period (s)", "state")  # fmt: skip
CYCLE = 64  # samples of one synchronous cycle for the model's vibration measure


def add_parser(sub) -> None:
    p = sub.add_parser("report", help="self-contained HTML commissioning report (model; with --bag: a run)")
    p.add_argument("--config", help="rotor config YAML (default: the bag's recorded config, else the seed rotor)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="config override (repeatable)")
    p.add_argument("--bag", help="a recorded amb-rig run: monitor verdict, vibration zones, measured sensitivity")
    p.add_argument("--speeds", type=float, nargs="+", default=None, help="rpm for modes and S (default: 0, operating)")
    p.add_argument("--chart-motion", choices=("roll", "pitch", "yaw"), default="pitch")
    p.add_argument("--chart-amplitude", type=_grid_text, default="0:0.4:9", help="lo:hi:n or a,b,c (rad)")
    p.add_argument("--chart-frequency", type=_grid_text, default="4:40:19", help="lo:hi:n or a,b,c (rad/s)")
    p.add_argument(
        "--chart-controller",
        choices=("continuous", "sampled"),
        default="sampled",
        help="sampled (default): the digital loop the rig runs; continuous: its continuous-time idealisation",
    )
    p.add_argument("--resolution", type=float, default=0.5, help="the bag's injection: multisine spacing (Hz)")
    p.add_argument("--settle", type=float, default=2.0, help="the bag's injection: s of its start left out")
    p.add_argument("--out", default="out/report.html", help="the HTML file")


def _grid_text(text: str) -> str:
    """Checked like amb-dynamics chart's grids (argparse's one-line error), kept as text for it."""
    from amb_dynamics.cli import grid

    grid(text)
    return text


def main_report(args: argparse.Namespace) -> int:
    from .report_html import render

    try:
        with tempfile.TemporaryDirectory(prefix="amb-rig-report-") as tmp:
            doc = gather(args, Path(tmp))
            html = render(doc)
        out = Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        part = out.with_name(out.name + ".part")  # nothing half-written: rename when complete
        part.write_text(html, encoding="utf-8")
        part.replace(out)
    except (AmbError, OSError) as exc:
        print(f"amb-rig report: {exc}", file=sys.stderr)
        return EXIT_USAGE
    print(f"commissioning report written to {out} ({len(doc['figures'])} figures)")
    return 0


def _config_args(args, tmp: Path) -> tuple[list[str], object, str]:
    """(--config/--set arguments for the amb-dynamics verbs, the RotorConfig, its name) of the report."""
    from amb_dynamics.config import load_config, to_dict

    sets = [f"--set={s}" for s in args.set]
    if args.config or not args.bag:
        cfg = load_config(args.config, args.set)
        return (["--config", args.config] if args.config else []) + sets, cfg, str(cfg.source)
    import yaml

    from amb_bag.reader import Bag
    from amb_bag.runconfig import recorded_config

    rec = recorded_config(Bag(args.bag))
    if rec is None:
        raise InputError(f"{args.bag}: the bag has no recorded config (/amb_plant/config): give --config")
    path = tmp / "recorded.yaml"
    path.write_text(yaml.safe_dump(to_dict(rec), sort_keys=False))
    return ["--config", str(path), *sets], load_config(path, args.set), f"{args.bag} (the run's recorded config)"


def gather(args, tmp: Path) -> dict:
    """Every section's data and figure paths (read into the HTML by the renderer)."""
    from amb_dynamics.cli import run
    from amb_dynamics.control_law import describe as controller_text

    common, cfg, name = _config_args(args, tmp)
    op = cfg.spin_speed_rpm
    speeds = args.speeds if args.speeds is not None else sorted({0.0, op})
    top = cfg.max_speed_rpm or max(3000.0, 1.5 * op)
    modes, _ = run(["modes", *common, "--speed-rpm", *map(str, speeds)])
    _, campbell_text = run(["campbell", *common, "--speeds", f"0:{top:g}:31", "--out", str(tmp / "campbell.png")])
    band = f"1:{min(500.0, 0.45 * cfg.controller.rate_hz):g}"
    sens, sens_text = run(["sensitivity", *common, "--controller", "sampled", "--speed-rpm", *map(str, speeds),
                           "--band", band, "--out", str(tmp / "S.png")])  # fmt: skip
    try:
        unb, _ = run(["unbalance", *common, "--speed-rpm", str(op), "--out", str(tmp / "unbalance.png")])
        unbalance = unb["speeds"][0]
    except InputError as exc:  # the paper's rotor has no unbalance: say so in its section
        unbalance = {"speed_rpm": op, "missing": str(exc)}
    chart, chart_text = run(["chart", *common, "--motion", args.chart_motion, "--amplitude", args.chart_amplitude,
                             "--frequency", args.chart_frequency, "--controller", args.chart_controller,
                             "--workers", "1", "--no-cache", "--out", str(tmp / "chart.png")])  # fmt: skip
    doc = {
        "title": f"Commissioning report: {Path(name.split(' (')[0]).name}",
        "config": name,
        "rotor": modes["model"],
        "controller": _controller_rows(cfg, controller_text(cfg)),
        "modes": modes["speeds"],
        "campbell": campbell_text.splitlines()[-1],
        "sensitivity": sens,
        "sensitivity_lines": [ln for ln in sens_text.splitlines() if "UNSTABLE" in ln],
        "unbalance": unbalance,
        "vibration_model": None if "missing" in unbalance else _model_vibration(cfg, unbalance),
        "chart": chart | {"text": chart_text.splitlines()[0] if chart_text else ""},
        "figures": {
            "Campbell diagram": tmp / "campbell.png",
            "Sensitivity of the digital loop (model)": tmp / "S.png",
            **({} if "missing" in unbalance else {"Unbalance response": tmp / "unbalance.png"}),
            f"Stability chart ({args.chart_motion})": tmp / "chart.png",
        },
    }
    doc["run"] = _run_part(args, cfg, tmp, doc["figures"]) if args.bag else None
    return doc


def _controller_rows(cfg, law: str) -> list[tuple[str, str]]:
    c, b = cfg.controller, cfg.bearings
    return [
        ("controller", law),
        ("rate", f"{c.rate_hz:g} Hz, delay {c.delay_samples} sample(s)"),
        (
            "PID gains",
            f"kp {c.proportional_gain:g} A/m, kd {c.derivative_gain:g} A s/m, kI {c.integral_gain:g} A/(m s)",
        ),
        ("current limit", f"{c.current_limit:g} A"),
        ("bearings", f"nodes {list(b.nodes)}, ki {b.current_stiffness:g} N/A, ks {b.displacement_stiffness:g} N/m"),
        ("operating speed", f"{cfg.spin_speed_rpm:g} rpm (max {cfg.max_speed_rpm or '-'} rpm)"),
    ]


def _model_vibration(cfg, unb: dict) -> dict:
    """ISO 14839-2 zones of the model's synchronous unbalance response at the operating speed."""
    from amb_dynamics.iso14839 import clearance_of, vibration_zones

    phase = 2 * np.pi * np.arange(CYCLE) / CYCLE
    samples = {axis: a * np.cos(phase) for axis, a in unb["amplitude_m"].items()}
    zones = vibration_zones(samples, clearance_of(cfg), cfg.iso14839.vibration_zone_limits,
                            cfg.iso14839.vibration_measure)  # fmt: skip
    return {axis: z.to_dict() for axis, z in zones.items()}


def _run_part(args, cfg, tmp: Path, figures: dict) -> dict:
    """Monitor verdict, vibration zones and (with an injection) measured sensitivity of a recorded run."""
    from amb_bag.info import last_report, recorded_vibration
    from amb_bag.reader import Bag

    bag_path = args.bag
    bag = Bag(bag_path)
    monitor = last_report(bag, "stability_monitor")
    out = {
        "bag": str(bag_path),
        "duration_s": (bag.end_ns - bag.start_ns) * 1e-9 if bag.message_count else 0.0,
        "monitor": {k: monitor[k] for k in MONITOR_KEYS if monitor and k in monitor} if monitor else None,
        "vibration": recorded_vibration(bag),
        "sensitivity": None,
    }
    axis = _injected_axis(bag)
    if axis is not None:
        out["sensitivity"] = _measured(bag_path, cfg, axis, tmp / "S_measured.png", args.resolution, args.settle)
        figures[f"Measured sensitivity {axis}"] = tmp / "S_measured.png"
    return out


def _injected_axis(bag) -> str | None:
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import JointState

    from amb_bag.sensitivity import INJECTION

    if INJECTION not in bag.topics:
        return None
    for _t, _type, _log, _pub, data in bag.messages([INJECTION]):
        names = list(deserialize_message(data, JointState).name)
        if names:
            return names[0].rsplit("_", 1)[0]
    return None


def _measured(bag_path: str, cfg, axis: str, png: Path, resolution_hz: float, settle_s: float) -> dict:
    from amb_bag.sensitivity import (
        add_fitted_model,
        measured_sensitivity,
        model_abs_at,
        read_injection,
        sensitivity_report,
    )
    from amb_dynamics.plots_sensitivity import measured_figure

    t, e, ym = read_injection(bag_path, axis)
    m, notes = measured_sensitivity(t, e, ym, resolution_hz, settle_s)
    limits = cfg.iso14839.sensitivity_zone_limits
    report = sensitivity_report(m, notes, axis, limits, model_abs_at(cfg, axis, m.frequency_hz))
    add_fitted_model(report, m, cfg, axis)
    measured_figure(report, limits, f"{axis}: measured and model", png)
    keys = ("axis", "peak", "resolution_hz", "coherent_bins", "max_rel_error_where_coherent",
            "max_difference_in_random_errors", "notes", "fitted_model")  # fmt: skip
    return {k: report[k] for k in keys if k in report}
