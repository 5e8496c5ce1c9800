"""Search a digital PD with lead-lag and notch filters for the real rig at a given rate: `.venv/bin/python
tools/controller_search.py --rate 2000 [--lead-lags 2] [--notches 1] [--objective sensitivity] [--seed 7]`.

The digital loop the rig runs (sampled plant with its amplifier and sensor filter on the full FE model, the
controller at ``--rate`` with its filters Tustin-prewarped, as amb_dynamics.control_law builds it) is judged at
the spin speeds ``--speeds`` (rpm) and on the nominal plant and three perturbed ones (``VARIANTS``: amplifier and
sensor 20 % slower, shaft damping 25 % lower), so that a controller which only just holds on the nominal model
is not chosen.  ``--objective radius``: the largest spectral radius per sample; ``sensitivity``: the largest peak
of |S_jj| (ISO 14839-3) over every axis, speed and variant, where every one of them is stable (else 1000 x the
radius).  scipy's differential evolution varies kp and kd (multiples of the config's; ki kp >= 1.3 |ks|, so the
bearing keeps 30 % of the net stiffness of the default), the zero and pole of each lead-lag and the frequency,
width and depth of each notch.  Prints the result per speed and variant, the peaks by amb-dynamics sensitivity's
own method, and the controller section of a rotor file (config/seed_rotor_2khz.yaml: ``--maxiter 150``).
"""

from __future__ import annotations

import argparse
import os

from amb_dynamics.threads import single_thread_env

os.environ.update(single_thread_env())  # one BLAS thread, set before numpy loads (amb_dynamics/threads.py)
import numpy as np
from scipy.optimize import differential_evolution

from amb_dynamics.analysis_sensitivity import model_sensitivity
from amb_dynamics.config import load_config
from amb_dynamics.errors import AmbError
from amb_dynamics.sensitivity import ModalResponse, loop_state_spaces, sensitivity_state_space
from amb_dynamics.structure import build_structure

VARIANTS = ((), ("actuator.bandwidth_hz=1600",), ("sensor.filter_hz=4000",), ("structural_damping.beta=6e-5",))
UNSTABLE = 1000.0  # objective tiers of unstable loops (above any stable peak): see score()
GRID = 300  # log-spaced frequencies of the peak estimate, plus every closed-loop pole's own frequency


def filters_yaml(x: np.ndarray, lead_lags: int) -> list[str]:
    """Flow-style YAML of each filter of the parameter vector (after kp and kd scales)."""
    out = [
        f"{{kind: lead_lag, zero_hz: {z:.6g}, pole_hz: {p:.6g}}}" for z, p in x[2 : 2 + 2 * lead_lags].reshape(-1, 2)
    ]
    for f, w, d in x[2 + 2 * lead_lags :].reshape(-1, 3):
        out.append(f"{{kind: notch, frequency_hz: {f:.6g}, bandwidth_hz: {w:.6g}, depth: {d:.4g}}}")
    return out


def controller_sets(x: np.ndarray, rate: float, kp: float, kd: float, lead_lags: int) -> list[str]:
    """--set lines of the controller ``x`` = (kp scale, kd scale, lead-lag zeros and poles, notch parameters)."""
    return [f"controller.rate_hz={rate:g}", f"controller.proportional_gain={kp * x[0]:.8g}",
            f"controller.derivative_gain={kd * x[1]:.8g}",
            f"controller.filters=[{', '.join(filters_yaml(x, lead_lags))}]"]  # fmt: skip


def judge(sets: list[str], speeds, variants=VARIANTS, path=None) -> tuple[float, float]:
    """(largest spectral radius per sample, largest |S_jj| peak or inf when any loop is unstable) over speeds and
    variants of the rotor file ``path`` (default: the real rig) with ``sets``; the peak from a log grid plus the
    closed-loop poles' frequencies (within 1 % of the refined peak: tests/test_controller_2khz.py)."""
    radius, peak = 0.0, 0.0
    for variant in variants:
        cfg = load_config(path, [*sets, *variant])
        model, rate = build_structure(cfg), cfg.controller.rate_hz
        for rpm in speeds:
            resp = ModalResponse.of(sensitivity_state_space(*loop_state_spaces(model, cfg, rpm, "sampled")))
            radius = max(radius, float(np.abs(resp.poles).max()))
            if radius >= 1.0:
                continue
            w_poles = np.abs(np.angle(resp.poles)) * rate
            w = np.concatenate([2 * np.pi * np.geomspace(0.5, 0.499 * rate, GRID), w_poles[w_poles < np.pi * rate]])
            peak = max(peak, float(np.abs(np.einsum("kjj->kj", resp(w))).max()))
        if radius >= 1.0:  # the later variants cannot make it stable
            break
    return radius, (peak if radius < 1.0 else np.inf)


def score(sets: list[str], speeds, objective: str) -> float:
    """The search's objective: unstable on the nominal plant > unstable on a variant > stable (the radius or the
    peak |S|), each tier ordered by the radius or the peak."""
    try:
        radius, peak = judge(sets, speeds, VARIANTS[:1])
        if radius >= 1.0:
            return 2 * UNSTABLE + radius
        radius_v, peak_v = judge(sets, speeds, VARIANTS[1:])
    except AmbError:  # a filter the config refuses
        return 10 * UNSTABLE
    if radius_v >= 1.0:
        return UNSTABLE + radius_v
    return max(radius, radius_v) if objective == "radius" else max(peak, peak_v)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rate", type=float, default=2000.0, help="controller rate (Hz)")
    ap.add_argument("--lead-lags", type=int, default=2, help="lead-lag filters in series after the PD")
    ap.add_argument("--notches", type=int, default=1, help="notch filters after the lead-lags")
    ap.add_argument("--objective", choices=("radius", "sensitivity"), default="sensitivity")
    ap.add_argument("--speeds", type=float, nargs="+", default=[0.0, 3000.0], help="spin speeds of the objective")
    ap.add_argument("--maxiter", type=int, default=50)
    ap.add_argument("--popsize", type=int, default=10)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--delay-samples", type=int, default=0, help="computation delay of the loop (samples)")
    args = ap.parse_args()
    base = load_config(None)
    c, b = base.controller, base.bearings
    kp_min = abs(b.displacement_stiffness) / b.current_stiffness / c.proportional_gain  # ki kp = |ks|
    top = 0.98 * args.rate / 2
    bounds = [(1.3 * kp_min, 3.0), (0.05, 15.0)] + [(2.0, top)] * (2 * args.lead_lags)
    bounds += [(50.0, top), (5.0, 600.0), (0.0, 1.0)] * args.notches

    def sets_of(x):
        sets = controller_sets(x, args.rate, c.proportional_gain, c.derivative_gain, args.lead_lags)
        return [*sets, f"controller.delay_samples={args.delay_samples}"]

    best = [np.inf]

    def objective(x) -> float:
        value = score(sets_of(x), args.speeds, args.objective)
        if value < best[0]:
            best[0] = value
            filters = ", ".join(filters_yaml(x, args.lead_lags))
            print(f"  best so far {value:.6g}: kp x {x[0]:.3f}, kd x {x[1]:.3f}; {filters}", flush=True)
        return value

    res = differential_evolution(objective, bounds, maxiter=args.maxiter, popsize=args.popsize, seed=args.seed,
                                 tol=1e-12, polish=False)  # fmt: skip
    sets = sets_of(res.x)
    net = b.current_stiffness * c.proportional_gain * res.x[0] + b.displacement_stiffness
    print(f"{args.rate:g} Hz, PD + {args.lead_lags} lead-lag(s) + {args.notches} notch(es); objective {res.fun:.6g}; "
          f"bearing net stiffness ki kp + ks = {net:.4g} N/m")  # fmt: skip
    for variant in VARIANTS:
        row = [judge(sets, [rpm], [variant]) for rpm in np.arange(0.0, base.max_speed_rpm + 1.0, 500.0)]
        print(f"  {' '.join(variant) or 'nominal':34s} max|mu| <= {max(r for r, _ in row):.7f}, peak |S| <= "
              f"{max(p for _, p in row):.3g} (0..{base.max_speed_rpm:g} rpm, every 500)")  # fmt: skip
    cfg = load_config(None, sets)
    model = build_structure(cfg)
    for rpm in args.speeds:
        axes = model_sensitivity(model, cfg, rpm, "sampled", (0.5, 0.499 * args.rate), 2000)["axes"]
        print(
            f"  amb-dynamics sensitivity at {rpm:g} rpm: "
            + ", ".join(f"{k} {v['peak_abs']:.3g} at {v['peak_hz']:.3g} Hz ({v['zone']})" for k, v in axes.items())
        )
    print("controller:")
    print(f"  rate_hz: {args.rate:g}\n  delay_samples: {args.delay_samples}")
    print(f"  proportional_gain: {c.proportional_gain * res.x[0]:.8g}")
    print(f"  derivative_gain: {c.derivative_gain * res.x[1]:.8g}\n  filters:")
    for f in filters_yaml(res.x, args.lead_lags):
        print(f"    - {f}")


if __name__ == "__main__":
    main()
