"""c4d_offboard: the public API for external nodes — offboard setpoint gateway and action servers."""
