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
