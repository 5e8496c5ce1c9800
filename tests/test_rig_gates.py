"""amb-rig's start gates: the plant and base_motion wait for exactly the readers that will come (no more: a gate
that counts a reader which never subscribes hangs the start; no fewer: a late reader would miss step 0)."""

from __future__ import annotations

import pytest

from amb_bringup.processes import node_parameters
from amb_bringup.rig import parser


def gates(*argv: str) -> dict:
    _, per = node_parameters(parser().parse_args(["run", *argv]))
    return {f"{n}.{k}": v for n, p in per.items() for k, v in p.items() if k.startswith("min_")}


@pytest.mark.parametrize(
    ("argv", "imu", "state", "disp"),
    [
        ((), 2, 1, 1),  # plant + monitor read /base/imu; the monitor reads the state
        (("--no-monitor",), 1, 0, 1),
        (("--bag", "b"), 3, 2, 2),  # + the recorder reads everything
        (("--param", "monitor:period_s=0.14"), 1, 1, 1),  # a given period: the monitor reads no /base/imu
        (("--param", "monitor:input=displacement"), 2, 0, 2),  # sensor-only monitor reads the displacements
        (("--no-plant",), 1, 0, 2),  # no plant: the monitor reads imu and displacements
    ],
)
def test_reader_gates_count_the_readers_that_come(argv, imu, state, disp):
    g = gates(*argv)
    assert g["base_motion.min_imu_subscribers"] == imu
    assert g["plant.min_state_subscribers"] == state
    assert g["plant.min_subscribers"] == disp
