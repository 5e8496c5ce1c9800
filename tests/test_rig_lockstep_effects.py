"""Lockstep over DDS with every real-rig effect equals the core's offline rig loop (one stepping code).

The real-rig default (config/seed_rotor.yaml: full FE model, amplifier current loop and slew limit, sensor
filter, noise and runout, shaft damping, unbalance, gravity with bias offsets, force noise, nonlinear bearing law,
touchdown bearings) with a spin ramp and a controller failure at FAIL_S (the rotor drops onto its backup
bearings), base at rest.  The offline reference is ``rig_loop.simulate_rig`` of the same case; the plant node
steps with the same ``RigPlant``, so the measured displacement and the state agree to rounding (1e-9).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from amb_dynamics.config import load_config
from amb_dynamics.motion import BaseMotion
from amb_dynamics.rig_loop import simulate_rig
from amb_dynamics.structure import build_structure
from helpers import TS_NS, DdsRecorder, run_rig, stamp

pytestmark = pytest.mark.ros

DURATION_S = 0.1
FAIL_S = 0.04
RAMP = ["spin.profile=ramp", "spin.start_rpm=1000", "spin.end_rpm=1100", "spin.rate_rpm_s=1000"]


def test_lockstep_with_every_effect_equals_offline_rig(tmp_path, venv_bin):
    from sensor_msgs.msg import JointState
    from std_msgs.msg import String
    from trajectory_msgs.msg import JointTrajectory

    topics = {
        "/amb/displacement": JointState,
        "/amb_plant/state": JointTrajectory,
        "/amb/spin_speed": JointState,
        "/amb_plant/touchdown": String,
    }
    rec = DdsRecorder(topics)
    sets = [a for kv in RAMP for a in ("--set", kv)]
    try:
        code, summary, text = run_rig(
            tmp_path,
            venv_bin,
            ["--duration", str(DURATION_S), "--motion", "none", "--no-monitor", *sets,
             "--param", "plant:min_subscribers=2", "--param", f"controller:fail_at_s={FAIL_S}"],
        )  # fmt: skip
    finally:
        rec.close()
    assert code == 0, (summary or {}).get("errors") or text[-2000:]
    steps = round(DURATION_S * 1e9 / TS_NS)
    cfg = load_config(None, RAMP)
    model = build_structure(cfg)
    ref = simulate_rig(model, cfg, BaseMotion(), steps, fail_at_s=FAIL_S)
    assert ref.contacts, "the dropped rotor must reach its backup bearings in the reference run"
    disp = {stamp(m): np.array(m.position) for m in rec.messages["/amb/displacement"]}
    y = np.array([disp[k * TS_NS] for k in range(steps + 1)])
    assert np.abs(y - ref.y).max() <= 1e-9 * np.abs(ref.y).max()
    state = {}
    for m in rec.messages["/amb_plant/state"]:
        for p in m.points:
            state[stamp(m) + p.time_from_start.sec * 10**9 + p.time_from_start.nanosec] = np.concatenate(
                [p.positions, p.velocities]
            )
    n2 = 2 * model.n
    x = np.array([state[k * TS_NS] for k in range(steps + 1)])
    assert np.abs(x - ref.x[:, :n2]).max() <= 1e-9 * np.abs(ref.x[:, :n2]).max()
    # tachometer: the ramp's speed at its stamps
    for m in rec.messages["/amb/spin_speed"]:
        k = stamp(m) // TS_NS
        assert m.velocity[0] == pytest.approx(ref.spin[k], rel=1e-12)
    # touchdown events on the topic and in the summary, as in the offline run
    events = [json.loads(m.data) for m in rec.messages["/amb_plant/touchdown"]]
    assert [(e["node"], round(e["t_s"] / 2e-4 * 1e3)) for e in events][:1] == [
        (ref.contacts[0][1], round(ref.contacts[0][0] / 2e-4 * 1e3))
    ]
    plant = summary["nodes"]["plant"]["values"]
    assert int(plant["touchdown contacts"]) == len(ref.contacts)
    assert summary["ok"] and summary["steps"] == steps
