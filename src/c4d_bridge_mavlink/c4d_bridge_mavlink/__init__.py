"""c4d_bridge_mavlink: the communication block — a MAVLink 2 ground-station bridge.

ROS-free modules hold the logic (frames, encoders, protocols, transports, telemetry
scheduler); ``bridge_node`` adapts them to ROS topics and services.
"""
