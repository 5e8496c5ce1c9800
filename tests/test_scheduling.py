"""Process-wide scheduling helpers (amb_ros.scheduling): every thread is changed, not just the caller.

Linux niceness and scheduling policy are per thread; the DDS threads that receive each message exist before a
node lowers its priority, so a helper that changed the calling thread only would leave them competing with the
loop.  Each case runs in a fresh interpreter with a few extra threads and reads every thread's value back from
/proc (field 19 of /proc/self/task/<tid>/stat is the niceness) or sched_getscheduler.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from amb_ros.scheduling import consumer_priority

SCRIPT = """
import json, os, threading, time
from amb_ros.scheduling import consumer_priority, idle_priority, lower_priority

stop = threading.Event()
threads = [threading.Thread(target=stop.wait) for _ in range(3)]
for t in threads:
    t.start()
def nice_of(tid):
    with open(f"/proc/self/task/{tid}/stat") as f:
        return int(f.read().rsplit(")", 1)[1].split()[16])
def policy_of(tid):
    return os.sched_getscheduler(int(tid)) == os.SCHED_IDLE
before = {tid: nice_of(tid) for tid in os.listdir("/proc/self/task")}
text = CALL
after = {tid: nice_of(tid) for tid in os.listdir("/proc/self/task")}
idle = {tid: policy_of(tid) for tid in os.listdir("/proc/self/task")}
late = threading.Thread(target=lambda: idle.update(late=policy_of(threading.get_native_id())))
late.start()
late.join()
stop.set()
print(json.dumps({"before": before, "after": after, "text": text, "idle": idle}))
"""


def run(call: str) -> dict:
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT.replace("CALL", call)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_lower_priority_renices_every_thread():
    got = run("lower_priority(3)")
    assert len(got["before"]) >= 4  # the main thread, three others (and any a library started on import)
    assert got["after"] == {tid: min(19, nice + 3) for tid, nice in got["before"].items()}
    assert got["text"] == f"nice +3 ({len(got['before'])} threads)"


def test_lower_priority_stops_at_19():
    got = run("lower_priority(25)")
    assert set(got["after"].values()) == {19}


def test_idle_priority_covers_every_thread_and_later_ones():
    got = run("idle_priority()")
    assert len(got["idle"]) >= 5 and all(got["idle"].values())  # four threads, then one started afterwards
    assert got["after"] == got["before"]  # SCHED_IDLE, not niceness
    assert got["text"] == f"SCHED_IDLE ({len(got['before'])} threads)"


def test_consumer_priority_names_the_three_levels():
    low = run("consumer_priority('low')")
    assert low["after"] == {tid: min(19, nice + 5) for tid, nice in low["before"].items()}
    normal = run("consumer_priority('normal')")
    assert normal["text"] == "normal" and normal["after"] == normal["before"] and not any(normal["idle"].values())
    with pytest.raises(ValueError, match="unknown priority 'high'"):
        consumer_priority("high")  # refused before anything is changed
