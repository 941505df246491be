"""c4d_gnc — the GNC core: cascaded multirotor controller (ROS-free) and the `core` node."""
