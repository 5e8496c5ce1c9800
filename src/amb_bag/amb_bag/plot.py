"""``amb-bag plot``: one PNG of a run from its bag.

Panels (each only if its topic is in the bag): AMB displacements from /amb/displacement as a fraction of the
air gap (``--config`` rotor file, default the run's own config recorded on /amb_plant/config, else the default
config), control currents from /amb/current
(effort, A), base attitude from /base/imu (roll about X, pitch about Z, yaw about Y, of the base->inertial
quaternion, rad, as docs/physics.md#base-motion), and the
spectral radius rho = max|mu| from /stability/multipliers (layout [k, 2] = re, im) against the stability
limit 1.  Times are the messages' header stamps (simulated time in lockstep); /stability/multipliers has no
stamp, so its log time is mapped to simulated time through the recorded /clock (log time from the start if
there is no /clock).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from . import msgdefs
from .errors import BagError
from .reader import Bag

TOPICS = ("/amb/displacement", "/amb/current", "/base/imu", "/stability/multipliers", "/clock")


def _stamp_s(msg) -> float:
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


def euler_from_quaternion(x: float, y: float, z: float, w: float) -> tuple[float, float, float]:
    """Roll, pitch, yaw (rad) of a unit base->inertial quaternion (x, y, z, w), in this project's convention.

    docs/physics.md#base-motion: roll about X (the rotor axis), yaw about Y, pitch about Z, and the attitude of a
    combined motion is R = Ry(yaw) Rz(pitch) Rx(roll).  With that product, R[1,0] = sin(pitch),
    (R[0,0], R[2,0]) = cos(pitch) (cos yaw, -sin yaw) and (R[1,1], R[1,2]) = cos(pitch) (cos roll, -sin roll).
    """
    r00, r10, r20 = 1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)
    r11, r12 = 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
    pitch = math.asin(max(-1.0, min(1.0, r10)))
    return math.atan2(-r12, r11), pitch, math.atan2(-r20, r00)


def read_series(bag: Bag) -> dict:
    """Time series of the plotted topics: name -> (t (k,), values (k, m), labels)."""
    from rclpy.serialization import deserialize_message

    present = [t for t in TOPICS if t in bag.topics]
    rows: dict[str, list] = {t: [] for t in present}
    names: dict[str, list[str]] = {}
    for topic, type_name, log_ns, _pub, data in bag.messages(present):
        try:
            msg = deserialize_message(data, msgdefs.message_class(type_name))
        except Exception as exc:  # rclpy raises plain exceptions for undecodable CDR
            raise BagError(f"{bag.dir}: a {topic} message at {log_ns} ns cannot be decoded as {type_name} "
                           f"({type(exc).__name__})") from None  # fmt: skip
        if topic == "/clock":
            rows[topic].append((log_ns, msg.clock.sec + 1e-9 * msg.clock.nanosec))
        elif topic == "/amb/displacement":
            names[topic] = list(msg.name)
            rows[topic].append((_stamp_s(msg), *msg.position))
        elif topic == "/amb/current":
            names[topic] = list(msg.name)
            rows[topic].append((_stamp_s(msg), *msg.effort))
        elif topic == "/base/imu":
            q = msg.orientation
            rows[topic].append((_stamp_s(msg), *euler_from_quaternion(q.x, q.y, q.z, q.w)))
        elif topic == "/stability/multipliers":
            mu = np.asarray(msg.data, dtype=float).reshape(-1, 2)
            rows[topic].append((log_ns, float(np.max(np.hypot(mu[:, 0], mu[:, 1]))) if len(mu) else np.nan))
    series = {}
    for topic, r in rows.items():
        if not r or len({len(x) for x in r}) != 1:
            continue  # nothing, or the channel count changed mid-run: not plottable as one array
        arr = np.asarray(r, dtype=float)
        series[topic] = (arr[:, 0], arr[:, 1:], names.get(topic))
    if "/stability/multipliers" in series:
        log_t, rho, _ = series["/stability/multipliers"]
        if "/clock" in series:
            clock_log, clock_t, _ = series["/clock"]
            t = np.interp(log_t, clock_log, clock_t[:, 0])
        else:
            t = (log_t - bag.start_ns) * 1e-9
        series["/stability/multipliers"] = (t, rho, ["rho"])
    return series


def plot_bag(path, out, config=None) -> Path:
    """Write the run plot of the bag at ``path`` to ``out`` (PNG); returns its path."""
    from amb_dynamics.config import load_config

    from .runconfig import recorded_config

    bag = Bag(path)
    cfg = load_config(config) if config else (recorded_config(bag) or load_config(None))
    air_gap = cfg.bearings.air_gap
    series = read_series(bag)
    panels = [t for t in ("/amb/displacement", "/amb/current", "/base/imu", "/stability/multipliers") if t in series]
    if not panels:
        raise BagError(f"{path} has none of /amb/displacement, /amb/current, /base/imu, /stability/multipliers")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(panels), 1, figsize=(9, 2.6 * len(panels)), sharex=True, squeeze=False)
    for ax, topic in zip(axes[:, 0], panels, strict=True):
        t, values, labels = series[topic]
        if topic == "/amb/displacement":
            for j in range(values.shape[1]):
                ax.plot(t, values[:, j] / air_gap, lw=0.8, label=labels[j] if labels else f"ch{j}")
            ax.axhline(1.0, color="k", ls=":", lw=0.8)
            ax.axhline(-1.0, color="k", ls=":", lw=0.8)
            ax.set_ylabel(f"displacement / air gap\n(gap {air_gap * 1e3:g} mm)")
        elif topic == "/amb/current":
            for j in range(values.shape[1]):
                ax.plot(t, values[:, j], lw=0.8, label=labels[j] if labels else f"ch{j}")
            ax.set_ylabel("control current (A)")
        elif topic == "/base/imu":
            for j, name in enumerate(("roll", "pitch", "yaw")):
                ax.plot(t, values[:, j], lw=0.8, label=name)
            ax.set_ylabel("base attitude (rad)")
        else:
            ax.plot(t, values[:, 0], lw=1.0, label="rho = max|mu|")
            ax.axhline(1.0, color="r", ls="--", lw=0.8, label="stability limit")
            ax.set_ylabel("rho")
        ax.legend(loc="upper right", fontsize=7, ncol=4)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle(f"amb-rig run: {Path(path).name}")
    fig.tight_layout()
    out = Path(out)
    try:
        fig.savefig(out, dpi=110)
    except OSError as exc:
        raise BagError(f"cannot write {out}: {exc.strerror}") from None
    finally:
        plt.close(fig)
    return out
