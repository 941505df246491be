"""`ros2 run c4d_gnc navigation` — state estimation (NavigationEkf) as a node.

Subscribes perception/{imu,gps,baro,mag,range_down}; each IMU sample runs one EKF prediction
and publishes navigation/state (c4d_interfaces/VehicleState, stamped with the IMU sample time,
best effort) — so the state comes at IMU rate — and navigation/odometry (nav_msgs/Odometry,
`odometry_rate_hz`, default 50 Hz to spare CPU). Validity flags follow the filter: attitude
after alignment, heading while the magnetometer is fused, position/velocity while GNSS fixes
keep coming, origin/global once home is set, terrain distance from a fresh range reading.
A missing sensor clears its flags; nothing stops. While the core reports the vehicle
disarmed (vehicle/status), zero-velocity updates at 10 Hz keep a vehicle standing without GNSS
from drifting; GNSS back after an outage resets the position if dead reckoning left the gate.
Parameters: odometry_rate_hz, mag_declination_deg, events_executor.
"""

from __future__ import annotations

import math
import sys

import numpy as np

from .ekf import EkfConfig, NavigationEkf, rotation_matrix

ZUPT_EVERY = 50  # IMU samples between zero-velocity updates (10 Hz at 500 Hz)


def main(argv: list[str] | None = None) -> int:
    from c4d_ros import node_runtime

    rclpy = node_runtime.init(argv)
    from nav_msgs.msg import Odometry
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import FluidPressure, Imu, MagneticField, NavSatFix, Range

    from c4d_interfaces.msg import VehicleState, VehicleStatus

    from .ros_conversions import stamp_to_s

    node = rclpy.create_node("navigation")
    odometry_rate = float(node.declare_parameter("odometry_rate_hz", 50.0).value)
    declination = float(node.declare_parameter("mag_declination_deg", 0.0).value)
    events = bool(node.declare_parameter("events_executor", True).value)
    if not (odometry_rate > 0 and math.isfinite(declination)):
        return node_runtime.fail("navigation", "parameter 'odometry_rate_hz' must be > 0", node)
    ekf = NavigationEkf(EkfConfig(mag_declination=math.radians(declination)))
    qos = QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
    state_qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
    pub_state = node.create_publisher(VehicleState, "navigation/state", state_qos)
    pub_odom = node.create_publisher(Odometry, "navigation/odometry", state_qos)
    memory = {"imu_count": 0, "on_ground": False,
              "imu_t": None, "mag": None, "range": (math.inf, -math.inf), "odom_t": -math.inf, "omega": np.zeros(3),
              "alpha": np.zeros(3)}

    def on_status(msg: VehicleStatus) -> None:
        memory["on_ground"] = not msg.armed

    def on_mag(msg: MagneticField) -> None:
        f = msg.magnetic_field
        memory["mag"] = (f.x, f.y, f.z)
        ekf.update_mag(memory["mag"])

    def on_gps(msg: NavSatFix) -> None:
        cov = msg.position_covariance
        sigma_h = math.sqrt(cov[0]) if cov[0] > 0 else 1.0
        sigma_v = math.sqrt(cov[8]) if cov[8] > 0 else 2.0
        age = (memory["imu_t"] or stamp_to_s(msg.header.stamp)) - stamp_to_s(msg.header.stamp)
        ekf.update_gps(msg.latitude, msg.longitude, msg.altitude, sigma_h, sigma_v, age)

    def on_baro(msg: FluidPressure) -> None:
        ekf.update_baro(msg.fluid_pressure)

    def on_range(msg: Range) -> None:
        distance = 0.0 if msg.range == -math.inf else msg.range  # −inf: closer than min range (on the ground)
        memory["range"] = (distance, stamp_to_s(msg.header.stamp))

    def on_imu(msg: Imu) -> None:
        t = stamp_to_s(msg.header.stamp)
        w, a = msg.angular_velocity, msg.linear_acceleration
        gyro, accel = (w.x, w.y, w.z), (a.x, a.y, a.z)
        last = memory["imu_t"]
        memory["imu_t"] = t
        if not ekf.aligned:
            ekf.align(accel, memory["mag"])
            return
        if last is None or not 0.0 < t - last < 0.1:
            return  # first sample after a gap: no integration over an unknown interval
        dt = t - last
        ekf.predict(gyro, accel, dt)
        memory["imu_count"] += 1
        if memory["on_ground"] and memory["imu_count"] % ZUPT_EVERY == 0:
            ekf.update_zero_velocity()  # disarmed = standing still: bounds drift while GNSS is out
        omega = np.asarray(gyro) - ekf.bg
        memory["alpha"] = 0.8 * memory["alpha"] + 0.2 * (omega - memory["omega"]) / dt
        memory["omega"] = omega
        publish(msg.header.stamp, t)

    def publish(stamp, t: float) -> None:
        s = VehicleState()
        s.header.stamp = stamp
        s.header.frame_id = "map"
        s.child_frame_id = "base_link"
        valid = VehicleState.VALID_ATTITUDE | VehicleState.VALID_ANGULAR_VELOCITY | VehicleState.VALID_ACCELERATION
        valid |= VehicleState.VALID_ANGULAR_ACCELERATION
        if ekf.heading_valid:
            valid |= VehicleState.VALID_HEADING
        if ekf.position_valid:
            valid |= (VehicleState.VALID_POSITION_XY | VehicleState.VALID_POSITION_Z | VehicleState.VALID_VELOCITY_XY
                      | VehicleState.VALID_VELOCITY_Z)
        s.position.x, s.position.y, s.position.z = (float(x) for x in ekf.p)
        s.velocity.x, s.velocity.y, s.velocity.z = (float(x) for x in ekf.v)
        s.acceleration.x, s.acceleration.y, s.acceleration.z = (float(x) for x in ekf.accel_world)
        s.orientation.w, s.orientation.x, s.orientation.y, s.orientation.z = ekf.q
        s.angular_velocity.x, s.angular_velocity.y, s.angular_velocity.z = (float(x) for x in memory["omega"])
        s.angular_acceleration.x, s.angular_acceleration.y, s.angular_acceleration.z = (float(x) for x in memory["alpha"])
        s.position_covariance = [float(x) for x in ekf.P[0:3, 0:3].ravel()]
        s.velocity_covariance = [float(x) for x in ekf.P[3:6, 3:6].ravel()]
        s.attitude_covariance = [float(x) for x in ekf.P[6:9, 6:9].ravel()]
        s.gyro_bias.x, s.gyro_bias.y, s.gyro_bias.z = (float(x) for x in ekf.bg)
        s.accel_bias.x, s.accel_bias.y, s.accel_bias.z = (float(x) for x in ekf.ba)
        distance, range_t = memory["range"]
        s.terrain_distance = float(distance) if math.isfinite(distance) and t - range_t < 0.5 else math.nan
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
        pub_state.publish(s)
        if t - memory["odom_t"] >= 1.0 / odometry_rate - 1e-6:
            memory["odom_t"] = t
            odom = Odometry()
            odom.header, odom.child_frame_id = s.header, "base_link"
            odom.pose.pose.position = s.position
            odom.pose.pose.orientation = s.orientation
            R = rotation_matrix(ekf.q)
            v_body = R.T @ ekf.v  # Odometry twist is in the child (body) frame
            odom.twist.twist.linear.x, odom.twist.twist.linear.y, odom.twist.twist.linear.z = (float(x) for x in v_body)
            odom.twist.twist.angular = s.angular_velocity
            cov = np.zeros((6, 6))
            cov[0:3, 0:3], cov[3:6, 3:6] = ekf.P[0:3, 0:3], ekf.P[6:9, 6:9]
            odom.pose.covariance = [float(x) for x in cov.ravel()]
            pub_odom.publish(odom)

    def log_status() -> None:
        node.get_logger().info(
            f"aligned {ekf.aligned}, home {'set' if ekf.origin else 'pending'}, position valid {ekf.position_valid}, "
            f"heading valid {ekf.heading_valid}, rejected {ekf.rejected}, p = {[round(float(x), 2) for x in ekf.p]}")

    node.create_timer(5.0, log_status)
    node.create_subscription(Imu, "perception/imu", on_imu, qos)
    node.create_subscription(NavSatFix, "perception/gps", on_gps, qos)
    node.create_subscription(FluidPressure, "perception/baro", on_baro, qos)
    node.create_subscription(MagneticField, "perception/mag", on_mag, qos)
    node.create_subscription(Range, "perception/range_down", on_range, qos)
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    node.create_subscription(VehicleStatus, "vehicle/status", on_status, latched)
    return node_runtime.spin_node(node, events)


if __name__ == "__main__":
    sys.exit(main())
