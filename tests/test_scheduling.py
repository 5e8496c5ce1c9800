"""Process-wide scheduling helpers (amb_ros.node_base): every thread is changed, not just the caller.

Linux niceness and scheduling policy are per thread; the DDS threads that receive each message exist before a
node lowers its priority, so a helper that changed the calling thread only would leave them competing with the
loop.  Each case runs in a fresh interpreter with a few extra threads and reads every thread's value back from
/proc (field 19 of /proc/self/task/<tid>/stat is the niceness).
"""

from __future__ import annotations

import json
import subprocess
import sys

SCRIPT = """
import json, os, threading, time
from amb_ros.node_base import lower_priority

stop = threading.Event()
threads = [threading.Thread(target=stop.wait) for _ in range(3)]
for t in threads:
    t.start()
def nice_of(tid):
    with open(f"/proc/self/task/{tid}/stat") as f:
        return int(f.read().rsplit(")", 1)[1].split()[16])
before = {tid: nice_of(tid) for tid in os.listdir("/proc/self/task")}
text = lower_priority(INCREMENT)
after = {tid: nice_of(tid) for tid in os.listdir("/proc/self/task")}
stop.set()
print(json.dumps({"before": before, "after": after, "text": text}))
"""


def run(increment: int) -> dict:
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT.replace("INCREMENT", str(increment))],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_lower_priority_renices_every_thread():
    got = run(3)
    assert len(got["before"]) >= 4  # the main thread, three others (and any a library started on import)
    assert got["after"] == {tid: min(19, nice + 3) for tid, nice in got["before"].items()}
    assert got["text"] == f"nice +3 ({len(got['before'])} threads)"


def test_lower_priority_stops_at_19():
    got = run(25)
    assert set(got["after"].values()) == {19}
