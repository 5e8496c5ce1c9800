"""The stability monitor on the real-rig default config: no hand-set kick, the rig's own disturbances (issue 16).

`amb-rig run --duration 6 --motion pitch --amplitude 0.6 --frequency 21.8 --json`, nothing else: the default
config (config/seed_rotor.yaml: G2.5 unbalance at 1000 rpm, sensor runout and noise, force noise, gravity turning
with the base, actuator and sensor dynamics, the nonlinear bearing law, touchdown bearings at 1.0 mm).  The
point is inside an instability tongue of that config: its digital loop, linearised at the levitated operating
point (gravity and the bias offsets load the nonlinear law: 22 % more negative stiffness at AMB5), has max|mu|
per period T = pi/omega 1.0560 (1.0606 about the centred law; interpolated in T/Ts between exact products at
T/Ts = 720, 721, 722), which the test computes itself.
The monitor (full state, synchronous model from the tachometer, forcing `two_periods` for gravity) must raise
the flag within 16 base-motion periods (2 pi / omega each); the recorded bag replayed into `amb-monitor analyze`
must give the live estimate, the model value, and with the four AMB displacements only (sensor-only) a flag
within 16 base periods as well.  At the default stable point (0.3, 24.5) the same 6 s run must raise no flag,
the monitor's model value must be the config's, and its estimate must agree with it (no mismatch).
"""

from __future__ import annotations

import json
import math
import subprocess

import numpy as np
import pytest

from amb_dynamics.config import load_config
from amb_dynamics.digital_floquet import estimate_point
from amb_dynamics.motion import BaseMotion
from stability_monitor.model_check import model_loop

pytestmark = pytest.mark.ros

A, W = 0.6, 21.8


def test_real_rig_tongue_point_raises_the_flag(venv_bin, tmp_path):
    cfg = load_config(None)
    loop = model_loop(cfg)
    model = estimate_point(loop, BaseMotion.single("pitch", A, W), math.pi / W)
    assert model["max_abs_multiplier"] - model["error_bound"] > 1.05  # well inside the tongue
    bag = tmp_path / "bag"
    cmd = [str(venv_bin / "amb-rig"), "run", "--duration", "6", "--motion", "pitch", "--amplitude", str(A),
           "--frequency", str(W), "--json", "--log-dir", str(tmp_path / "logs"), "--bag", str(bag)]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    s = json.loads(proc.stdout)
    st = s["stability"]
    mon = s["nodes"]["monitor"]["values"]
    assert mon["synchronous harmonics"] == "1" and mon["forcing"] == "2", mon  # unbalance/runout, gravity
    assert st["unstable"] is True, st
    base_period = 2 * math.pi / W
    assert st["flag_raised_at_s"] <= 16 * base_period, st
    assert st["rho"] > 1.02, st  # the last estimate; its windows may hold touchdown contacts (see below)

    # ISO 14839-2 grade of the run's last second: a rotor that reached its backup bearings (C_min) is in zone D
    zones = {a: v["zone"] for a, v in s["vibration"]["axes"].items()}
    assert set(zones) == {"amb1_y", "amb1_z", "amb5_y", "amb5_z"}
    if int(s["nodes"]["plant"]["values"]["touchdown contacts"]):
        assert "D" in zones.values(), zones
    # `amb-bag info` reads the same grade back from the plant's final report in the bag
    info = subprocess.run([str(venv_bin / "amb-bag"), "info", str(bag), "--json"], capture_output=True, text=True,
                          timeout=120)  # fmt: skip
    assert info.returncode == 0, info.stderr
    recorded = json.loads(info.stdout)["vibration"]
    assert recorded["final_report"] is True
    assert recorded["axes"] == s["vibration"]["axes"] and recorded["window_s"] == s["vibration"]["window_s"]
    # the recorded run replayed into the monitor's pipeline gives the live estimate bit for bit
    replay = analyze(venv_bin, bag)
    assert replay["flag_time_s"] == pytest.approx(st["flag_raised_at_s"], abs=1e-9)
    assert f"{replay['final']['rho']:.6f}" == mon["rho"]
    # while the rotor is in its air gap the estimate is the model's within 0.25 (rho - 1), tighter than the
    # monitor's mismatch allowance (0.4): the median of the refits before the first touchdown (the last ones see
    # the bearing law's nonlinearity as the orbit nears the backup bearings, and the contacts bend the windows
    # after them)
    plant = s["nodes"]["plant"]["values"]
    first_touch = float(plant["first touchdown"].split()[2]) if int(plant["touchdown contacts"]) else math.inf
    free = [e["rho"] for e in replay["estimates"] if e["excited"] and e["time_s"] < first_touch]
    rho_free, rho_model = float(np.median(free)), model["max_abs_multiplier"]
    assert abs(rho_free - rho_model) < 0.25 * (rho_model - 1.0), (rho_free, rho_model)
    # on the complete bag; the motion is the one refitted from the recorded base rates (amplitude, frequency)
    assert replay["model"]["rho"] == pytest.approx(model["max_abs_multiplier"], abs=1e-8)
    # sensor-only (the four AMB displacements a real rig has), same signals: flagged within 16 base periods too
    sensors = analyze(venv_bin, bag, "--sensor-only", "--no-model")
    assert sensors["unstable"] and sensors["flag_time_s"] <= 16 * base_period, sensors["flag_time_s"]


def analyze(venv_bin, bag, *extra):
    out = subprocess.run([str(venv_bin / "amb-monitor"), "analyze", str(bag), "--json", *extra], capture_output=True,
                         text=True, timeout=600)  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    return json.loads(out.stdout)


def test_real_rig_stable_point_raises_no_flag(venv_bin, tmp_path):
    # the default run (pitch 0.3 rad at 24.5 rad/s, outside the tongues: the model gives max|mu| < 1 per period):
    # unbalance, runout, noise and gravity must not read as instability, and the model value is the config's
    cfg = load_config(None)
    loop = model_loop(cfg)
    model = estimate_point(loop, BaseMotion.single("pitch", 0.3, 24.5), math.pi / 24.5)
    assert model["max_abs_multiplier"] + model["error_bound"] < 1.0
    cmd = [str(venv_bin / "amb-rig"), "run", "--duration", "6", "--json", "--log-dir", str(tmp_path / "logs")]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    s = json.loads(proc.stdout)
    st = s["stability"]
    assert st["unstable"] is False and st["flag_raised_at_s"] is None, st
    assert s["verdict"]["result"] != "unstable", s["verdict"]
    assert st["model_rho"] == pytest.approx(model["max_abs_multiplier"], abs=1e-6)
    assert st["model_mismatch"] is False
    # the fit's standard error assumes independent noise per entry; the refits' scatter shows the real spread
    assert st["rho_std"] is not None and st["rho_scatter"] is not None, st
    assert st["rho_std"] < st["rho_scatter"] < 0.005, st
    # the full state's positions identify the slowest mode: the accuracy, |rho_hat - rho| <= 0.005
    assert st["rho"] is not None and abs(st["rho"] - model["max_abs_multiplier"]) <= 0.005, st
