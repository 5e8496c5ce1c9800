"""A recorded base trajectory: Euler angles read from CSV, smoothed, differentiated (docs/physics.md#base-motion).

The file has a header line and columns ``t`` (s, strictly increasing) and any of ``roll``, ``pitch``, ``yaw``
(rad; a missing axis is zero), e.g. from a rig's IMU log.  Each angle is fitted with a cubic smoothing spline
(``scipy.interpolate.make_smoothing_spline``; ``smoothing`` is its lambda, None = chosen by generalized
cross-validation), whose first and second derivatives give beta_dot and beta_ddot, and the same kinematics as
the periodic profiles give Omega, dOmega and the attitude.  Time is shifted so that the first row is t = 0.
After the last row the base holds its final attitude at rest (documented; the node warns).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.interpolate import make_smoothing_spline

from .errors import InputError
from .motion import AXES, BaseMotion
from .yamlread import read_text_bounded

MIN_ROWS = 5


@dataclass(frozen=True)
class RecordedMotion(BaseMotion):
    """BaseMotion whose angles come from splines over [0, duration] instead of harmonics."""

    splines: tuple = ()  # per axis (roll, pitch, yaw): (beta, beta_dot, beta_ddot) callables, or None
    duration: float = 0.0  # s

    @property
    def is_static(self) -> bool:
        return False

    def fundamental_period(self) -> float | None:
        return None

    def _angles(self, t: np.ndarray):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        inside = t <= self.duration
        tc = np.clip(t, 0.0, self.duration)
        b, bd, bdd = (np.zeros((3, t.size)) for _ in range(3))
        for i, fns in enumerate(self.splines):
            if fns is None:
                continue
            b[i] = fns[0](tc)
            bd[i] = np.where(inside, fns[1](tc), 0.0)  # at rest after the recording ends
            bdd[i] = np.where(inside, fns[2](tc), 0.0)
        return b, bd, bdd


MAX_TRAJECTORY_BYTES = 64 << 20  # 1 h at 1 kHz of t, roll, pitch, yaw is ~150 MB of CSV: decimate before


def _rows(path: Path, lines: list[str], columns: int) -> np.ndarray:
    """The numeric rows; an error names the file and line number, never the line's content."""
    out = np.empty((len(lines), columns))
    n = 0
    for i, line in enumerate(lines, start=2):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        parts = line.split(",")
        if len(parts) != columns:
            raise InputError(f"{path}: line {i} has {len(parts)} values for {columns} header columns")
        try:
            out[n] = [float(v) for v in parts]
        except ValueError:
            raise InputError(f"{path}: line {i} is not a row of numbers") from None
        n += 1
    return out[:n]


def load_recorded(path: str | Path, smoothing: float | None = None) -> RecordedMotion:
    """Read a CSV trajectory; raises InputError with one line for a bad file."""
    path = Path(path)
    # regular files only, size checked before reading (a /dev/zero would otherwise be read without end)
    text = read_text_bounded(path, MAX_TRAJECTORY_BYTES, "recorded trajectory", InputError)
    lines = text.splitlines()
    header = [h.strip().lower() for h in lines[0].split(",")] if lines else []
    rows = _rows(path, lines[1:], len(header))
    if "t" not in header:
        raise InputError(f"{path}: line 1 (header) must name a 't' column and any of roll, pitch, yaw")
    unknown = [h for h in header if h not in ("t", *AXES)]
    if unknown:
        raise InputError(f"{path}: line 1 (header) has a column other than t, roll, pitch, yaw")
    if rows.shape[1] != len(header):
        raise InputError(f"{path}: {rows.shape[1]} values per row for {len(header)} header columns")
    if rows.shape[0] < MIN_ROWS:
        raise InputError(f"{path}: a recorded trajectory needs at least {MIN_ROWS} rows (got {rows.shape[0]})")
    if not np.isfinite(rows).all():
        raise InputError(f"{path}: non-finite value in the trajectory")
    t = rows[:, header.index("t")]
    if np.any(np.diff(t) <= 0):
        raise InputError(f"{path}: column t must be strictly increasing")
    t = t - t[0]
    splines = []
    for axis in AXES:
        if axis not in header:
            splines.append(None)
            continue
        spl = make_smoothing_spline(t, rows[:, header.index(axis)], lam=smoothing)
        splines.append((spl, spl.derivative(1), spl.derivative(2)))
    return RecordedMotion((), "recorded", tuple(splines), float(t[-1]))
