"""DDS hygiene: discovery on localhost unless the user asks for more, and a domain id no concurrent run shares.

This module imports no ROS code, so it can run before ``rclpy.init``.  ``ensure_localhost_dds()`` is the
first call of every entry point that may start DDS: LOCALHOST when the user set nothing, a wider discovery the
user set (``amb_ros.discovery``) checked and announced with one warning line; ``force_localhost_dds()`` is what
tests, the demo and the benchmarks use.  ``reserve_domain_id()`` gives a test session or an ``amb-rig`` run a
ROS_DOMAIN_ID that no concurrent run on this machine holds (an exclusive file lock); ``hold_run_lock()`` keeps a
second ``amb-rig`` off a domain given explicitly that a running rig already uses (per network namespace).
"""

from __future__ import annotations

import fcntl
import os
import random
import sys
import tempfile
import time
from pathlib import Path

from .discovery import LOCALHOST, PEERS_VAR, RANGE_VAR, DiscoveryError, resolve
from .fastdds import use_rig_profile

DOMAIN_RANGE = range(10, 100)  # ids 0..101 are safe for Fast DDS ports on Linux
_held_locks: list = []
_warned: list[str] = []


class DdsEnvError(RuntimeError):
    """The environment asks for a DDS discovery that ROS 2 would not understand (the message names it)."""


def ensure_localhost_dds(env: dict | None = None) -> dict:
    """LOCALHOST discovery (and a domain id) unless the user set a valid wider one; refuse invalid settings.

    A wider discovery (ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET or SYSTEM_DEFAULT, or ROS_STATIC_PEERS) is kept and,
    for this process's own environment (``env`` None), announced once with one warning line on stderr.  Also
    points Fast DDS at the rig's profile for that discovery (:mod:`amb_ros.fastdds`) unless the user gave one.
    """
    own = env is None
    env = os.environ if env is None else env
    try:
        found = resolve(env)
    except DiscoveryError as exc:
        raise DdsEnvError(str(exc)) from None
    env[RANGE_VAR] = found.range
    if found.peers:
        env[PEERS_VAR] = ";".join(found.peers)
    else:
        env.pop(PEERS_VAR, None)
    # deprecated in Jazzy (rcl warns whenever it is set, even to 0); the range above replaces it
    env.pop("ROS_LOCALHOST_ONLY", None)
    if not env.get("ROS_DOMAIN_ID"):
        env["ROS_DOMAIN_ID"] = str(reserve_domain_id())
    use_rig_profile(env, localhost_only=found.localhost_only)
    if own and not found.localhost_only and found.warning() not in _warned:
        _warned.append(found.warning())
        print(f"{Path(sys.argv[0]).name or 'amb-rig'}: {found.warning()}", file=sys.stderr, flush=True)
    return env


def force_localhost_dds(env: dict | None = None) -> dict:
    """LOCALHOST discovery whatever the environment says (tests, ``make demo``, ``make bench``, CI)."""
    env = os.environ if env is None else env
    env[RANGE_VAR] = LOCALHOST
    env.pop(PEERS_VAR, None)
    return ensure_localhost_dds(env)


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


def network_namespace() -> str:
    """This process's network namespace (the inode of /proc/self/ns/net; "" where there is none)."""
    try:
        return str(os.stat("/proc/self/ns/net").st_ino)
    except OSError:
        return ""


def hold_run_lock(domain: str, wait_s: float = 0.0, on_wait=None, side: str = ""):
    """Lock ``domain`` for one rig run and return the open lock file; raise DdsEnvError if a run holds it.

    The lock is per network namespace (rigs in two namespaces reach each other only through a discovery the
    user widened, and the graph checks of ``amb_bringup.domain`` guard that case) and, with ``side``, per side
    of a run split across two processes (``amb-rig --only plant`` and ``--no-plant``: a full rig takes both).

    Pass the file to the run's children (``pass_fds``): the lock is released when the last of them has exited,
    so nodes still shutting down after amb-rig itself was killed keep the domain too.  A held lock is retried
    for ``wait_s`` (the nodes of a run that just ended may still be exiting); ``on_wait(holder)`` is called once
    when the wait begins.
    """
    netns = network_namespace()
    name = f"amb-rig-run-domain-{domain}" + (f"-net{netns}" if netns else "") + (f"-{side}" if side else "")
    fh = open(Path(tempfile.gettempdir()) / f"{name}.lock", "a+")
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
                f"ROS_DOMAIN_ID={domain} is used by another amb-rig run{f' ({side} side)' if side else ''} ({holder} "
                "or its nodes): two rigs on one "
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
    """Environment for a spawned node: the parent's (its discovery checked), the same domain, plus ``extra``."""
    env = dict(os.environ if base is None else base)
    ensure_localhost_dds(env)
    env.update(extra)
    return env
