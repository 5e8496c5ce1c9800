"""Search a digital PD with lead-lag filters for the real rig at a given rate: `.venv/bin/python
tools/controller_search.py --rate 1000 [--lead-lags 2] [--maxiter 60] [--seed 3]`.

The objective is the digital loop's spectral radius per sample with the base at rest (amb_dynamics.preflight, the
check amb-rig runs before it starts), the worst over the spin speeds ``--speeds`` (rpm), on the real-rig default
config (full FE model with its amplifier and sensor filter).  scipy's differential evolution varies kp and kd (as
multiples of the config's) and the zero and pole of each lead-lag (below 0.98 x Nyquist; a zero above the pole is
a lag).  kp stays above the bearing's negative stiffness (ki kp > |ks|).  Prints the best max|mu| per sample at
every 500 rpm from 0 to max_speed_rpm and the --set lines of that controller; docs/real-rig.md quotes it.
"""

from __future__ import annotations

import argparse
import os

from amb_dynamics.threads import single_thread_env

os.environ.update(single_thread_env())  # one BLAS thread, set before numpy loads (amb_dynamics/threads.py)
import numpy as np
from scipy.optimize import differential_evolution

from amb_dynamics.config import load_config
from amb_dynamics.errors import AmbError
from amb_dynamics.preflight import digital_at_rest
from amb_dynamics.structure import build_structure

UNUSABLE = 10.0  # objective of a controller the config refuses


def controller_sets(x: np.ndarray, rate: float, kp: float, kd: float) -> list[str]:
    """--set lines of the controller ``x`` = (kp scale, kd scale, zero_1, pole_1, zero_2, pole_2, ...)."""
    filters = ", ".join(f"{{kind: lead_lag, zero_hz: {z:.6g}, pole_hz: {p:.6g}}}" for z, p in x[2:].reshape(-1, 2))
    return [f"controller.rate_hz={rate:g}", f"controller.proportional_gain={kp * x[0]:.8g}",
            f"controller.derivative_gain={kd * x[1]:.8g}", f"controller.filters=[{filters}]"]  # fmt: skip


def worst_radius(sets: list[str], speeds) -> float:
    """max over ``speeds`` (rpm) of the spectral radius per sample of the digital loop at rest."""
    worst = 0.0
    try:
        for rpm in speeds:
            cfg = load_config(None, [*sets, f"spin_speed_rpm={rpm}"])
            worst = max(worst, digital_at_rest(build_structure(cfg), cfg)["spectral_radius_per_sample"])
    except AmbError:
        return UNUSABLE
    return worst


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rate", type=float, default=1000.0, help="controller rate (Hz)")
    ap.add_argument("--lead-lags", type=int, default=2, help="lead-lag filters in series after the PD")
    ap.add_argument("--speeds", type=float, nargs="+", default=[0.0, 3000.0], help="spin speeds of the objective")
    ap.add_argument("--maxiter", type=int, default=60)
    ap.add_argument("--seed", type=int, default=3)
    args = ap.parse_args()
    base = load_config(None)
    c, b = base.controller, base.bearings
    kp_min = abs(b.displacement_stiffness) / b.current_stiffness / c.proportional_gain  # ki kp = |ks|
    top = 0.98 * args.rate / 2
    bounds = [(1.01 * kp_min, 2.0), (0.02, 3.0)] + [(2.0, top), (2.0, top)] * args.lead_lags
    res = differential_evolution(
        lambda x: worst_radius(controller_sets(x, args.rate, c.proportional_gain, c.derivative_gain), args.speeds),
        bounds, maxiter=args.maxiter, popsize=12, seed=args.seed, tol=1e-9, polish=True,
    )  # fmt: skip
    sets = controller_sets(res.x, args.rate, c.proportional_gain, c.derivative_gain)
    check = np.arange(0.0, base.max_speed_rpm + 1.0, 500.0)
    print(f"{args.rate:g} Hz, PD + {args.lead_lags} lead-lag(s), kp x {res.x[0]:.3f} (bearing stiffness ki kp + ks "
          f"= {b.current_stiffness * c.proportional_gain * res.x[0] + b.displacement_stiffness:.4g} N/m)")  # fmt: skip
    print("max|mu| per sample at rest: " + ", ".join(f"{rpm:g} rpm {worst_radius(sets, [rpm]):.6f}" for rpm in check))
    print("controller: " + " ".join(f"--set '{s}'" for s in sets))


if __name__ == "__main__":
    main()
