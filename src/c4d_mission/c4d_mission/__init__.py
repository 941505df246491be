"""c4d_mission — plans, validation, command executor and waypoint guidance (ROS-free core)."""
