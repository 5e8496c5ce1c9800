"""The rig's Fast DDS profile (``fastdds_profile.xml`` next to this module), applied through the environment.

Fast DDS reads its default profiles from the file named by ``FASTRTPS_DEFAULT_PROFILES_FILE`` when the first
participant is created, so setting it before ``rclpy.init`` (or in a child's environment) is enough.  A profile
file of the user's own is left alone.  Other RMW implementations ignore the variable.
"""

from __future__ import annotations

from pathlib import Path

PROFILE_FILE = Path(__file__).with_name("fastdds_profile.xml")
PROFILE_VARS = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")


def use_rig_profile(env: dict) -> dict:
    """Point Fast DDS at the rig's profile in ``env`` unless a profile file is already given; returns ``env``."""
    if not any(env.get(var) for var in PROFILE_VARS):
        env[PROFILE_VARS[0]] = str(PROFILE_FILE)
    return env
