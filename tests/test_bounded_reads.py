"""Recorded trajectories are read bounded (issue 20 item 5) and the controller's final count is fresh (item 3).

Before: ``base_motion:recorded_file=/dev/zero`` was read without limit (24 GB in 50 s, then the OOM killer), and
a bad line was quoted in the error message (a password file's line ended up in the summary and the logs).
"""

from __future__ import annotations

import numpy as np
import pytest

from amb_dynamics.errors import InputError
from amb_dynamics.recorded import MAX_TRAJECTORY_BYTES, load_recorded


def test_dev_zero_is_refused_before_reading():
    with pytest.raises(InputError) as exc:
        load_recorded("/dev/zero")
    assert str(exc.value) == "/dev/zero: not a regular file (a recorded trajectory must be a file)"


def test_oversized_file_is_refused_by_its_size(tmp_path):
    big = tmp_path / "big.csv"
    with open(big, "wb") as f:  # sparse: the size is checked, nothing is read
        f.truncate(MAX_TRAJECTORY_BYTES + 1)
    with pytest.raises(InputError) as exc:
        load_recorded(big)
    assert f"{MAX_TRAJECTORY_BYTES + 1} bytes, larger than the {MAX_TRAJECTORY_BYTES}-byte limit" in str(exc.value)


def test_a_bad_line_is_named_by_number_and_never_echoed(tmp_path):
    secret = "root,$6$saltsalt$0123456789abcdef:19000:0:99999:7:::"
    path = tmp_path / "traj.csv"
    rows = "\n".join(f"{0.01 * k},{0.1 * np.sin(k)}" for k in range(10))
    path.write_text(f"t,pitch\n{rows}\n{secret}\n")
    with pytest.raises(InputError) as exc:
        load_recorded(path)
    assert str(exc.value) == f"{path}: line 12 is not a row of numbers"  # header, 10 rows, then the bad one
    path.write_text(f"{secret}\n{rows}\n")
    with pytest.raises(InputError) as exc:
        load_recorded(path)
    text = str(exc.value).removeprefix(f"{path}: ")
    assert text.startswith("line 1 (header)") and "saltsalt" not in text and "root" not in text


def test_a_good_trajectory_still_loads(tmp_path):
    path = tmp_path / "traj.csv"
    t = np.linspace(0.0, 1.0, 201)
    path.write_text("t,pitch\n" + "\n".join(f"{float(a)!r},{float(0.2 * np.sin(5 * a))!r}" for a in t) + "\n")
    motion = load_recorded(path, smoothing=1e-12)
    assert motion.duration == pytest.approx(1.0)
    beta = motion._angles(np.array([0.5]))  # the smoothing spline through 0.2 sin(5 t), nearly interpolating
    assert np.asarray(beta[0]).ravel()[1] == pytest.approx(0.2 * np.sin(2.5), abs=1e-6)


@pytest.mark.ros
def test_controller_final_count_includes_the_last_publish():
    """values() sets ``published /amb/current`` before reading the counters: the first report is not stale."""
    import rclpy

    from amb_controller.node import ControllerNode
    from amb_ros.runtime import StopFlag

    rclpy.init(args=[])
    try:
        node = ControllerNode(StopFlag())
        node.answered, node.safe_ticks = 7, 2
        assert node.values()["published /amb/current"] == "9"  # 7 answers + 2 zero-current ticks, this report
        node.answered = 8
        assert node.values()["published /amb/current"] == "10"
        node.destroy_node()
    finally:
        rclpy.try_shutdown()
