"""The verbs of ``amb-dynamics``: each takes parsed arguments, returns (JSON-able dict, human-readable text)."""

from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import guards, plots
from .analysis_sensitivity import run_sensitivity  # noqa: F401  (the `sensitivity` verb)
from .config import RotorConfig, load_config
from .delay_margin import delay_margin, margin_text
from .digital_floquet import estimate_point, verdict_of
from .errors import InputError
from .floquet import aperiodic_exponents, floquet, hybrid_period, sampled_floquet
from .forced_orbit import orbit_floquet
from .modes import OVERDAMPED_ZETA, campbell_data, modes_at_speed
from .motion import BaseMotion, Harmonic
from .newmark import disk_initial_state, fit_growth_rate, newmark
from .preflight import digital_over_speeds
from .rig_loop import levitated_bearing
from .sampled import SampledLoop
from .structure import StructuralModel, build_structure
from .system import ClosedLoop, closed_loop, periodic_system


@dataclass
class Setup:
    cfg: RotorConfig
    model: StructuralModel
    loop: ClosedLoop


def setup(args, digital: bool = False) -> Setup:
    """Config, structure and continuous loop of a command.  The continuous analyses run on the full FE model;
    ``modal_cutoff`` serves the digital loop only (``digital=True``: the sampled-data analyses)."""
    overrides = list(args.overrides)
    if getattr(args, "formulation", None):
        overrides.append(f"formulation={args.formulation}")
    cfg = load_config(args.config, overrides)
    model = build_structure(cfg if digital else dataclasses.replace(cfg, modal_cutoff=None))
    return Setup(cfg, model, closed_loop(model, cfg))


def describe(cfg: RotorConfig, model: StructuralModel) -> str:
    red = f", modal cutoff {cfg.modal_cutoff:g} rad/s ({model.n} modes)" if model.basis is not None else ", full FE"
    return f"{Path(cfg.source).name}: {cfg.shaft.elements} elements, {cfg.formulation}{red}"


def motion_of(args, cfg: RotorConfig) -> BaseMotion:
    """The base motion of the command line, or the config's ``base_motion`` when --motion is not given."""
    if args.motion is None:
        return BaseMotion.from_config(cfg.base_motion)
    if args.motion == "none":
        return BaseMotion()
    if args.motion == "combined":
        if not args.harmonic:
            raise InputError("--motion combined needs at least one --harmonic axis:A:omega")
        for axis, amp, freq, _ in args.harmonic:
            BaseMotion.single(axis, amp, freq)  # validates each harmonic
        return BaseMotion(tuple(Harmonic(*h) for h in args.harmonic), "combined")
    return BaseMotion.single(args.motion, args.amplitude, args.frequency)


def motion_dict(motion: BaseMotion) -> dict:
    return {
        "kind": motion.kind,
        "harmonics": [
            {"axis": h.axis, "amplitude_rad": h.amplitude, "frequency_rad_s": h.frequency, "phase_rad": h.phase}
            for h in motion.harmonics
        ],
    }


def motion_text(motion: BaseMotion) -> str:
    if motion.is_static:
        return "base at rest"
    return " + ".join(f"{h.axis} {h.amplitude:g} rad at {h.frequency:g} rad/s" for h in motion.harmonics)


def digital_at_speeds(cfg: RotorConfig, speeds_rpm, margins: bool = False) -> tuple[list[dict], str]:
    """The digital loop's verdict at rest per speed (preflight), on the model the rig steps (``modal_cutoff``
    applies, unlike the modes' full FE model), and that model's description; ``margins``: with the delay margin of
    each stable loop (``delay_margin``, :mod:`amb_dynamics.delay_margin`)."""
    model = build_structure(cfg)
    digital = digital_over_speeds(model, cfg, speeds_rpm)
    for d in digital if margins else ():
        if d["stable"]:
            d["delay_margin"] = delay_margin(model, cfg, d["spin_speed_rpm"])
    return digital, describe(cfg, model)


def run_modes(args):
    s = setup(args)
    results = [modes_at_speed(s.model, s.loop, v) for v in args.speed_rpm]
    digital, digital_model = digital_at_speeds(s.cfg, args.speed_rpm, margins=True)
    data = {"model": describe(s.cfg, s.model), "digital_loop_model": digital_model,
            "speeds": [r.to_dict() for r in results]}  # fmt: skip
    for d, dig in zip(data["speeds"], digital, strict=True):
        d["digital_loop"] = dig
    lines = [data["model"]]
    if data["digital_loop_model"] != data["model"]:
        lines.append(f"digital loop on {data['digital_loop_model']}")
    for r, dig in zip(results, digital, strict=True):
        lines.append(f"\n{r.speed_rpm:g} rpm   {digital_line(dig)}")
        lines.append(f"{r.speed_rpm:g} rpm   freq (rad/s)   freq (Hz)   damping   whirl     eigenvalue")
        for m in r.modes:
            if args.max_frequency and m.frequency_rad_s > args.max_frequency:
                continue
            lam = m.eigenvalue
            lines.append(
                f"         {m.frequency_rad_s:12.4f} {m.frequency_rad_s / 2 / np.pi:11.4f} "
                f"{m.damping_ratio:9.5f}   {m.whirl:8s}  {lam.real:+.5g}{lam.imag:+.5g}j"
            )
        if r.real_roots:
            lines.append("         overdamped real roots (1/s): " + ", ".join(f"{x:.5g}" for x in r.real_roots))
        if r.overdamped:  # real roots that spinning made into pairs (amb_dynamics.modes.OVERDAMPED_ZETA)
            pairs = ", ".join(f"{z.real:.5g}+-{z.imag:.4g}j" for z in r.overdamped)
            lines.append(f"         overdamped pairs, damping ratio >= {OVERDAMPED_ZETA:g} (1/s): {pairs}")
    return data, "\n".join(lines)


def run_campbell(args):
    s = setup(args)
    t0 = time.perf_counter()
    results = campbell_data(s.model, s.loop, args.speeds)
    out = plots.campbell_figure(results, f"Campbell diagram: {describe(s.cfg, s.model)}", args.out, args.max_frequency)
    digital, digital_model = digital_at_speeds(s.cfg, args.speeds)
    data = {
        "png": str(out),
        "model": describe(s.cfg, s.model),
        "digital_loop_model": digital_model,
        "speeds_rpm": args.speeds.tolist(),
        "seconds": time.perf_counter() - t0,
        "speeds": [r.to_dict() | {"digital_loop": dig} for r, dig in zip(results, digital, strict=True)],
    }
    bad = [d["spin_speed_rpm"] for d in digital if not d["stable"]]
    worst = max(digital, key=lambda d: d["spectral_radius_per_sample"])
    verdict = (
        f"digital loop ({worst['rate_hz']:g} Hz, delay {worst['delay_samples']}) stable at all {len(digital)} speeds, "
        f"largest max|mu| per sample {worst['spectral_radius_per_sample']:.7g}"
        if not bad
        else f"WARNING: the digital loop ({worst['rate_hz']:g} Hz, delay {worst['delay_samples']}) is UNSTABLE at "
        f"{len(bad)} of {len(digital)} speeds ({min(bad):g}-{max(bad):g} rpm; max|mu| per sample up to "
        f"{worst['spectral_radius_per_sample']:.6g})"
    )
    if data["digital_loop_model"] != data["model"]:
        verdict += f"\ndigital loop on {data['digital_loop_model']}"
    return data, f"Campbell diagram ({len(results)} speeds) written to {out}\n{verdict}"


def digital_line(d: dict) -> str:
    """One line: the digital loop's verdict at rest (preflight.digital_at_rest)."""
    word = "stable" if d["stable"] else "UNSTABLE"
    return (
        f"digital loop {d['rate_hz']:g} Hz, delay {d['delay_samples']}: {word}, max|mu| per sample "
        f"{d['spectral_radius_per_sample']:.7g} (margin {d['margin']:.3g}; slowest pole {d['growth_rate_1_s']:.4g} 1/s "
        f"at {d['frequency_rad_s']:.5g} rad/s)" + (f"; {margin_text(d['delay_margin'])}" if "delay_margin" in d else "")
    )


def run_floquet(args):
    s = setup(args, digital=args.controller == "sampled")
    motion = motion_of(args, s.cfg)
    ps = periodic_system(s.loop, motion, s.cfg.spin_rad_s)
    if motion.is_static:
        raise InputError("a static base gives no periodic A(t): use `amb-dynamics modes` for its eigenvalues")
    if ps.period is None:
        return _aperiodic(s, ps, motion, args)
    if args.controller == "continuous":
        if args.about != "centre":
            raise InputError(f"--about {args.about} needs --controller sampled (the digital loop the rig runs)")
        res = floquet(ps)
        data = res.to_dict(args.top)
    elif args.about == "orbit":
        data = _orbit_floquet(s, motion, ps.period)
    else:
        Ts = 1.0 / s.cfg.controller.rate_hz
        bearing = levitated_bearing(s.model, s.cfg, Ts) if args.about == "rest" else None
        loop = SampledLoop(s.model, s.cfg, forcing=False, bearing=bearing)
        pr = hybrid_period(ps.period, loop.Ts) if ps.period is not None else None
        # work in controller samples: the hybrid period, or the three integer ratios of the estimate
        cost = pr[0] if pr else (1 if args.snap else 3) * round((ps.period or 0.0) / loop.Ts)
        guards.check_sampled(ps.period, loop.Ts, int(cost))
        if args.snap:
            data = sampled_floquet(loop, motion, ps.period, snap=True).to_dict(args.top)
        else:  # exact for T/Ts = p/r, else interpolated in T/Ts with an error bound (digital_floquet)
            data = estimate_point(loop, motion, ps.period)
            data["multipliers"] = data["multipliers"][: args.top]
        data["controller_rate_hz"] = 1.0 / loop.Ts
    data.update(
        model=describe(s.cfg, s.model), controller=args.controller, motion=motion_dict(motion), about=args.about
    )
    text = [
        f"{data['model']}; {motion_text(motion)}, {args.controller} controller, {ABOUT[args.about]}",
        f"period {data['period_s']:.6g} s   max|mu| = {data['max_abs_multiplier']:.9f}   "
        f"{'STABLE' if data['stable'] else 'NOT STABLE'}   ({data['method']}, {data.get('steps', '-')} steps)",
    ]
    for z in (data.get("multipliers") or [])[: args.top]:
        text.append(f"   mu = {z[0]:+.9f} {z[1]:+.9f}j   |mu| = {np.hypot(*z):.9f}")
    text += [f"   note: {n}" for n in data.get("notes", [])]
    return data, "\n".join(text)


ABOUT = {
    "centre": "bearing law at the centre",
    "rest": "bearing law at the levitated point, level base",
    "orbit": "bearing law along the forced orbit",
}


def _orbit_floquet(s: Setup, motion: BaseMotion, period: float) -> dict:
    """The digital loop about its forced orbit (amb_dynamics.forced_orbit), beside its value at rest."""
    guards.check_sampled(period, 1.0 / s.cfg.controller.rate_hz, 6 * round(period * s.cfg.controller.rate_hz))
    data = orbit_floquet(s.model, s.cfg, motion, period)
    Ts = 1.0 / s.cfg.controller.rate_hz
    rest = estimate_point(SampledLoop(s.model, s.cfg, forcing=False, bearing=levitated_bearing(s.model, s.cfg, Ts)),
                          motion, period)  # fmt: skip
    rho = data["max_abs_multiplier"]
    stable, verdict = verdict_of(rho, data["error_bound"])
    data.update(
        stable=stable,
        verdict=verdict,
        growth_rate_1_s=float(np.log(rho) / period),
        controller_rate_hz=s.cfg.controller.rate_hz,
        multipliers=None,
        at_rest_max_abs_multiplier=rest["max_abs_multiplier"],
        notes=[
            "forced orbit (gravity turning with the base; noise, unbalance and runout left out): swing "
            + ", ".join(f"{c} {v * 1e6:.3g} um" for c, v in zip(s.model.channels, data["orbit_swing_m"], strict=True))
            + f"; about the levitated point on a level base the loop gives max|mu| = {rest['max_abs_multiplier']:.9f}"
        ],
    )
    return data


def _aperiodic(s: Setup, ps, motion: BaseMotion, args):
    """Incommensurate harmonics: no monodromy; Lyapunov-type growth measures (docs/physics.md#aperiodic)."""
    if args.controller != "continuous":
        raise InputError("an aperiodic base motion is analysed with the continuous controller only")
    fastest = max(h.frequency for h in motion.harmonics)
    data = aperiodic_exponents(ps, args.horizon, h=2 * np.pi / fastest / 64)
    data.update(
        model=describe(s.cfg, s.model),
        controller=args.controller,
        motion=motion_dict(motion),
        period_s=None,
        multipliers=None,
        stable=bool(data["lyapunov_exponent_1_s"] < 0),
        method="magnus4-lyapunov",
        notes=["the harmonics are incommensurate: A(t) has no period"],
    )
    text = (
        f"{data['model']}; {motion_text(motion)}: no period (incommensurate)\n"
        f"largest Lyapunov exponent {data['lyapunov_exponent_1_s']:.6g} 1/s, finite-time exponent "
        f"{data['ftle_1_s']:.6g} 1/s over {data['duration_s']:g} s, max ||Phi(t,0)|| = "
        f"{data['max_transition_norm']:.4g}"
    )
    return data, text


def run_chart(args):
    from .chart_cli import run_chart as chart_verb

    return chart_verb(args, setup(args, digital=args.controller == "sampled"), describe)


def run_sweep(args):
    from .sweep import run_sweep as sweep_verb

    return sweep_verb(args, describe)


def run_simulate(args):
    s = setup(args)
    motion = motion_of(args, s.cfg)
    if getattr(args, "sampled", False):  # the digital loop on the rig plant (the plant node's stepping code)
        from .rig_sim import run_sampled

        return run_sampled(s, motion, args, describe)
    ps = periodic_system(s.loop, motion, s.cfg.spin_rad_s)
    disk_node = s.cfg.disks[0].node if s.cfg.disks else s.cfg.n_nodes
    x0 = disk_initial_state(s.model, s.loop.N, disk_node)
    if ps.period is not None:
        T, h = ps.period, ps.period / args.steps_per_period
        every = args.steps_per_period
    else:
        T, h, every = None, 2e-4, 1
    steps = round(args.duration / h)
    if steps < 1:
        raise InputError("--duration must cover at least one time step")
    guards.check_simulate_steps(steps)
    run = newmark(ps, s.model.M, x0, h, steps, every=1, forcing=s.cfg.base_forcing)
    q_fe = s.model.to_fe(run.x[:, : s.model.n])
    disk = q_fe[:, 4 * (disk_node - 1) : 4 * (disk_node - 1) + 2]
    t_strobe, n_strobe = run.t[::every], np.linalg.norm(run.x[::every], axis=1)
    sigma, c0, tt = fit_growth_rate(t_strobe, n_strobe)
    data = {
        "model": describe(s.cfg, s.model),
        "duration_s": float(run.t[-1]),
        "step_s": h,
        "steps": steps,
        "newmark_growth_rate_1_s": sigma,
        "peak_disk_displacement_m": float(np.abs(disk).max()),
    }
    if T is not None:
        fl = floquet(ps)
        sigma_f = float(np.log(fl.max_abs) / T)
        data.update(
            period_s=T,
            floquet_growth_rate_1_s=sigma_f,
            max_abs_multiplier=fl.max_abs,
            stable=fl.stable,
            relative_difference=abs(sigma - sigma_f) / max(abs(sigma_f), 1e-300),
        )
        # the fit is only comparable once the subdominant multipliers have decayed by 1e-2 (docs/physics.md#newmark)
        gap = np.log(fl.max_abs / max(abs(fl.multipliers[2]), 1e-300)) / T  # [0], [1]: a conjugate pair
        needed = np.log(100.0) / gap if gap > 0 else np.inf
        data["fit_window_start_s"] = float(tt[0])
        data["fit_window_valid"] = bool(tt[0] >= needed)
        if tt[0] < needed:
            data["notes"] = [
                f"subdominant multipliers have not decayed by 1e-2 before the fit window (needs t >= {needed:.3g} s,"
                f" window starts at {tt[0]:.3g} s): run --duration {2 * needed:.3g} or more to compare growth rates"
            ]
    png = plots.response_figure(
        run.t,
        disk,
        [f"v node {disk_node}", f"w node {disk_node}"],
        (t_strobe, n_strobe),
        (tt, sigma, c0),
        f"Newmark response: {data['model']}",
        args.out,
    )
    data["png"] = str(png)
    text = (
        f"{data['model']}: {steps} Newmark steps of {h:.4g} s; growth rate (Newmark fit) {sigma:.6g} 1/s"
        + (
            f", Floquet {data['floquet_growth_rate_1_s']:.6g} 1/s (max|mu| {data['max_abs_multiplier']:.9f})"
            if T is not None
            else ""
        )
        + "".join(f"\nnote: {n}" for n in data.get("notes", []))
        + f"\nPNG: {png}"
    )
    return data, text


def _write_json(path: Path, data: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".part")
    tmp.write_text(json.dumps({"schema_version": 1, **guards.finite_json(data)[0]}, allow_nan=False))
    tmp.replace(path)
