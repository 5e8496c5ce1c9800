"""MCAP recorder (rosbag2 layout), player, info, check and plot."""
