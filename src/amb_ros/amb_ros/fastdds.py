"""The rig's Fast DDS profiles (XML files next to this module), applied through the environment.

Fast DDS reads its default profiles from the file named by ``FASTRTPS_DEFAULT_PROFILES_FILE`` when the first
participant is created, so setting it before ``rclpy.init`` (or in a child's environment) is enough.  A profile
file of the user's own is left alone.  Other RMW implementations ignore the variable.

Two files: ``fastdds_profile_localhost.xml`` for localhost-only discovery (the writer settings below plus
transports bound to loopback only: shared memory and UDPv4 on 127.0.0.1), ``fastdds_profile.xml`` for a wider
discovery the user asked for (the writer settings alone: Fast DDS's own transports on every interface).

With localhost discovery, rmw_fastrtps would add transports of its own for LOCALHOST (a UDPv4 transport that no
XML restricts, with send sockets on 0.0.0.0 and on each interface address).  The localhost file therefore
configures the whole participant (loopback transports, unicast discovery to 127.0.0.1, no multicast), and
:func:`init_rclpy` starts DDS inside :func:`rig_transports`, which tells rmw_fastrtps, for the duration of
``rclpy.init`` only, to leave the transports to it (range SYSTEM_DEFAULT, which makes rmw_fastrtps add nothing).
It does so only when that file is the profile in force and the RMW is Fast DDS; otherwise rmw_fastrtps's own
LOCALHOST handling stays.

On by default; ``AMB_RIG_FASTDDS_PROFILE=0`` turns it off.  With it, short lockstep runs got fast enough to end
before amb-rig's collector had discovered base_motion and the controller, whose reports were then lost; every
final report now waits for the collector (``min_diagnostics_readers``), and a full CI passed with the profile on.
"""

from __future__ import annotations

import os
from contextlib import contextmanager
from pathlib import Path

from .discovery import LOCALHOST, PEERS_VAR, RANGE_VAR, SYSTEM_DEFAULT

PROFILE_FILE = Path(__file__).with_name("fastdds_profile.xml")
LOCALHOST_PROFILE_FILE = Path(__file__).with_name("fastdds_profile_localhost.xml")
PROFILE_VARS = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")
SWITCH = "AMB_RIG_FASTDDS_PROFILE"  # "0": Fast DDS's own defaults
_OURS = {str(PROFILE_FILE), str(LOCALHOST_PROFILE_FILE)}
FAST_DDS_RMWS = ("", "rmw_fastrtps_cpp", "rmw_fastrtps_dynamic_cpp")  # "": the default RMW of Jazzy


def use_rig_profile(env: dict, localhost_only: bool = True) -> dict:
    """Point Fast DDS at the rig's profile for this discovery in ``env`` unless a profile file of the user's own
    is given or ``AMB_RIG_FASTDDS_PROFILE=0``; returns ``env``.  One of the rig's own files (inherited from a
    parent whose discovery differed) is replaced by the one that fits."""
    given = [var for var in PROFILE_VARS if env.get(var)]
    if any(env[var] not in _OURS for var in given):
        return env
    for var in given:
        del env[var]
    if env.get(SWITCH) != "0":
        env[PROFILE_VARS[0]] = str(LOCALHOST_PROFILE_FILE if localhost_only else PROFILE_FILE)
    return env


def profile_confines_localhost(env: dict) -> bool:
    """True when ``env`` gives localhost discovery through the rig's localhost profile on Fast DDS."""
    return (
        env.get(RANGE_VAR) == LOCALHOST
        and not env.get(PEERS_VAR)
        and env.get(PROFILE_VARS[0]) == str(LOCALHOST_PROFILE_FILE)
        and not env.get(PROFILE_VARS[1])
        and env.get("RMW_IMPLEMENTATION", "") in FAST_DDS_RMWS
        and LOCALHOST_PROFILE_FILE.is_file()
    )


@contextmanager
def rig_transports():
    """Wrap ``rclpy.init``: where the localhost profile is in force, rmw_fastrtps gets range SYSTEM_DEFAULT
    while rcl reads it (``rclpy.init`` copies it into the context), so that the profile alone sets the
    transports; this process's environment says LOCALHOST again right after.  Yields whether it did."""
    if not profile_confines_localhost(os.environ):
        yield False
        return
    os.environ[RANGE_VAR] = SYSTEM_DEFAULT
    try:
        yield True
    finally:
        os.environ[RANGE_VAR] = LOCALHOST


def init_rclpy(**kwargs) -> None:
    """``rclpy.init(**kwargs)`` inside :func:`rig_transports`: how every process of the project starts DDS."""
    import rclpy

    with rig_transports():
        rclpy.init(**kwargs)
