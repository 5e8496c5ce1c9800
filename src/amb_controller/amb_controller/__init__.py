"""Node: fixed-rate digital PID per AMB axis."""
