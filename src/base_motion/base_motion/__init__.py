"""Node: publishes the moving base's attitude, angular velocity and acceleration."""
