"""c4d_common — shared ROS-free code: geodesy, quaternions, airframes, vehicle enums, plan model and geofence."""
