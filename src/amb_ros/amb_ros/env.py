"""DDS hygiene: every process of the project keeps discovery on localhost (docs/nodes.md).

This module imports no ROS code, so it can run before ``rclpy.init``.  ``ensure_localhost_dds()`` is the
first call of every entry point that may start DDS; ``reserve_domain_id()`` gives a test session or an
``amb-rig`` run a ROS_DOMAIN_ID that no concurrent run on this machine holds (an exclusive file lock);
``hold_run_lock()`` keeps a second ``amb-rig`` off a domain given explicitly that a running rig already uses.
"""

from __future__ import annotations

import fcntl
import os
import random
import tempfile
import time
from pathlib import Path

from .fastdds import use_rig_profile

LOCALHOST = "LOCALHOST"
DOMAIN_RANGE = range(10, 100)  # ids 0..101 are safe for Fast DDS ports on Linux
_held_locks: list = []


class DdsEnvError(RuntimeError):
    """The environment asks for DDS discovery beyond this machine."""


def ensure_localhost_dds(env: dict | None = None) -> dict:
    """Set ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST (and a domain id) unless set; refuse other ranges.

    Also points Fast DDS at the rig's profile (:mod:`amb_ros.fastdds`) unless the user gave one."""
    env = os.environ if env is None else env
    current = env.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "")
    if current and current.upper() != LOCALHOST:
        raise DdsEnvError(
            f"ROS_AUTOMATIC_DISCOVERY_RANGE={current} would let DDS discover beyond this machine; "
            "amb-rig only runs with LOCALHOST"
        )
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = LOCALHOST
    env.pop("ROS_STATIC_PEERS", None)
    # deprecated in Jazzy (rcl warns whenever it is set, even to 0); the range above replaces it
    env.pop("ROS_LOCALHOST_ONLY", None)
    if not env.get("ROS_DOMAIN_ID"):
        env["ROS_DOMAIN_ID"] = str(reserve_domain_id())
    use_rig_profile(env)
    return env


def reserve_domain_id(seed: int | None = None) -> int:
    """Lock and return a ROS_DOMAIN_ID that no other live process of this project holds."""
    rng = random.Random(seed if seed is not None else os.getpid() ^ int.from_bytes(os.urandom(4), "little"))
    ids = list(DOMAIN_RANGE)
    rng.shuffle(ids)
    lock_dir = Path(tempfile.gettempdir())
    for domain in ids:
        fh = open(lock_dir / f"amb-rig-ros-domain-{domain}.lock", "w")
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.close()
            continue
        _held_locks.append(fh)
        return domain
    raise DdsEnvError(f"every ROS_DOMAIN_ID in {DOMAIN_RANGE.start}..{DOMAIN_RANGE.stop - 1} is in use")


def hold_run_lock(domain: str, wait_s: float = 0.0, on_wait=None):
    """Lock ``domain`` for one rig run and return the open lock file; raise DdsEnvError if a run holds it.

    Pass the file to the run's children (``pass_fds``): the lock is released when the last of them has exited,
    so nodes still shutting down after amb-rig itself was killed keep the domain too.  A held lock is retried
    for ``wait_s`` (the nodes of a run that just ended may still be exiting); ``on_wait(holder)`` is called once
    when the wait begins.
    """
    fh = open(Path(tempfile.gettempdir()) / f"amb-rig-run-domain-{domain}.lock", "a+")
    deadline = time.monotonic() + wait_s
    while True:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
            break
        except OSError:
            fh.seek(0)
            holder = fh.read().strip() or "a process"
        if time.monotonic() >= deadline:
            fh.close()
            raise DdsEnvError(
                f"ROS_DOMAIN_ID={domain} is used by another amb-rig run ({holder} or its nodes): two rigs on one "
                "domain would mix their samples. Stop it, or give this run another ROS_DOMAIN_ID (unset, amb-rig "
                "picks a free one)"
            )
        if on_wait is not None:
            on_wait(holder)
            on_wait = None
        time.sleep(0.1)
    fh.seek(0)
    fh.truncate()
    fh.write(f"amb-rig pid {os.getpid()}")
    fh.flush()
    return fh


def child_env(base: dict | None = None, **extra: str) -> dict:
    """Environment for a spawned node: the parent's, localhost DDS, the same domain, plus ``extra``."""
    env = dict(os.environ if base is None else base)
    ensure_localhost_dds(env)
    env.update(extra)
    return env
