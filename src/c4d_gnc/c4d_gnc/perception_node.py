"""`ros2 run c4d_gnc perception` — sensor conditioning and sensor health.

Subscribes sensors/{imu,gps,baro,mag,range_down} (sensor_msgs, best effort), rejects and
counts NaN / out-of-range samples (they are never republished), applies the IMU calibration,
and republishes each accepted sample unchanged in time on perception/{imu,gps,baro,mag,
range_down}. Publishes perception/health (diagnostic_msgs/DiagnosticArray, 5 Hz): one status
per sensor with its state (ok, stale, frozen, invalid, low rate), measured rate, counts, age.
Topic names and QoS: c4d_ros.manifest. Parameters: PARAMS below (all read-only).
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from sensor_msgs.msg import FluidPressure, Imu, MagneticField, NavSatFix, NavSatStatus, Range

from c4d_ros import cdr, gc_policy, lifecycle, node_runtime
from c4d_ros.component import ComponentError, Host, SpunNode, run_components
from c4d_ros.manifest import (
    BARO,
    GPS,
    IMU,
    MAG,
    P_BARO,
    P_GPS,
    P_HEALTH,
    P_IMU,
    P_MAG,
    P_RANGE_DOWN,
    RANGE_DOWN,
    Topic,
    side_node_name,
)
from c4d_ros.params import ParameterError, Spec, declare_all

from . import perception_surroundings as surroundings
from .perception import Health, ImuCalibration, SensorMonitor, valid_fix, valid_imu, valid_mag, valid_pressure, valid_range

NAME = "perception"
PARAMS = {
    "gyro_offset": Spec([0.0, 0.0, 0.0], "gyro bias removed from each sample, x y z [rad/s]", read_only=True),
    "accel_offset": Spec([0.0, 0.0, 0.0], "accelerometer bias removed from each sample, x y z [m/s²]", read_only=True),
    "accel_scale": Spec([1.0, 1.0, 1.0], "accelerometer scale factors applied after the bias, x y z [-]", read_only=True),
    "rt_priority": node_runtime.RT_PRIORITY,
    "events_executor": Spec(True, "spin with rclpy's EventsExecutor (less CPU) instead of the default executor [bool]",
                            read_only=True),
    **surroundings.PARAMS,
}
HEALTH_PERIOD_S = 0.2  # 5 Hz: also the heartbeat health watches
LEVELS = {Health.OK: DiagnosticStatus.OK, Health.LOW_RATE: DiagnosticStatus.WARN,
          Health.WAITING: DiagnosticStatus.STALE, Health.STALE: DiagnosticStatus.STALE,
          Health.FROZEN: DiagnosticStatus.ERROR, Health.INVALID: DiagnosticStatus.ERROR}


@dataclass(frozen=True)
class Stream:
    """One sensor stream: raw topic in, conditioned topic out, expected rate and silence timeout."""

    name: str
    raw: Topic
    conditioned: Topic
    msg_type: type
    rate_hz: float
    timeout_s: float


STREAMS = (
    Stream("imu", IMU, P_IMU, Imu, 500.0, 0.05),
    Stream("gps", GPS, P_GPS, NavSatFix, 10.0, 1.0),
    Stream("baro", BARO, P_BARO, FluidPressure, 50.0, 0.5),
    Stream("mag", MAG, P_MAG, MagneticField, 50.0, 0.5),
    Stream("range_down", RANGE_DOWN, P_RANGE_DOWN, Range, 50.0, 0.5),
)


def calibration_from(params: dict[str, object]) -> ImuCalibration:
    """The IMU calibration of the three vector parameters; ParameterError unless each has 3 values."""
    vectors = []
    for name in ("gyro_offset", "accel_offset", "accel_scale"):
        value = list(params[name])  # type: ignore[call-overload]
        if len(value) != 3:
            raise ParameterError(f"parameter '{name}' needs 3 values")
        vectors.append(tuple(float(v) for v in value))
    return ImuCalibration(*vectors)


class PerceptionNode:
    """Maps each raw sensor topic through its SensorMonitor onto the conditioned topic and
    publishes the monitors' health."""

    def __init__(self, node, calibration: ImuCalibration) -> None:
        self.node, self.calibration, self.clock = node, calibration, node.get_clock()
        self.monitors = {s.name: SensorMonitor(s.name, s.rate_hz, s.timeout_s) for s in STREAMS}
        self.pubs = {s.name: node.create_publisher(s.msg_type, s.conditioned.name, s.conditioned.qos) for s in STREAMS}
        self.pub_health = node.create_publisher(DiagnosticArray, P_HEALTH.name, P_HEALTH.qos)
        handlers = {"imu": self.on_imu, "gps": self.on_gps, "baro": self.on_baro, "mag": self.on_mag,
                    "range_down": self.on_range}
        for s in STREAMS:  # the IMU (500 Hz) is taken and republished serialized (c4d_ros.cdr)
            node.create_subscription(s.msg_type, s.raw.name, handlers[s.name], s.raw.qos, raw=s.name == "imu")
        node.create_timer(HEALTH_PERIOD_S, self.publish_health)
        gc_policy.install(node)  # 500 Hz callbacks: no automatic full collection (c4d_ros.gc_policy)

    def now(self) -> float:
        return self.clock.now().nanoseconds * 1e-9

    def on_imu(self, raw: bytes) -> None:
        """Validate, calibrate and forward one serialized Imu: the bytes as they came when the
        calibration is the identity, else repacked with the calibrated vectors."""
        v = cdr.IMU.unpack(raw, Imu)
        gyro, accel = v[cdr.IMU_GYRO], v[cdr.IMU_ACCEL]
        if self.monitors["imu"].accept(self.now(), gyro + accel, valid_imu(gyro, accel)):
            if self.calibration.identity and v[0] == cdr.CDR_LE:
                self.pubs["imu"].publish(bytes(raw))
                return
            values = list(v)
            values[cdr.IMU_GYRO], values[cdr.IMU_ACCEL] = self.calibration.apply(gyro, accel)
            self.pubs["imu"].publish(cdr.IMU.pack((values[3],), *values[1:]))

    def on_gps(self, msg: NavSatFix) -> None:
        ok = valid_fix(msg.latitude, msg.longitude, msg.altitude, msg.status.status >= NavSatStatus.STATUS_FIX)
        if self.monitors["gps"].accept(self.now(), (msg.latitude, msg.longitude, msg.altitude), ok):
            self.pubs["gps"].publish(msg)

    def on_baro(self, msg: FluidPressure) -> None:
        if self.monitors["baro"].accept(self.now(), (msg.fluid_pressure,), valid_pressure(msg.fluid_pressure)):
            self.pubs["baro"].publish(msg)

    def on_mag(self, msg: MagneticField) -> None:
        f = msg.magnetic_field
        values = (f.x, f.y, f.z)
        if self.monitors["mag"].accept(self.now(), values, valid_mag(values)):
            self.pubs["mag"].publish(msg)

    def on_range(self, msg: Range) -> None:
        finite = math.isfinite(msg.range)
        if self.monitors["range_down"].accept(self.now(), (msg.range,), valid_range(msg.range), can_freeze=finite):
            self.pubs["range_down"].publish(msg)

    def publish_health(self) -> None:
        stamp = self.clock.now()
        t = stamp.nanoseconds * 1e-9
        array = DiagnosticArray()
        array.header.stamp = stamp.to_msg()
        for name, m in self.monitors.items():
            state = m.health(t)
            status = DiagnosticStatus(level=LEVELS[state], name=f"perception/{name}", message=state.value, hardware_id=name)
            age = t - m.last_time if m.accepted else -1.0
            status.values = [KeyValue(key="state", value=state.name), KeyValue(key="rate_hz", value=f"{m.rate():.1f}"),
                             KeyValue(key="accepted", value=str(m.accepted)), KeyValue(key="rejected", value=str(m.rejected)),
                             KeyValue(key="age_s", value=f"{age:.3f}")]
            array.status.append(status)
        self.pub_health.publish(array)


def component(rclpy, host: Host) -> lifecycle.ManagedComponent:
    """The perception node as a component (c4d_ros.component): alone or composed with others."""
    node = lifecycle.create_node(rclpy, NAME)
    try:
        params = declare_all(node, PARAMS)
    except ParameterError as exc:
        node.destroy_node()
        raise ComponentError(str(exc)) from None

    def build() -> SpunNode:  # configure (c4d_ros.lifecycle): calibration and airframe checked, entities created
        try:
            calibration = calibration_from(params)
            airframe = surroundings.airframe_of(str(params["airframe"]))
        except ParameterError as exc:
            raise ComponentError(str(exc)) from None
        side = rclpy.create_node(side_node_name(NAME))  # navigation/state sampled, never spun (c4d_ros.drain.LatestSampler)
        try:
            around = surroundings.SurroundingsNode(node, side, params, airframe)
        except ParameterError as exc:
            side.destroy_node()
            raise ComponentError(str(exc)) from None
        return SpunNode(NAME, node, bool(params["events_executor"]), params["rt_priority"],
                        (PerceptionNode(node, calibration), around), (side,))
    return lifecycle.ManagedComponent(NAME, node, build, events_executor=bool(params["events_executor"]),
                                      rt_priority=params["rt_priority"])


def main(argv: list[str] | None = None) -> int:
    return run_components([(NAME, component)], argv, NAME, composed=False)


if __name__ == "__main__":
    sys.exit(main())
