"""c4d_sim — vehicle simulation: the ROS-free multirotor plant (and, with issue 5, the SITL node)."""
