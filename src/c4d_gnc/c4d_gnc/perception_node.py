"""`ros2 run c4d_gnc perception` — sensor conditioning and sensor health.

Subscribes sensors/{imu,gps,baro,mag,range_down} (sensor_msgs, best effort), rejects and
counts NaN / out-of-range samples (they are never republished), applies the IMU calibration,
and republishes each accepted sample unchanged in time on perception/{imu,gps,baro,mag,
range_down}. Publishes perception/health (diagnostic_msgs/DiagnosticArray, 5 Hz): one status
per sensor with its state (ok, stale, frozen, invalid, low rate), measured rate, counts, age.
Parameters: gyro_offset, accel_offset, accel_scale (calibration, 3 values each),
events_executor (default true).
"""

from __future__ import annotations

import math
import sys

from .perception import Health, ImuCalibration, SensorMonitor, valid_fix, valid_imu, valid_mag, valid_pressure, valid_range

SENSORS = {  # name: (expected rate Hz, timeout s)
    "imu": (500.0, 0.05),
    "gps": (10.0, 1.0),
    "baro": (50.0, 0.5),
    "mag": (50.0, 0.5),
    "range_down": (50.0, 0.5),
}


def main(argv: list[str] | None = None) -> int:
    from c4d_ros import node_runtime

    rclpy = node_runtime.init(argv)
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import FluidPressure, Imu, MagneticField, NavSatFix, NavSatStatus, Range

    node = rclpy.create_node("perception")
    try:
        def vec3(name, default):
            value = list(node.declare_parameter(name, default).value)
            if len(value) != 3:
                raise ValueError(f"parameter '{name}' needs 3 values")
            return tuple(float(v) for v in value)

        calibration = ImuCalibration(vec3("gyro_offset", [0.0, 0.0, 0.0]), vec3("accel_offset", [0.0, 0.0, 0.0]),
                                     vec3("accel_scale", [1.0, 1.0, 1.0]))
        events = bool(node.declare_parameter("events_executor", True).value)
    except ValueError as exc:
        return node_runtime.fail("perception", str(exc), node)

    qos = QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
    monitors = {name: SensorMonitor(name, rate, timeout) for name, (rate, timeout) in SENSORS.items()}
    pubs = {
        "imu": node.create_publisher(Imu, "perception/imu", qos),
        "gps": node.create_publisher(NavSatFix, "perception/gps", qos),
        "baro": node.create_publisher(FluidPressure, "perception/baro", qos),
        "mag": node.create_publisher(MagneticField, "perception/mag", qos),
        "range_down": node.create_publisher(Range, "perception/range_down", qos),
    }
    pub_health = node.create_publisher(DiagnosticArray, "perception/health", 10)

    def now() -> float:
        return node.get_clock().now().nanoseconds * 1e-9

    def on_imu(msg: Imu) -> None:
        w, a = msg.angular_velocity, msg.linear_acceleration
        gyro, accel = (w.x, w.y, w.z), (a.x, a.y, a.z)
        if monitors["imu"].accept(now(), gyro + accel, valid_imu(gyro, accel)):
            gyro, accel = calibration.apply(gyro, accel)
            msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = gyro
            msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z = accel
            pubs["imu"].publish(msg)

    def on_gps(msg: NavSatFix) -> None:
        ok = valid_fix(msg.latitude, msg.longitude, msg.altitude, msg.status.status >= NavSatStatus.STATUS_FIX)
        if monitors["gps"].accept(now(), (msg.latitude, msg.longitude, msg.altitude), ok):
            pubs["gps"].publish(msg)

    def on_baro(msg: FluidPressure) -> None:
        if monitors["baro"].accept(now(), (msg.fluid_pressure,), valid_pressure(msg.fluid_pressure)):
            pubs["baro"].publish(msg)

    def on_mag(msg: MagneticField) -> None:
        f = msg.magnetic_field
        values = (f.x, f.y, f.z)
        if monitors["mag"].accept(now(), values, valid_mag(values)):
            pubs["mag"].publish(msg)

    def on_range(msg: Range) -> None:
        if monitors["range_down"].accept(now(), (msg.range,), valid_range(msg.range), can_freeze=math.isfinite(msg.range)):
            pubs["range_down"].publish(msg)

    node.create_subscription(Imu, "sensors/imu", on_imu, qos)
    node.create_subscription(NavSatFix, "sensors/gps", on_gps, qos)
    node.create_subscription(FluidPressure, "sensors/baro", on_baro, qos)
    node.create_subscription(MagneticField, "sensors/mag", on_mag, qos)
    node.create_subscription(Range, "sensors/range_down", on_range, qos)

    levels = {Health.OK: DiagnosticStatus.OK, Health.LOW_RATE: DiagnosticStatus.WARN,
              Health.WAITING: DiagnosticStatus.STALE, Health.STALE: DiagnosticStatus.STALE,
              Health.FROZEN: DiagnosticStatus.ERROR, Health.INVALID: DiagnosticStatus.ERROR}

    def publish_health() -> None:
        t = now()
        array = DiagnosticArray()
        array.header.stamp = node.get_clock().now().to_msg()
        for name, m in monitors.items():
            state = m.health(t)
            status = DiagnosticStatus(level=levels[state], name=f"perception/{name}", message=state.value,
                                      hardware_id=name)
            age = t - m.last_time if m.accepted else -1.0
            status.values = [KeyValue(key="state", value=state.name), KeyValue(key="rate_hz", value=f"{m.rate():.1f}"),
                             KeyValue(key="accepted", value=str(m.accepted)), KeyValue(key="rejected", value=str(m.rejected)),
                             KeyValue(key="age_s", value=f"{age:.3f}")]
            array.status.append(status)
        pub_health.publish(array)

    node.create_timer(0.2, publish_health)  # 5 Hz: also the heartbeat health watches
    return node_runtime.spin_node(node, events)


if __name__ == "__main__":
    sys.exit(main())
