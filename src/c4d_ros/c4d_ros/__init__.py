"""c4d_ros — shared ROS helpers: run loop, drains, QoS presets, interface manifest, stamps, plan messages."""
