"""Lockstep over DDS equals the core's offline sampled-data simulation, and two runs are identical.

``amb-rig run`` starts base_motion, controller and plant as separate processes (localhost DDS).  An rclpy node in
this test process records every /amb/displacement and /amb_plant/state message; the plant waits for it
(min_subscribers = 2: controller and this recorder), so it sees the run from t = 0.  The offline reference is
``SampledLoop.simulate`` of the same case from the same initial state (the disk displaced 0.1 mm, so that the
pitch-modulated closed loop has something to do; base forcing is off in the seed config).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from amb_dynamics.config import load_config
from amb_dynamics.fe import dof_index
from amb_dynamics.motion import BaseMotion
from amb_dynamics.sampled import SampledLoop
from amb_dynamics.structure import build_structure
from helpers import TS_NS, DdsRecorder, run_rig, stamp

pytestmark = pytest.mark.ros

DURATION_S = 0.4  # 2000 steps at 5 kHz
DISK_V = 1e-4  # m


def lockstep_run(tmp_path, venv_bin, extra=()):
    from sensor_msgs.msg import JointState
    from trajectory_msgs.msg import JointTrajectory

    rec = DdsRecorder({"/amb/displacement": JointState, "/amb_plant/state": JointTrajectory})
    try:
        code, summary, text = run_rig(
            tmp_path,
            venv_bin,
            [
                "--duration",
                str(DURATION_S),
                "--initial-displacement",
                str(DISK_V),
                "--param",
                "plant:min_subscribers=2",
                *(extra if "--config" in extra else ["--config", PAPER, *extra]),
            ],
        )
    finally:
        rec.close()
    assert code == 0, (summary or {}).get("errors") or text[-2000:]
    disp = {stamp(m): np.array(m.position) for m in rec.messages["/amb/displacement"]}
    state = {}  # blocks of consecutive samples: point stamp = header stamp + time_from_start
    for m in rec.messages["/amb_plant/state"]:
        for p in m.points:
            state[stamp(m) + p.time_from_start.sec * 10**9 + p.time_from_start.nanosec] = np.concatenate(
                [p.positions, p.velocities]
            )
    return summary, disp, state


def rec_blocks(samples: int, block: int) -> list[int]:
    """Sizes of the state blocks of a run of ``samples`` samples."""
    return [min(block, samples - a) for a in range(0, samples, block)]


PAPER = str(Path(__file__).resolve().parents[1] / "config" / "seed_paper.yaml")  # the idealised loop


def offline(steps: int):
    cfg = load_config(PAPER)
    model = build_structure(cfg)
    q = np.zeros(model.fe.n)
    q[dof_index(cfg.disks[0].node, 0)] = DISK_V
    x0 = np.concatenate([model.from_fe(q), np.zeros(model.n)])
    loop = SampledLoop(model, cfg, Ts=TS_NS / 1e9)
    return loop.simulate(BaseMotion.from_config(cfg.base_motion), steps, x0), x0


def test_lockstep_equals_offline_and_two_runs_are_identical(tmp_path, venv_bin):
    s1, disp1, state1 = lockstep_run(tmp_path / "a", venv_bin)
    steps = round(DURATION_S * 1e9 / TS_NS)
    assert s1["ok"] and s1["steps"] == steps
    assert s1["nodes"]["plant"]["values"]["saturated steps"] == "0"  # the offline loop has no current limit
    # every sample arrived exactly once, on the grid t_k = k Ts
    assert sorted(disp1) == [k * TS_NS for k in range(steps + 1)]
    y_dds = np.array([disp1[k * TS_NS] for k in range(steps + 1)])
    ref, x0 = offline(steps)
    np.testing.assert_allclose(state1[0], x0, rtol=0, atol=1e-18)
    scale = np.abs(ref.y).max()
    assert scale > 1e-6  # a trajectory worth comparing (the disk starts 0.1 mm off centre)
    assert np.abs(y_dds - ref.y).max() <= 1e-9 * scale
    x_dds = np.array([state1[k * TS_NS] for k in range(steps + 1)])
    assert np.abs(x_dds - ref.x).max() <= 1e-9 * np.abs(ref.x).max()
    # the controller answered every sample, nothing was lost or rejected anywhere
    ctl = s1["nodes"]["controller"]["values"]
    assert ctl["samples answered"] == str(steps + 1) and ctl["samples lost"] == "0"
    assert all(n["values"]["rejected total"] == "0" for n in s1["nodes"].values())
    # /clock every clock_every = 5 steps and at the last one; base_motion kept ahead of it all the same
    plant = s1["nodes"]["plant"]["values"]
    assert int(plant["published /clock"]) == len([k for k in range(steps + 1) if k % 5 == 0 or k == steps])
    assert int(s1["nodes"]["base_motion"]["values"]["received /clock"]) == int(plant["published /clock"])
    # base_motion: every sample in /base/rates blocks of rates_block = 25 (the plant's input; the offline equality
    # above shows each step got its own), /base/imu and /base/angular_acceleration every imu_every = 5 samples
    base = s1["nodes"]["base_motion"]["values"]
    n_base = int(base["samples published"])
    assert n_base > steps  # ahead of the plant (lead_samples)
    assert int(base["published /base/rates"]) == -(-n_base // 25)
    assert int(base["published /base/imu"]) == int(base["published /base/angular_acceleration"]) == -(-n_base // 5)
    # the state in blocks of state_block = 25 samples (the last one shorter), every sample exactly once
    assert sorted(state1) == [k * TS_NS for k in range(steps + 1)]
    assert int(plant["published /amb_plant/state"]) == len(rec_blocks(steps + 1, 25))

    # the second run under SCHED_FIFO (the speed option; where refused, the nodes say so and run normally):
    # scheduling changes the timing only, never the numbers
    s2, disp2, _ = lockstep_run(tmp_path / "b", venv_bin, ["--no-monitor", "--rt-priority", "20"])
    assert s2["steps"] == steps
    assert "SCHED_FIFO 20" in s2["nodes"]["plant"]["values"]["scheduling"]
    assert "monitor" not in s2["nodes"]
    y2 = np.array([disp2[k * TS_NS] for k in range(steps + 1)])
    assert np.array_equal(y_dds, y2)  # bit for bit
