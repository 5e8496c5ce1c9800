"""The recorder alone: ``ros2 launch amb_bringup record.launch.py bag:=out/run1`` (``ros2 run amb_bag record -o
out/run1``, the process ``amb-rig run --bag out/run1`` starts); nodes from amb_bringup.launchgen.
"""

from amb_bringup.launchgen import launch_description


def generate_launch_description():
    return launch_description(recorder_only=True, overrides={"bag": "bag"})
