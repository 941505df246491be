"""c4d_client — fly a c4d vehicle from a Python script.

    from c4d_client import Vehicle

    with Vehicle() as v:                 # joins the graph of ROS_DOMAIN_ID (or Vehicle(domain_id=...))
        v.arm()
        v.takeoff(5)                     # [m above home]; blocks until the core holds there
        v.goto(10, 0, 5)                 # map ENU [m]: x east, y north, z up; OFFBOARD, then hold
        v.follow_path([(10, 10, 5), (0, 10, 5)], speed=3)
        with v.offboard() as ob:         # stream at 50 Hz from a thread; OFFBOARD after 1.1 s
            ob.set_velocity(1.0, 0.0, 0.0)
            time.sleep(3)
            ob.set_position(0, 0, 5, yaw=0.0)
            time.sleep(5)
        v.land()                         # blocks until disarmed on the ground
        print(v.status.flight_mode, v.state.position)

What it uses: vehicle/command (arm, disarm, hold, set mode), the offboard node's actions
offboard/takeoff, offboard/land, offboard/goto, offboard/follow_path, vehicle/status,
navigation/state and offboard/trajectory_setpoint (docs/offboard.md). It imports only rclpy,
c4d_interfaces and standard messages (test/test_architecture.py keeps it so), so a script needs
nothing else of c4d. A Vehicle owns its own rclpy context, node and executor thread: it does not
touch the script's own rclpy use; `close()` (or the `with` block) ends them.

Every blocking call has a timeout and raises a typed `VehicleError` carrying the vehicle's
one-line reason: `CommandRefused` (vehicle/command said no: `.result`, `.reason`),
`GoalRejected` (an action goal refused up front: not flying, outside the geofence, another goal
running — the reason is read from the offboard node's log), `ActionFailed` (an accepted goal
aborted), `VehicleTimeout` (the goal is cancelled first: the vehicle holds), `NotConnected`.
Ctrl-C during an action cancels the goal before the exception propagates.
"""

from .errors import ActionFailed, CommandRefused, GoalRejected, NotConnected, VehicleError, VehicleTimeout
from .offboard import OffboardStream, setpoint
from .vehicle import Vehicle, make_path

__all__ = ["ActionFailed", "CommandRefused", "GoalRejected", "NotConnected", "OffboardStream", "Vehicle", "VehicleError",
           "VehicleTimeout", "make_path", "setpoint"]
