"""The controller node runs filters and a user state space exactly as the core's offline rig loop does.

Lockstep over DDS on the real-rig default (gravity, bias offsets, amplifier, sensor filter, noise, unbalance):
a notch and a lead-lag after the PID, and a user discrete state space equal to the PID.  The reference is
``rig_loop.simulate_rig`` of the same config (for the user's PID: of the plain PID), to rounding.
"""

from __future__ import annotations

import numpy as np
import pytest

from amb_dynamics.config import load_config
from amb_dynamics.motion import BaseMotion
from amb_dynamics.rig_loop import simulate_rig
from amb_dynamics.structure import build_structure
from helpers import TS_NS, DdsRecorder, run_rig, stamp, user_pid_setting

pytestmark = pytest.mark.ros

DURATION_S = 0.06
FILTERS = "controller.filters=[{kind: notch, frequency_hz: 1500, bandwidth_hz: 100, depth: 0.5}, " \
          "{kind: lead_lag, zero_hz: 600, pole_hz: 400, axes: [1, 3]}]"  # fmt: skip


def _lockstep(tmp_path, venv_bin, item: str):
    from sensor_msgs.msg import JointState

    rec = DdsRecorder({"/amb/displacement": JointState, "/amb/current": JointState})
    try:
        code, summary, text = run_rig(
            tmp_path,
            venv_bin,
            ["--duration", str(DURATION_S), "--motion", "none", "--no-monitor", "--set", item,
             "--param", "plant:min_subscribers=2", "--param", "controller:min_subscribers=2"],
        )  # fmt: skip
    finally:
        rec.close()
    assert code == 0, (summary or {}).get("errors") or text[-2000:]
    steps = round(DURATION_S * 1e9 / TS_NS)
    y = {stamp(m): np.array(m.position) for m in rec.messages["/amb/displacement"]}
    i = {stamp(m): np.array(m.effort) for m in rec.messages["/amb/current"]}
    return steps, np.array([y[k * TS_NS] for k in range(steps)]), np.array([i[k * TS_NS] for k in range(steps)])


@pytest.mark.parametrize("case", ["filters", "user_pid"])
def test_node_runs_the_configured_controller_as_the_core(tmp_path, venv_bin, case):
    model = build_structure(load_config(None))
    item = FILTERS if case == "filters" else user_pid_setting(model.gains, continuous=False)
    steps, y, i = _lockstep(tmp_path, venv_bin, item)
    ref_cfg = load_config(None, [FILTERS] if case == "filters" else [])
    ref = simulate_rig(model, ref_cfg, BaseMotion(), steps)
    assert np.abs(y - ref.y[:steps]).max() <= 1e-9 * np.abs(ref.y).max()
    assert np.abs(i - ref.i).max() <= 1e-9 * np.abs(ref.i).max()
    if case == "filters":  # and the filters matter: the plain PID's currents differ
        plain = simulate_rig(model, load_config(None), BaseMotion(), steps)
        assert np.abs(plain.i - ref.i).max() > 1e-4 * np.abs(ref.i).max()
