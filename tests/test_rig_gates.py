"""amb-rig's start gates: the plant and base_motion wait for exactly the readers that will come (no more: a gate
that counts a reader which never subscribes hangs the start; no fewer: a late reader would miss step 0)."""

from __future__ import annotations

import pytest

from amb_bringup.processes import bag_process, node_parameters
from amb_bringup.rig import parser


def gates(*argv: str) -> dict:
    _, per = node_parameters(parser().parse_args(["run", *argv]))
    return {f"{n}.{k}": v for n, p in per.items() for k, v in p.items() if k.startswith("min_")}


@pytest.mark.parametrize(
    ("argv", "rates", "imu", "acc", "state", "disp"),
    [
        ((), 1, 1, 0, 1, 1),  # the plant reads /base/rates, the monitor /base/imu and the state
        (("--no-monitor",), 1, 0, 0, 0, 1),
        (("--bag", "b"), 2, 2, 1, 2, 2),  # + the recorder reads everything
        (("--param", "monitor:period_s=0.14"), 1, 0, 0, 1, 1),  # a given period: the monitor reads no /base/imu
        (("--param", "monitor:input=displacement"), 1, 1, 0, 0, 2),  # sensor-only monitor reads the displacements
        (("--no-plant",), 0, 1, 0, 0, 2),  # no plant: the monitor reads imu and displacements
    ],
)
def test_reader_gates_count_the_readers_that_come(argv, rates, imu, acc, state, disp):
    g = gates(*argv)
    assert g["base_motion.min_rates_subscribers"] == rates
    assert g["base_motion.min_imu_subscribers"] == imu
    assert g["base_motion.min_acceleration_subscribers"] == acc
    assert g["plant.min_state_subscribers"] == state
    assert g["plant.min_subscribers"] == disp


@pytest.mark.parametrize(("argv", "readers"), [((), 1), (("--bag", "b"), 2), (("--live",), 2),
                                               (("--bag", "b", "--live"), 3)])  # fmt: skip
def test_final_reports_wait_for_every_diagnostics_reader(argv, readers):
    """The collector, the recorder and the live view each read /diagnostics: a final report sent when only the
    recorder had matched never reached the collector (a short run then ended with 'published no diagnostics')."""
    _, per = node_parameters(parser().parse_args(["run", *argv]))
    assert {p["min_diagnostics_readers"] for p in per.values()} == {readers}


@pytest.mark.parametrize(("mode", "priority"), [("lockstep", "normal"), ("realtime", "low")])
def test_consumers_are_starved_only_beside_a_realtime_loop(tmp_path, mode, priority):
    args = parser().parse_args(["run", "--mode", mode, "--bag", str(tmp_path / "b")])
    _, per = node_parameters(args)
    assert per["monitor"]["priority"] == priority
    cmd = bag_process(args, tmp_path).cmd
    assert cmd[cmd.index("--priority") + 1] == priority
    _, per = node_parameters(parser().parse_args(["run", "--mode", "realtime", "--param", "monitor:priority=idle"]))
    assert per["monitor"]["priority"] == "idle"  # an explicit --param wins


@pytest.mark.ros
def test_a_late_peer_is_start_up_not_loop_time(tmp_path, venv_bin):
    """base_motion held at its gate for ~2 s (a reader it waits for subscribes late, as a recorder still being
    discovered does): the plant reports that wait as `start wait (s)`, and neither its per-step command waits
    nor its loop rate (steps/s) contain it."""
    import time

    from geometry_msgs.msg import Vector3Stamped
    from rosgraph_msgs.msg import Clock

    from helpers import DdsRecorder, rig_json
    from procs import spawn

    late_s, duration = 2.0, 1.0
    cmd = [str(venv_bin / "amb-rig"), "run", "--json", "--no-monitor", "--duration", str(duration),
           "--log-dir", str(tmp_path / "logs"), "--param", "base_motion:min_acceleration_subscribers=1"]  # fmt: skip
    clock = DdsRecorder({"/clock": Clock})  # the plant publishes /clock t_0 with step 0
    late = None
    try:
        with spawn(cmd, tmp_path / "rig.log") as proc:
            end = time.monotonic() + 60
            while not clock.messages["/clock"] and time.monotonic() < end and proc.popen.poll() is None:
                time.sleep(0.01)
            assert clock.messages["/clock"], proc.text()
            time.sleep(late_s)  # the plant waits for step 0's base sample meanwhile
            t_late = time.monotonic()
            late = DdsRecorder({"/base/angular_acceleration": Vector3Stamped})
            assert proc.wait(120) == 0, proc.text()
            t_end = time.monotonic()
            s = rig_json(proc.text())
    finally:
        for rec in (clock, late):
            if rec is not None:
                rec.close()
    plant = s["nodes"]["plant"]["values"]
    assert s["ok"] and s["steps"] == round(duration * s["rate_hz"])
    assert float(plant["start wait (s)"]) >= late_s
    assert float(plant["command wait max (us)"]) * 1e-6 < late_s  # the per-step waits exclude it
    # the loop is timed from step 0's inputs, which came after the late reader subscribed
    assert float(plant["wall time (s)"]) <= t_end - t_late
    assert s["steps_per_s"] == pytest.approx(s["steps"] / float(plant["wall time (s)"]), rel=1e-3)
