"""Remove the Fast DDS shared-memory files a killed process left in /dev/shm, never a live process's.

Fast DDS (the rmw of this project) keeps each shared-memory segment and port as a file in /dev/shm
(``fastrtps_<16 hex>``, ``fastrtps_port<N>``), each with a lock file (suffix ``_el`` or ``_sl``) that its
owner holds with ``flock`` for as long as it lives.  The kernel drops the lock when the owner dies, also by
SIGKILL, so a lock file that can be locked exclusively belongs to nobody: its segment, the lock file and (for a
port) its named semaphore ``sem.fastrtps_port<N>_mutex`` are leftovers that later runs would otherwise map
again.  A segment of a concurrent run is locked and stays.  Files younger than ``min_age_s`` are left alone
(their owner may be between creating the file and locking it), as are other users' files.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import re
import time
from pathlib import Path

SHM_DIR = Path("/dev/shm")
_LOCK = re.compile(r"^fastrtps_(?:port\d{1,5}|[0-9a-f]{16})_(?:el|sl)$")


def _unowned(lock_file: Path) -> bool:
    """True when nobody holds ``lock_file`` (an exclusive flock succeeds; it is released at once)."""
    try:
        fd = os.open(lock_file, os.O_RDONLY | os.O_NOFOLLOW)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return False
    else:
        fcntl.flock(fd, fcntl.LOCK_UN)
        return True
    finally:
        os.close(fd)


def clean_stale_shm(shm_dir: Path = SHM_DIR, min_age_s: float = 2.0) -> list[str]:
    """Delete stale Fast DDS segments/ports of this user in ``shm_dir``; return the names removed.

    Parameters
    ----------
    shm_dir : Path
        Where the segments live (/dev/shm on Linux).
    min_age_s : float
        Leave lock files modified less than this many seconds ago (s).
    """
    removed: list[str] = []
    try:
        names = os.listdir(shm_dir)
    except OSError:
        return removed
    now, uid = time.time(), os.geteuid()
    for name in sorted(names):
        if not _LOCK.match(name):
            continue
        lock = shm_dir / name
        try:
            st = lock.lstat()
        except OSError:
            continue
        if st.st_uid != uid or now - st.st_mtime < min_age_s or not _unowned(lock):
            continue
        base = name[:-3]
        victims = [base, name] + ([f"sem.{base}_mutex"] if base.startswith("fastrtps_port") else [])
        for victim in victims:
            with contextlib.suppress(FileNotFoundError):
                (shm_dir / victim).unlink()
                removed.append(victim)
    return removed
