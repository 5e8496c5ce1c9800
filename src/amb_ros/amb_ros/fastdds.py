"""The rig's Fast DDS profile (``fastdds_profile.xml`` next to this module), applied through the environment.

Fast DDS reads its default profiles from the file named by ``FASTRTPS_DEFAULT_PROFILES_FILE`` when the first
participant is created, so setting it before ``rclpy.init`` (or in a child's environment) is enough.  A profile
file of the user's own is left alone.  Other RMW implementations ignore the variable.

On by default; ``AMB_RIG_FASTDDS_PROFILE=0`` turns it off.  With it, short lockstep runs got fast enough to end
before amb-rig's collector had discovered base_motion and the controller, whose reports were then lost; every
final report now waits for the collector (``min_diagnostics_readers``), and a full CI passed with the profile on.
"""

from __future__ import annotations

from pathlib import Path

PROFILE_FILE = Path(__file__).with_name("fastdds_profile.xml")
PROFILE_VARS = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")
SWITCH = "AMB_RIG_FASTDDS_PROFILE"  # "0": Fast DDS's own defaults


def use_rig_profile(env: dict) -> dict:
    """Point Fast DDS at the rig's profile in ``env`` unless a profile file is already given or
    ``AMB_RIG_FASTDDS_PROFILE=0``; returns ``env``."""
    if env.get(SWITCH) != "0" and not any(env.get(var) for var in PROFILE_VARS):
        env[PROFILE_VARS[0]] = str(PROFILE_FILE)
    return env
