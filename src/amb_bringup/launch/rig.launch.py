"""The rig as ``amb-rig run`` starts it, for a full ROS 2 install: ``ros2 launch amb_bringup rig.launch.py``.

Arguments mirror amb-rig's options (``ros2 launch amb_bringup rig.launch.py --show-args``), e.g.
``duration:=2.0 motion:=pitch amplitude:=0.3 frequency:=24.5 bag:=out/run1``.  The nodes and their parameters are
computed by amb-rig's own code (amb_bringup.launchgen), so this file and amb-rig cannot drift apart.  In lockstep
the launch ends when the plant has run its duration.  amb-rig adds what a launch file cannot: the domain lock,
the start-up gates it waits on, and the run summary.
"""

from amb_bringup.launchgen import launch_description


def generate_launch_description():
    return launch_description()
