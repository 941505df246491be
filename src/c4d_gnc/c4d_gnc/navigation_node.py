"""`ros2 run c4d_gnc navigation` — state estimation (NavigationEkf via NavigationFilter) as a node.

Subscribes perception/{imu,gps,baro,mag,range_down}; each IMU sample runs one EKF prediction
and publishes navigation/state (c4d_interfaces/VehicleState, stamped with the IMU sample time)
— so the state comes at IMU rate — and navigation/odometry (nav_msgs/Odometry,
`odometry_rate_hz`, default 50 Hz to spare CPU) with navigation/pose (PoseStamped in `map`, for
external nodes) and, where tf2_msgs is installed, TF map → base_link on /tf at the same rate
(not there: one info line, no TF). Validity flags follow the filter: attitude
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
from collections.abc import Callable

import numpy as np
from geometry_msgs.msg import PoseStamped, TransformStamped, Vector3
from nav_msgs.msg import Odometry
from sensor_msgs.msg import FluidPressure, Imu, MagneticField, NavSatFix, Range

from c4d_interfaces.msg import VehicleState, VehicleStatus
from c4d_ros import cdr, gc_policy, node_runtime
from c4d_ros.component import ComponentError, Host, SpunNode, run_components
from c4d_ros.manifest import NAV_ODOMETRY, NAV_POSE, NAV_STATE, P_BARO, P_GPS, P_IMU, P_MAG, P_RANGE_DOWN, STATUS
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
MAP_FRAME, BASE_LINK = cdr.text("map"), cdr.text("base_link")
STATE_FRAMES = (MAP_FRAME[0], BASE_LINK[0])  # the string lengths of navigation/state's CDR layout
POSITION_VALID = (VehicleState.VALID_POSITION_XY | VehicleState.VALID_POSITION_Z | VehicleState.VALID_VELOCITY_XY
                  | VehicleState.VALID_VELOCITY_Z)


def tf_sender(node) -> Callable[[Odometry], None] | None:
    """Publishes an odometry's pose as TF map → base_link on /tf (tf2_msgs/TFMessage, depth 100 as
    tf2_ros' TransformBroadcaster); None, with one info line, where tf2_msgs is not installed
    (the PyPI wheels do not carry it)."""
    try:
        from tf2_msgs.msg import TFMessage
    except ImportError:
        node.get_logger().info("tf2_msgs not installed: no TF map -> base_link (navigation/pose and "
                               "navigation/odometry carry the same pose)")
        return None
    publisher = node.create_publisher(TFMessage, "/tf", 100)

    def send(odometry: Odometry) -> None:
        p, transform = odometry.pose.pose.position, TransformStamped(header=odometry.header,
                                                                     child_frame_id=odometry.child_frame_id)
        transform.transform.translation = Vector3(x=p.x, y=p.y, z=p.z)
        transform.transform.rotation = odometry.pose.pose.orientation
        publisher.publish(TFMessage(transforms=[transform]))
    return send


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
        self.pub_pose = node.create_publisher(PoseStamped, NAV_POSE.name, NAV_POSE.qos)
        self.send_tf = tf_sender(node)
        node.create_timer(LOG_PERIOD_S, self.log_status)
        gc_policy.install(node)  # 500 Hz callbacks: no automatic full collection (c4d_ros.gc_policy)
        node.create_subscription(Imu, P_IMU.name, self.on_imu, P_IMU.qos, raw=True)  # 500 Hz: serialized (c4d_ros.cdr)
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

    def on_imu(self, raw: bytes) -> None:
        v = cdr.IMU.unpack(raw, Imu)
        sec, nanosec = v[1], v[2]
        t = sec + nanosec * 1e-9
        if self.filter.imu(t, v[cdr.IMU_GYRO], v[cdr.IMU_ACCEL]):
            self.pub_state.publish(self.state_cdr(sec, nanosec, t))
            if t - self.odometry_t >= self.odometry_period:
                self.odometry_t = t
                odometry = self.odometry_msg(sec, nanosec)
                self.pub_odometry.publish(odometry)
                self.pub_pose.publish(PoseStamped(header=odometry.header, pose=odometry.pose.pose))
                if self.send_tf is not None:
                    self.send_tf(odometry)

    def state_cdr(self, sec: int, nanosec: int, t: float) -> bytes:
        """navigation/state stamped with the IMU sample time, written straight to CDR (c4d_ros.cdr:
        ~40 µs less per sample than filling a VehicleState message and serializing it)."""
        ekf, filt = self.ekf, self.filter
        valid = ALWAYS_VALID
        if ekf.heading_valid:
            valid |= VehicleState.VALID_HEADING
        if ekf.position_valid:
            valid |= POSITION_VALID
        terrain = filt.terrain_distance(t)
        if not math.isnan(terrain):
            valid |= VehicleState.VALID_TERRAIN_DISTANCE
        origin = geodetic = (0.0, 0.0, 0.0)
        if ekf.origin is not None:
            valid |= VehicleState.VALID_ORIGIN
            o = ekf.origin
            origin = (o.latitude, o.longitude, o.altitude)
            if ekf.position_valid:
                valid |= VehicleState.VALID_GLOBAL
                geodetic = o.to_geodetic(*ekf.p)
        P = ekf.P
        qw, qx, qy, qz = ekf.q
        return cdr.VEHICLE_STATE.pack(
            STATE_FRAMES, sec, nanosec, *MAP_FRAME, *BASE_LINK, valid, *ekf.p.tolist(), *ekf.v.tolist(),
            *ekf.accel_world.tolist(), qx, qy, qz, qw, *filt.omega.tolist(), *filt.alpha.tolist(),
            *P[0:3, 0:3].ravel().tolist(), *P[3:6, 3:6].ravel().tolist(), *P[6:9, 6:9].ravel().tolist(),
            *ekf.bg.tolist(), *ekf.ba.tolist(), terrain, *origin, *geodetic,
            VehicleState.SOURCE_GNSS if ekf.position_valid else VehicleState.SOURCE_NONE, VehicleState.SOURCE_BARO)

    def odometry_msg(self, sec: int, nanosec: int) -> Odometry:
        ekf, odom = self.ekf, Odometry()
        odom.header.stamp.sec, odom.header.stamp.nanosec = sec, nanosec
        odom.header.frame_id, odom.child_frame_id = "map", "base_link"
        p, o = odom.pose.pose.position, odom.pose.pose.orientation
        p.x, p.y, p.z = ekf.p.tolist()
        o.w, o.x, o.y, o.z = ekf.q
        v_body = rotation_matrix(ekf.q).T @ ekf.v  # Odometry twist is in the child (body) frame
        odom.twist.twist.linear.x, odom.twist.twist.linear.y, odom.twist.twist.linear.z = v_body.tolist()
        odom.twist.twist.angular.x, odom.twist.twist.angular.y, odom.twist.twist.angular.z = self.filter.omega.tolist()
        cov = np.zeros((6, 6))
        cov[0:3, 0:3], cov[3:6, 3:6] = ekf.P[0:3, 0:3], ekf.P[6:9, 6:9]
        odom.pose.covariance = cov.ravel().tolist()
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

