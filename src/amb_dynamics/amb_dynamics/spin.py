"""Spin profile (config ``spin``): the spin angle, rate and acceleration relative to the base at time t.

``constant``: phi' = spin_speed_rpm.  ``ramp``: the speed goes linearly from start_rpm to end_rpm at rate_rpm_s
(run-up or coast-down), then holds end_rpm; phi is its exact integral (phi(0) = 0).
"""

from __future__ import annotations

import numpy as np

RPM = np.pi / 30.0  # rad/s per rpm


def spin_state(cfg, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(phi rad, phi' rad/s, phi'' rad/s^2) at times t (s), arrays of the shape of t."""
    t = np.asarray(t, dtype=float)
    sp = cfg.spin
    if sp.profile == "constant":
        w = cfg.spin_speed_rpm * RPM
        return w * t, np.full_like(t, w), np.zeros_like(t)
    w0, w1 = sp.start_rpm * RPM, sp.end_rpm * RPM
    a = np.sign(w1 - w0) * sp.rate_rpm_s * RPM
    t_end = (w1 - w0) / a
    tr = np.clip(t, 0.0, t_end)
    phi = w0 * tr + 0.5 * a * tr**2 + w1 * np.maximum(t - t_end, 0.0)
    rate = w0 + a * tr
    acc = np.where((t >= 0.0) & (t < t_end), a, 0.0)
    return phi, rate, acc
