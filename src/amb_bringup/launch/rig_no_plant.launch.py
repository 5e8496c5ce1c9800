"""The rig without the plant (a real rig supplies /amb/displacement): ``ros2 launch amb_bringup
rig_no_plant.launch.py``; the same as ``amb-rig run --no-plant`` (nodes and parameters from amb_bringup.launchgen).
"""

from amb_bringup.launchgen import launch_description


def generate_launch_description():
    return launch_description(overrides={"no_plant": "true"})
