"""Config sections of the controller beyond the PID: notch and lead-lag filters, a user state-space controller.

``controller.filters`` are applied in series after the PID, per AMB axis; ``controller.state_space`` replaces the
PID with the user's own linear controller.  Both are analysed and run exactly as the PID is
(:mod:`amb_dynamics.control_law`).  A config without these keys keeps the plain PID, bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .config_fields import spec as _f
from .errors import ConfigError

NOTCH_KEYS = ("frequency_hz", "bandwidth_hz", "depth")
LEAD_LAG_KEYS = ("zero_hz", "pole_hz")


@dataclass(frozen=True)
class FilterConfig:
    """One filter in series after the PID: a notch or a lead-lag, on all axes or the listed ones."""

    kind: str = _f(choices=("notch", "lead_lag"))
    frequency_hz: float | None = _f("Hz", 0.0, open_lo=True, default=None, doc="notch: centre frequency")
    bandwidth_hz: float | None = _f("Hz", 0.0, open_lo=True, default=None, doc="notch: -3 dB width (depth 0)")
    depth: float = _f("", 0.0, 1.0, default=0.0, doc="notch: gain at the centre (0 = full notch, 1 = no notch)")
    zero_hz: float | None = _f("Hz", 0.0, open_lo=True, default=None, doc="lead-lag: zero (s/wz + 1)")
    pole_hz: float | None = _f("Hz", 0.0, open_lo=True, default=None, doc="lead-lag: pole 1/(s/wp + 1)")
    axes: tuple[int, ...] = _f("", 0, 3, default=(), doc="AMB axis indices 0..3 (channel order); empty = all")


@dataclass(frozen=True)
class StateSpaceConfig:
    """The user's controller, u = C x + D y_m, x' = A x + B y_m (or x_k+1 = A x_k + B y_k): y_m in m, u in A.

    The feedback sign is in the matrices (a PD is D = -kp).  per_axis: one SISO controller applied to each axis
    (B n x 1, C 1 x n, D 1 x 1); mimo: 4 inputs and 4 outputs in channel order.
    """

    A: tuple[tuple[float, ...], ...] = _f(doc="n x n")
    B: tuple[tuple[float, ...], ...] = _f(doc="n x inputs")
    C: tuple[tuple[float, ...], ...] = _f(doc="outputs x n")
    D: tuple[tuple[float, ...], ...] = _f(doc="outputs x inputs")
    sample_time: float | None = _f(
        "s", 0.0, open_lo=True, default=None, doc="null: continuous (Tustin at rate_hz); else must be 1/rate_hz"
    )
    structure: str = _f(choices=("per_axis", "mimo"), default="per_axis")

    def matrices(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        n = len(self.A)
        A = np.array(self.A, dtype=float).reshape(n, n)
        B = np.array(self.B, dtype=float).reshape(n, -1) if n else np.zeros((0, len(self.D[0])))
        C = np.array(self.C, dtype=float).reshape(len(self.C), n)
        return A, B, C, np.array(self.D, dtype=float)


def check_control(cfg: Any, source: str) -> None:
    """Cross-field checks of controller.filters and controller.state_space; one line naming the key."""
    c = cfg.controller
    nyquist = c.rate_hz / 2.0
    for i, f in enumerate(c.filters):
        key = f"controller.filters[{i}]"
        own, other = (NOTCH_KEYS, LEAD_LAG_KEYS) if f.kind == "notch" else (LEAD_LAG_KEYS, NOTCH_KEYS)
        given = [k for k in other if getattr(f, k) not in (None, 0.0)]
        if given:
            raise ConfigError(f"{source}: '{key}.{given[0]}' does not apply to a {f.kind} filter")
        missing = [k for k in own if k != "depth" and getattr(f, k) is None]
        if missing:
            raise ConfigError(f"{source}: '{key}' ({f.kind}) needs '{missing[0]}'")
        for k in own:
            v = getattr(f, k)
            if k.endswith("_hz") and v >= nyquist:
                raise ConfigError(
                    f"{source}: '{key}.{k}' = {v:g} Hz must be below the Nyquist frequency {nyquist:g} Hz "
                    "(controller.rate_hz / 2)"
                )
        if len(set(f.axes)) != len(f.axes):
            raise ConfigError(f"{source}: '{key}.axes' must be distinct")
    if c.state_space is not None:
        _check_state_space(c.state_space, c.rate_hz, c.filters, source)


def _check_state_space(ss: StateSpaceConfig, rate_hz: float, filters, source: str) -> None:
    key = "controller.state_space"
    if filters:
        raise ConfigError(f"{source}: '{key}' replaces the PID; put its filters into the state space")
    n = len(ss.A)
    if n == 0:
        raise ConfigError(f"{source}: '{key}.A' must have at least one state")
    io = 1 if ss.structure == "per_axis" else 4
    shapes = {"A": (n, n), "B": (n, io), "C": (io, n), "D": (io, io)}
    for name, (rows, cols) in shapes.items():
        m = getattr(ss, name)
        if len(m) != rows or any(len(r) != cols for r in m):
            got = f"{len(m)} x {'/'.join(sorted({str(len(r)) for r in m})) or 0}"
            raise ConfigError(f"{source}: '{key}.{name}' must be {rows} x {cols} for {ss.structure} (got {got})")
    if ss.sample_time is not None and not math.isclose(ss.sample_time * rate_hz, 1.0, rel_tol=1e-9):
        raise ConfigError(
            f"{source}: '{key}.sample_time' = {ss.sample_time:g} s must equal 1/controller.rate_hz = "
            f"{1.0 / rate_hz:g} s (or be null for a continuous controller)"
        )
