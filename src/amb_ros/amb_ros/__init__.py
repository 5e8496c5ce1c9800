"""Shared ROS 2 glue for the amb-rig nodes: DDS environment, QoS, diagnostics, message checks."""
