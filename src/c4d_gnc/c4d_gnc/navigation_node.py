"""`ros2 run c4d_gnc navigation` — state estimation (NavigationEkf via NavigationFilter) as a node.

Subscribes perception/{imu,gps,baro,mag,range_down}; each IMU sample runs one EKF prediction
and publishes navigation/state (c4d_interfaces/VehicleState, stamped with the IMU sample time)
— so the state comes at IMU rate — and navigation/odometry (nav_msgs/Odometry,
`odometry_rate_hz`, default 50 Hz to spare CPU). Validity flags follow the filter: attitude
after alignment, heading while the magnetometer is fused, position/velocity while GNSS fixes
keep coming, origin/global once home is set, terrain distance from a fresh range reading.
A missing sensor clears its flags; nothing stops. While the core reports the vehicle
disarmed (vehicle/status), zero-velocity updates at 10 Hz keep a vehicle standing without GNSS
from drifting; GNSS back after an outage resets the position if dead reckoning left the gate.
Topic names and QoS: c4d_ros.manifest. Parameters: PARAMS below (all read-only).
"""

from __future__ import annotations

import math
import sys

import numpy as np
from nav_msgs.msg import Odometry
from sensor_msgs.msg import FluidPressure, Imu, MagneticField, NavSatFix, Range

from c4d_interfaces.msg import VehicleState, VehicleStatus
from c4d_ros import node_runtime
from c4d_ros.component import ComponentError, Host, SpunNode, run_components
from c4d_ros.manifest import NAV_ODOMETRY, NAV_STATE, P_BARO, P_GPS, P_IMU, P_MAG, P_RANGE_DOWN, STATUS
from c4d_ros.params import ParameterError, Spec, declare_all
from c4d_ros.stamps import stamp_to_s

from .ekf import EkfConfig, NavigationEkf, rotation_matrix
from .navigation_filter import NavigationFilter

NAME = "navigation"
PARAMS = {
    "odometry_rate_hz": Spec(50.0, "navigation/odometry publication rate [Hz]", 0.01, 1000.0, read_only=True),
    "mag_declination_deg": Spec(0.0, "magnetic declination, east positive [deg]", -180.0, 180.0, read_only=True),
    "rt_priority": node_runtime.RT_PRIORITY,
    "events_executor": Spec(True, "spin with rclpy's EventsExecutor (less CPU) instead of the default executor [bool]",
                            read_only=True),
}
LOG_PERIOD_S = 5.0
ALWAYS_VALID = (VehicleState.VALID_ATTITUDE | VehicleState.VALID_ANGULAR_VELOCITY | VehicleState.VALID_ACCELERATION
                | VehicleState.VALID_ANGULAR_ACCELERATION)
POSITION_VALID = (VehicleState.VALID_POSITION_XY | VehicleState.VALID_POSITION_Z | VehicleState.VALID_VELOCITY_XY
                  | VehicleState.VALID_VELOCITY_Z)


class NavigationNode:
    """Maps the perception topics onto NavigationFilter and publishes its estimate."""

    def __init__(self, node, odometry_rate_hz: float, mag_declination_deg: float) -> None:
        self.node = node
        self.filter = NavigationFilter(NavigationEkf(EkfConfig(mag_declination=math.radians(mag_declination_deg))))
        self.ekf = self.filter.ekf
        self.odometry_period = 1.0 / odometry_rate_hz - 1e-6
        self.odometry_t = -math.inf
        self.pub_state = node.create_publisher(VehicleState, NAV_STATE.name, NAV_STATE.qos)
        self.pub_odometry = node.create_publisher(Odometry, NAV_ODOMETRY.name, NAV_ODOMETRY.qos)
        node.create_timer(LOG_PERIOD_S, self.log_status)
        node.create_subscription(Imu, P_IMU.name, self.on_imu, P_IMU.qos)
        node.create_subscription(NavSatFix, P_GPS.name, self.on_gps, P_GPS.qos)
        node.create_subscription(FluidPressure, P_BARO.name, self.on_baro, P_BARO.qos)
        node.create_subscription(MagneticField, P_MAG.name, self.on_mag, P_MAG.qos)
        node.create_subscription(Range, P_RANGE_DOWN.name, self.on_range, P_RANGE_DOWN.qos)
        node.create_subscription(VehicleStatus, STATUS.name, self.on_status, STATUS.qos)

    def on_status(self, msg: VehicleStatus) -> None:
        self.filter.on_ground = not msg.armed

    def on_mag(self, msg: MagneticField) -> None:
        f = msg.magnetic_field
        self.filter.magnetometer((f.x, f.y, f.z))

    def on_gps(self, msg: NavSatFix) -> None:
        cov = msg.position_covariance
        self.filter.gnss(msg.latitude, msg.longitude, msg.altitude, cov[0], cov[8], stamp_to_s(msg.header.stamp))

    def on_baro(self, msg: FluidPressure) -> None:
        self.ekf.update_baro(msg.fluid_pressure)

    def on_range(self, msg: Range) -> None:
        self.filter.range_down(msg.range, stamp_to_s(msg.header.stamp))

    def on_imu(self, msg: Imu) -> None:
        t = stamp_to_s(msg.header.stamp)
        w, a = msg.angular_velocity, msg.linear_acceleration
        if self.filter.imu(t, (w.x, w.y, w.z), (a.x, a.y, a.z)):
            state = self.state_msg(msg.header.stamp, t)
            self.pub_state.publish(state)
            if t - self.odometry_t >= self.odometry_period:
                self.odometry_t = t
                self.pub_odometry.publish(self.odometry_msg(state))

    def state_msg(self, stamp, t: float) -> VehicleState:
        ekf, s = self.ekf, VehicleState()
        s.header.stamp = stamp
        s.header.frame_id = "map"
        s.child_frame_id = "base_link"
        valid = ALWAYS_VALID
        if ekf.heading_valid:
            valid |= VehicleState.VALID_HEADING
        if ekf.position_valid:
            valid |= POSITION_VALID
        s.position.x, s.position.y, s.position.z = (float(x) for x in ekf.p)
        s.velocity.x, s.velocity.y, s.velocity.z = (float(x) for x in ekf.v)
        s.acceleration.x, s.acceleration.y, s.acceleration.z = (float(x) for x in ekf.accel_world)
        s.orientation.w, s.orientation.x, s.orientation.y, s.orientation.z = ekf.q
        s.angular_velocity.x, s.angular_velocity.y, s.angular_velocity.z = (float(x) for x in self.filter.omega)
        s.angular_acceleration.x, s.angular_acceleration.y, s.angular_acceleration.z = (float(x) for x in self.filter.alpha)
        s.position_covariance = [float(x) for x in ekf.P[0:3, 0:3].ravel()]
        s.velocity_covariance = [float(x) for x in ekf.P[3:6, 3:6].ravel()]
        s.attitude_covariance = [float(x) for x in ekf.P[6:9, 6:9].ravel()]
        s.gyro_bias.x, s.gyro_bias.y, s.gyro_bias.z = (float(x) for x in ekf.bg)
        s.accel_bias.x, s.accel_bias.y, s.accel_bias.z = (float(x) for x in ekf.ba)
        s.terrain_distance = self.filter.terrain_distance(t)
        if not math.isnan(s.terrain_distance):
            valid |= VehicleState.VALID_TERRAIN_DISTANCE
        if ekf.origin is not None:
            valid |= VehicleState.VALID_ORIGIN
            o = ekf.origin
            s.origin.latitude, s.origin.longitude, s.origin.altitude = o.latitude, o.longitude, o.altitude
            if ekf.position_valid:
                valid |= VehicleState.VALID_GLOBAL
                s.geodetic.latitude, s.geodetic.longitude, s.geodetic.altitude = o.to_geodetic(*ekf.p)
        s.valid = valid
        return s

    def odometry_msg(self, s: VehicleState) -> Odometry:
        ekf, odom = self.ekf, Odometry()
        odom.header, odom.child_frame_id = s.header, "base_link"
        odom.pose.pose.position = s.position
        odom.pose.pose.orientation = s.orientation
        v_body = rotation_matrix(ekf.q).T @ ekf.v  # Odometry twist is in the child (body) frame
        odom.twist.twist.linear.x, odom.twist.twist.linear.y, odom.twist.twist.linear.z = (float(x) for x in v_body)
        odom.twist.twist.angular = s.angular_velocity
        cov = np.zeros((6, 6))
        cov[0:3, 0:3], cov[3:6, 3:6] = ekf.P[0:3, 0:3], ekf.P[6:9, 6:9]
        odom.pose.covariance = [float(x) for x in cov.ravel()]
        return odom

    def log_status(self) -> None:
        ekf = self.ekf
        self.node.get_logger().info(
            f"aligned {ekf.aligned}, home {'set' if ekf.origin else 'pending'}, position valid {ekf.position_valid}, "
            f"heading valid {ekf.heading_valid}, rejected {ekf.rejected}, p = {[round(float(x), 2) for x in ekf.p]}")


def component(rclpy, host: Host) -> SpunNode:
    """The navigation node as a component (c4d_ros.component): alone or composed with others."""
    node = rclpy.create_node(NAME)
    try:
        params = declare_all(node, PARAMS)
    except ParameterError as exc:
        node.destroy_node()
        raise ComponentError(str(exc)) from None
    owner = NavigationNode(node, params["odometry_rate_hz"], params["mag_declination_deg"])
    return SpunNode(NAME, node, bool(params["events_executor"]), params["rt_priority"], owner)


def main(argv: list[str] | None = None) -> int:
    return run_components([(NAME, component)], argv, NAME, composed=False)


if __name__ == "__main__":
    sys.exit(main())

