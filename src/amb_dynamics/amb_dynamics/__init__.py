"""ROS-free numerical core: FE rotor on AMBs, moving base, Floquet, Newmark, sampled-data loop, estimator."""
