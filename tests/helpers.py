"""Helpers shared by several test files (import them from here, not from another test file).

* DDS: :class:`DdsRecorder` records topics in the test process; :func:`run_rig` runs ``amb-rig run --json`` and
  :func:`rig_json` reads its summary.
* Monitor: :func:`model_rho`, the sampled-data model's max|mu| of a pitch run of the seed rotor.
* Estimator: :func:`synthetic` builds period-stacked snapshots with known multipliers ``MU``; :func:`matched`
  measures how far identified multipliers are from expected ones.

The physics tests have their own module, tests/physics_helpers.py.
"""

from __future__ import annotations

import json
import threading

import numpy as np

from amb_dynamics import BaseMotion, SampledLoop, build_structure, load_config, sampled_floquet
from amb_dynamics.estimator.mapfit import forcing_regressors
from procs import spawn


# ---- DDS and amb-rig (moved from test_rig_lockstep.py) ---------------------------------------------------------
class DdsRecorder:
    """Records raw messages of some topics in this process (own rclpy context, spun in a thread)."""

    def __init__(self, topics: dict, qos=None):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        from amb_ros.qos import diagnostics_qos, lockstep_qos

        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx)
        self.node = rclpy.create_node("test_recorder", context=self.ctx)
        self.messages: dict[str, list] = {t: [] for t in topics}
        qos = qos if qos is not None else lockstep_qos(100000)
        for topic, msg_type in topics.items():
            q = diagnostics_qos() if topic == "/diagnostics" else qos
            self.node.create_subscription(msg_type, topic, self.messages[topic].append, q)
        self.executor = SingleThreadedExecutor(context=self.ctx)
        self.executor.add_node(self.node)
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self):
        while not self._stop.is_set():
            self.executor.spin_once(timeout_sec=0.05)

    def close(self):
        self._stop.set()
        self.thread.join(5)
        self.node.destroy_node()
        self.ctx.try_shutdown()


def rig_json(text: str) -> dict:
    return json.loads(text[text.index("{") : text.rindex("}") + 1])


def run_rig(tmp_path, venv_bin, args, timeout=180.0):
    """amb-rig run --json with ``args``; returns (exit code, summary dict, log text)."""
    tmp_path.mkdir(parents=True, exist_ok=True)
    log = tmp_path / "rig.log"
    cmd = [str(venv_bin / "amb-rig"), "run", "--json", "--log-dir", str(tmp_path / "logs"), *args]
    with spawn(cmd, log) as proc:
        code = proc.wait(timeout)
        text = proc.text()
    return code, rig_json(text), text


# ---- the monitor's truth: the sampled-data model --------------------------------------------------------------
def model_rho(amplitude: float, T: float) -> float:
    """max|mu| of the sampled-data model of a pitch run of the seed rotor without current limit.

    The digital loop's monodromy over T = N Ts (``sampled_floquet``), the truth the monitor's estimate must meet.
    """
    cfg = load_config(None, ["controller.current_limit=1e9"])
    motion = BaseMotion.single("pitch", amplitude, np.pi / T)
    return sampled_floquet(SampledLoop(build_structure(cfg), cfg, forcing=False), motion, T).max_abs


# ---- the estimator on synthetic data (moved from test_estimate_core.py) ----------------------------------------
MU = np.array([1.03 * np.exp(0.7j), 1.03 * np.exp(-0.7j), 0.9 * np.exp(2.1j), 0.9 * np.exp(-2.1j), 0.5, -0.3])


def synthetic(mu, cols, m=60, forcing="alternating", seed=0, noise=0.0):
    """Columns z_0..z_{cols-1} of z_{j+1} = A z_j + d_j observed through a random (m x len(mu)) map."""
    rng = np.random.default_rng(seed)
    n = len(mu)
    V = rng.standard_normal((n, n)) + 0j
    # complex-conjugate pairs get conjugate eigenvectors so that A is real
    k = 0
    while k < n:
        if abs(mu[k].imag) > 0:
            v = rng.standard_normal(n) + 1j * rng.standard_normal(n)
            V[:, k], V[:, k + 1] = v, v.conj()
            k += 2
        else:
            k += 1
    A = np.real(V @ np.diag(mu) @ np.linalg.inv(V))
    O = rng.standard_normal((m, n))
    E = forcing_regressors(forcing, cols)
    D = rng.standard_normal((n, E.shape[0]))
    x = rng.standard_normal(n)
    Z = np.empty((m, cols))
    for j in range(cols):
        Z[:, j] = O @ x
        x = A @ x + D @ E[:, j]
    return Z + noise * rng.standard_normal(Z.shape)


def matched(got, expected):
    return max(np.min(np.abs(got - z)) for z in expected)
