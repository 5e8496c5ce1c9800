"""Up-front checks of ``amb-dynamics`` arguments: every bad value is refused with one line before any work.

The bounds are not physics limits but the range where the analyses mean something and finish in bounded
time and memory: a base-motion angle beyond pi rad, a spin beyond 1e6 rpm, a chart of more than
``MAX_CHART_POINTS`` points or a time response of more than ``MAX_SIMULATE_STEPS`` steps is refused with a line
that names the option.  Non-finite numbers never reach JSON output (:func:`finite_json`).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .errors import InputError

MAX_AMPLITUDE_RAD = math.pi  # a base tilt amplitude beyond half a turn has no meaning for the rig
MAX_FREQUENCY_RAD_S = 1e5  # base motion faster than this is far beyond any vehicle or floor (and any AMB loop)
MAX_SPEED_RPM = 1e6
MAX_CHART_POINTS = 1_000_000  # 100 x 100 takes ~2 s here: a million points is already minutes
MAX_SIMULATE_STEPS = 2_000_000
MAX_SAMPLED_STEPS = 60_000  # controller samples of one sampled-data analysis: ~3.5 ms each here, ~3.5 min
MAX_HORIZON_S = 1e4
IMAGE_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg")


def _finite(name: str, values, lo: float | None = None, hi: float | None = None, unit: str = "") -> None:
    arr = np.atleast_1d(np.asarray(values, dtype=float))
    for v in arr:
        if not np.isfinite(v):
            raise InputError(f"{name} must be finite (got {v})")
        if lo is not None and v < lo:
            raise InputError(f"{name} must be >= {lo:g}{unit} (got {v:g})")
        if hi is not None and v > hi:
            raise InputError(f"{name} must be <= {hi:g}{unit} (got {v:g})")


def check_output(option: str, path: Path | None, suffixes: tuple[str, ...] | None = IMAGE_SUFFIXES) -> None:
    """An output file option: not a folder, a known image type, a parent that is (or can be) a folder."""
    if path is None:
        return
    if path.is_dir():
        raise InputError(f"{option} {path} is a folder: give a file name, e.g. {path / 'out.png'}")
    if suffixes and path.suffix.lower() not in suffixes:
        raise InputError(f"{option} {path}: unsupported file type (use {', '.join(suffixes)})")
    for parent in path.parents:
        if parent.exists():
            if not parent.is_dir():
                raise InputError(f"{option} {path}: {parent} is not a folder")
            break


def check_args(args) -> None:
    """Refuse out-of-range or non-finite arguments of any ``amb-dynamics`` verb with one line."""
    verb = args.verb
    if verb == "modes":
        _finite("--speed-rpm", args.speed_rpm, -MAX_SPEED_RPM, MAX_SPEED_RPM, " rpm")
        if args.max_frequency is not None:
            _finite("--max-frequency", args.max_frequency, 0.0)
    if verb == "campbell":
        _finite("--speeds", args.speeds, -MAX_SPEED_RPM, MAX_SPEED_RPM, " rpm")
        if args.speeds.size > 10_000:
            raise InputError(f"--speeds has {args.speeds.size} speeds (at most 10000)")
        _finite("--max-frequency", args.max_frequency, 0.0)
        if not args.max_frequency > 0:
            raise InputError("--max-frequency must be > 0 rad/s")
        check_output("--out", args.out)
    if verb in ("floquet", "simulate"):
        _motion_args(args)
    if verb == "floquet":
        if args.top < 1:
            raise InputError(f"--top must be >= 1 (got {args.top})")
        _finite("--horizon", args.horizon, 0.0, MAX_HORIZON_S, " s")
        if not args.horizon > 0:
            raise InputError("--horizon must be > 0 s")
    if verb == "chart":
        _finite("--amplitude", args.amplitude, -MAX_AMPLITUDE_RAD, MAX_AMPLITUDE_RAD, " rad")
        _finite("--frequency", args.frequency, None, MAX_FREQUENCY_RAD_S, " rad/s")
        points = args.amplitude.size * args.frequency.size
        if points > MAX_CHART_POINTS:
            raise InputError(
                f"chart of {args.amplitude.size} x {args.frequency.size} = {points} points refused "
                f"(at most {MAX_CHART_POINTS}; 100 x 100 takes about 2 s)"
            )
        if args.workers is not None and not 1 <= args.workers <= 256:
            raise InputError(f"--workers must be in 1..256 (got {args.workers})")
        check_output("--out", args.out)
        check_output("--json-out", args.json_out, (".json",))
    if verb == "simulate":
        _finite("--duration", args.duration, 0.0, None, " s")
        if not args.duration > 0:
            raise InputError("--duration must be > 0 s")
        if not 1 <= args.steps_per_period <= 100_000:
            raise InputError(f"--steps-per-period must be in 1..100000 (got {args.steps_per_period})")
        check_output("--out", args.out)


def _motion_args(args) -> None:
    _finite("--amplitude", args.amplitude, -MAX_AMPLITUDE_RAD, MAX_AMPLITUDE_RAD, " rad")
    _finite("--frequency", args.frequency, None, MAX_FREQUENCY_RAD_S, " rad/s")
    for axis, amp, freq, phase in args.harmonic:
        _finite(f"--harmonic {axis} amplitude", amp, -MAX_AMPLITUDE_RAD, MAX_AMPLITUDE_RAD, " rad")
        _finite(f"--harmonic {axis} frequency", freq, None, MAX_FREQUENCY_RAD_S, " rad/s")
        _finite(f"--harmonic {axis} phase", phase)


def check_simulate_steps(steps: int) -> None:
    """Refuse a time response too long to hold in memory (``--duration`` over the step)."""
    if steps > MAX_SIMULATE_STEPS:
        raise InputError(
            f"--duration needs {steps} Newmark steps (at most {MAX_SIMULATE_STEPS}): "
            "shorten --duration or lower --steps-per-period"
        )


def check_sampled(period_s: float, sample_s: float, steps: int) -> None:
    """The sampled-data analysis needs a base period of at least two controller samples and bounded work.

    Parameters
    ----------
    period_s : float
        Base-motion period T (s).
    sample_s : float
        Controller sample time Ts (s).
    steps : int
        Controller samples the analysis would take (the hybrid period or the Lyapunov horizon).
    """
    if period_s < 2 * sample_s:
        raise InputError(
            f"base period {period_s:.3g} s is shorter than two controller samples ({2 * sample_s:.3g} s): "
            "the digital loop cannot see this motion (lower --frequency or raise controller.rate_hz)"
        )
    if steps > MAX_SAMPLED_STEPS:
        raise InputError(
            f"the sampled analysis would take {steps} controller samples (at most {MAX_SAMPLED_STEPS}): "
            "raise --frequency, use --snap, or use --controller continuous"
        )


def finite_json(obj):
    """``obj`` with every NaN/inf float replaced by None, and the dotted paths that were replaced.

    Returns
    -------
    tuple
        (clean object, list of paths such as ``"multipliers.0.1"``).
    """
    replaced: list[str] = []

    def walk(x, path: str):
        if isinstance(x, dict):
            return {k: walk(v, f"{path}.{k}" if path else str(k)) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [walk(v, f"{path}.{i}" if path else str(i)) for i, v in enumerate(x)]
        if isinstance(x, (float, np.floating)) and not math.isfinite(float(x)):
            replaced.append(path)
            return None
        return x

    return walk(obj, ""), replaced
