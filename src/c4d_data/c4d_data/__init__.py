"""c4d data management: flight recorder (rosbag2 MCAP), replay, repair, flight analysis."""
