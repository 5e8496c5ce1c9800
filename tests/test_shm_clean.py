"""Fast DDS shared-memory leftovers of a killed process are removed; a live process's are not (issue 20 item 8).

Before: kill -9 of a node left its /dev/shm segments, which later runs mapped again.  The first test builds the
files by hand in a private folder (lock held by another process for the "live" ones); the second kills a real
rclpy process with SIGKILL and cleans /dev/shm while a second rclpy process keeps running.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from amb_ros.shm_clean import SHM_DIR, clean_stale_shm

HOLD = "\n".join(
    [
        "import fcntl, sys, time",
        "f = open(sys.argv[1])",
        "fcntl.flock(f, fcntl.LOCK_EX)",
        "print('locked', flush=True)",
        "time.sleep(60)",
    ]
)


def _old(*paths: Path) -> None:
    for p in paths:
        p.write_bytes(b"x")
        os.utime(p, (time.time() - 60, time.time() - 60))


def test_unlocked_segments_and_ports_go_locked_and_young_ones_stay(tmp_path):
    zombie, live, young = "fastrtps_00000000000000aa", "fastrtps_00000000000000bb", "fastrtps_00000000000000cc"
    _old(tmp_path / zombie, tmp_path / f"{zombie}_el", tmp_path / live, tmp_path / f"{live}_el")
    _old(tmp_path / "fastrtps_port7411", tmp_path / "fastrtps_port7411_sl", tmp_path / "sem.fastrtps_port7411_mutex")
    _old(tmp_path / "unrelated_el", tmp_path / "fastrtps_port7412")  # no lock file of ours / not a lock file
    (tmp_path / young).write_bytes(b"x")
    (tmp_path / f"{young}_el").write_bytes(b"")
    holder = subprocess.Popen([sys.executable, "-c", HOLD, str(tmp_path / f"{live}_el")], stdout=subprocess.PIPE)
    try:
        assert holder.stdout.readline().strip() == b"locked"
        removed = clean_stale_shm(tmp_path)
    finally:
        holder.kill()
        holder.wait()
    assert sorted(removed) == sorted([zombie, f"{zombie}_el", "fastrtps_port7411", "fastrtps_port7411_sl",
                                      "sem.fastrtps_port7411_mutex"])  # fmt: skip
    left = sorted(p.name for p in tmp_path.iterdir())
    assert left == sorted([live, f"{live}_el", young, f"{young}_el", "unrelated_el", "fastrtps_port7412"])


NODE = """
import sys, time, rclpy
from std_msgs.msg import Float64
rclpy.init()
n = rclpy.create_node(sys.argv[1])
p = n.create_publisher(Float64, '/shm_clean_probe', 10)
print('up', flush=True)
while True:
    p.publish(Float64(data=1.0)); time.sleep(0.05)
"""


def _locked_by(pid: int) -> set[str]:
    """Lock files in /dev/shm on which ``pid`` holds a flock (from /proc/locks), and their segments."""
    inodes = set()
    for line in Path("/proc/locks").read_text().splitlines():
        f = line.split()
        if len(f) >= 6 and f[1] == "FLOCK" and f[4] == str(pid):
            inodes.add(int(f[5].split(":")[2]))
    out = set()
    for name in os.listdir(SHM_DIR):
        if name.startswith("fastrtps_") and name.endswith(("_el", "_sl")):
            try:
                if (SHM_DIR / name).stat().st_ino in inodes:
                    out |= {name, name[:-3]}
            except FileNotFoundError:
                pass
    return out


def _segments() -> set[str]:
    return {n for n in os.listdir(SHM_DIR) if n.startswith("fastrtps_")}


@pytest.mark.ros
def test_kill_9_leftovers_are_cleaned_and_a_live_process_keeps_its_segments():
    victim = subprocess.Popen([sys.executable, "-c", NODE, "victim"], stdout=subprocess.PIPE)
    try:
        assert victim.stdout.readline().strip() == b"up"
        time.sleep(0.5)
        mine = _locked_by(victim.pid)  # this machine is shared: other processes create segments meanwhile
        survivor = subprocess.Popen([sys.executable, "-c", NODE, "survivor"], stdout=subprocess.PIPE)
        assert survivor.stdout.readline().strip() == b"up"
        time.sleep(0.5)
        theirs = _locked_by(survivor.pid)
        os.kill(victim.pid, signal.SIGKILL)
        victim.wait()
        if not mine:
            pytest.fail("the rclpy process created no Fast DDS shared-memory files (is SHM transport off?)")
        assert mine <= _segments()  # left behind by the SIGKILL
        time.sleep(2.5)  # older than min_age_s
        clean_stale_shm()
        # the victim's own segments go; its port files are shared by every participant of the domain (the
        # survivor's too) and stay while one of them holds the port's lock
        own = {n for n in mine if not n.startswith("fastrtps_port")}
        assert own and not (own & _segments()), own & _segments()
        assert theirs and theirs <= _segments()  # the live process's segments are untouched
        assert survivor.poll() is None
    finally:
        for p in (victim, locals().get("survivor")):
            if p is not None and p.poll() is None:
                p.send_signal(signal.SIGINT)
                try:
                    p.wait(5)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()


@pytest.mark.ros
def test_a_killed_rigs_segments_are_gone_after_the_next_amb_rig_start(tmp_path, venv_bin):
    """kill -9 of a whole amb-rig run (amb-rig and every node) leaves its Fast DDS segments in /dev/shm; the next
    ``amb-rig run`` removes them when it starts (rig.py calls clean_stale_shm before its first node)."""
    from helpers import started_pids, wait_gone
    from procs import spawn

    cmd = [str(venv_bin / "amb-rig"), "run", "--duration", "100", "--no-monitor", "--log-dir", str(tmp_path / "a")]
    with spawn(cmd, tmp_path / "killed.log") as rig:
        assert rig.wait_for("started plant", 60), rig.text()
        time.sleep(3.0)  # the loop runs: every node has its segments
        pids = started_pids(rig.text())
        left = set().union(*(_locked_by(p) for p in pids.values()))
        for pid in [rig.popen.pid, *pids.values()]:
            os.kill(pid, signal.SIGKILL)
        assert wait_gone([rig.popen.pid, *pids.values()]) == []
    own = {n for n in left if not n.startswith("fastrtps_port")}  # port files are shared by the whole domain
    assert len(own) >= 2 * len(pids) and own <= _segments()  # a segment and its lock file per node, left behind
    time.sleep(2.5)  # older than clean_stale_shm's min_age_s
    nxt = [str(venv_bin / "amb-rig"), "run", "--duration", "0.2", "--no-monitor", "--log-dir", str(tmp_path / "b")]
    done = subprocess.run(nxt, capture_output=True, text=True, timeout=180)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert not (own & _segments()), sorted(own & _segments())
