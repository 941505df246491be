"""c4d_health — monitors, diagnostics and the failsafe policy (ROS-free logic + the health node)."""
