"""Synthetic survey flights written with the project's MCAP writer, for catalog tests and the
scale benchmark: `python -m c4d_data.catalog_synthetic OUT_DIR -n 200 [--duration 4] [--bulk]`.

Why: a fleet catalog is tested on hundreds of flights and benchmarked on a thousand; flying them
in SITL would take hours. These files are real c4d recordings as far as every reader is
concerned — the same topics, message types (the installed c4d_interfaces/sensor_msgs classes,
serialized with rclpy), schemas, rosbag2 metadata and BagWriter as the recorder — but the
vehicle is a kinematic model: take-off, a lawn-mower survey, land, with a seeded tracking lag,
noise, battery drain (rising with `wear`, so a fleet shows an energy-per-km trend), executive
statistics, captures and, in some flights, an RTL failsafe. `bulk` adds the IMU topics at the
state rate and fills the estimate's covariances (random samples, so they compress like real
ones): files then have ~75 % of the size of a real SITL recording of that length (0.23 vs 0.3
MB/s at 500 Hz), with the topics the catalog decodes at their real rates.
"""

from __future__ import annotations

import argparse
import math
import random
import sys
from dataclasses import dataclass
from pathlib import Path

from .bag_writer import BagWriter
from .msgdef import DefinitionCache

TOPICS = {  # topic: type
    "/navigation/state": "c4d_interfaces/msg/VehicleState",
    "/guidance/setpoint": "c4d_interfaces/msg/GuidanceSetpoint",
    "/control/actuators": "c4d_interfaces/msg/ActuatorCommand",
    "/vehicle/status": "c4d_interfaces/msg/VehicleStatus",
    "/sensors/battery": "sensor_msgs/msg/BatteryState",
    "/gnc/executor_stats": "c4d_interfaces/msg/ExecutorStats",
    "/payload/captures": "c4d_interfaces/msg/CaptureEvent",
}
BULK = {"/sensors/imu": "sensor_msgs/msg/Imu", "/perception/imu": "sensor_msgs/msg/Imu"}
QOS = [{"history": 3, "depth": 0, "reliability": 1, "durability": 2, "deadline": {"sec": 9223372036, "nsec": 854775807},
        "lifespan": {"sec": 9223372036, "nsec": 854775807}, "liveliness": 1,
        "liveliness_lease_duration": {"sec": 9223372036, "nsec": 854775807}, "avoid_ros_namespace_conventions": False}]


@dataclass
class FlightSpec:
    """What one synthetic flight looks like."""

    vehicle: str = "synth-1"
    airframe: str = "quad_x"
    seed: int = 0
    start_ns: int = 1_790_000_000 * 10**9
    duration_s: float = 4.0
    state_hz: float = 50.0
    altitude_m: float = 10.0
    speed_m_s: float = 5.0
    wear: float = 0.0  # 0 = new pack; energy per km grows with it
    failsafe_at_s: float | None = None  # RTL from then on
    bulk: bool = False


class _Clock:
    """Sim-time stamps for headers (builtin_interfaces/Time)."""

    def __init__(self, start_ns: int) -> None:
        self.start_ns = start_ns

    def ns(self, t: float) -> int:
        return self.start_ns + int(round(t * 1e9))


def _position(spec: FlightSpec, t: float) -> tuple[float, float, float]:
    """Kinematic survey: climb, lawn-mower legs of 40 m spaced 10 m, descend in the last 15 %."""
    climb = min(1.0, t / max(0.15 * spec.duration_s, 1e-3))
    land = min(1.0, max(0.0, (spec.duration_s - t) / max(0.15 * spec.duration_s, 1e-3)))
    z = spec.altitude_m * min(climb, land)
    s = spec.speed_m_s * max(0.0, t - 0.15 * spec.duration_s) if t < 0.85 * spec.duration_s else \
        spec.speed_m_s * 0.7 * spec.duration_s
    leg, along = divmod(s, 50.0)
    x = min(along, 40.0) if int(leg) % 2 == 0 else 40.0 - min(along, 40.0)
    y = 10.0 * leg + max(0.0, along - 40.0)
    return x, y, z


def write_flight(path: str | Path, spec: FlightSpec) -> Path:
    """Write one synthetic flight to `path` (must not exist); returns the path."""
    from builtin_interfaces.msg import Time
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import BatteryState, Imu

    from c4d_interfaces.msg import ActuatorCommand, CaptureEvent, ExecutorStats, GuidanceSetpoint, VehicleState, VehicleStatus

    rng = random.Random(spec.seed)
    clock = _Clock(spec.start_ns)
    definitions = DefinitionCache()
    writer = BagWriter(path, custom_data={"c4d.start_reason": "armed", "c4d.vehicle": spec.vehicle,
                                          "c4d.airframe": spec.airframe, "c4d.synthetic": "1"})
    topics = dict(TOPICS, **(BULK if spec.bulk else {}))
    for name, type_name in topics.items():
        writer.add_topic(name, type_name, definitions.get(type_name), QOS)

    def stamp(t: float) -> Time:
        ns = clock.ns(t)
        return Time(sec=ns // 10**9, nanosec=ns % 10**9)

    def put(topic: str, t: float, message: object) -> None:
        ns = clock.ns(t)
        writer.write(topic, serialize_message(message), ns, ns)

    dt = 1.0 / spec.state_hz
    n = int(spec.duration_s * spec.state_hz)
    lag = 0.15 + 0.1 * rng.random()  # [s] the estimate trails the setpoint
    charge, voltage = 1.0, 16.8
    hover_current = 18.0 * (1.0 + 0.6 * spec.wear)
    state, setpoint, imu = VehicleState(), GuidanceSetpoint(), Imu()
    setpoint.control_level = GuidanceSetpoint.LEVEL_POSITION
    captured, last_capture = 0, (0.0, 0.0)
    for k in range(n + 1):
        t = k * dt
        x, y, z = _position(spec, max(0.0, t - lag))
        px, py, pz = (c + rng.gauss(0.0, 0.05) for c in (x, y, z))
        ax, ay, az = _position(spec, max(0.0, t - lag - dt))
        state.header.stamp = stamp(t)
        state.position.x, state.position.y, state.position.z = px, py, pz
        state.velocity.x, state.velocity.y, state.velocity.z = ((x - ax) / dt, (y - ay) / dt, (z - az) / dt)
        state.orientation.w = 1.0
        if spec.bulk:  # a real estimate's covariances change every sample (and do not compress away)
            for name in ("position_covariance", "velocity_covariance", "attitude_covariance"):
                setattr(state, name, [abs(rng.gauss(0.0, 0.01)) for _ in range(9)])
        put("/navigation/state", t, state)
        if spec.bulk:
            for topic in BULK:
                imu.header.stamp = stamp(t)
                imu.linear_acceleration.x, imu.linear_acceleration.y = rng.gauss(0, 0.3), rng.gauss(0, 0.3)
                imu.linear_acceleration.z = 9.81 + rng.gauss(0, 0.3)
                imu.angular_velocity.x, imu.angular_velocity.y, imu.angular_velocity.z = (rng.gauss(0, 0.02) for _ in "xyz")
                imu.orientation.w = 1.0
                put(topic, t, imu)
        put("/control/actuators", t, ActuatorCommand(header=state.header, armed=True, tick=k,
                                                       outputs=[0.45 + rng.gauss(0, 0.02) for _ in range(4)]))
        if k % max(1, round(spec.state_hz / 15)) == 0:  # 15 Hz guidance
            setpoint.header.stamp = stamp(t)
            setpoint.position.x, setpoint.position.y, setpoint.position.z = _position(spec, t)
            put("/guidance/setpoint", t, setpoint)
        if k % max(1, round(spec.state_hz / 4)) == 0:  # 4 Hz status
            failsafe = spec.failsafe_at_s is not None and t >= spec.failsafe_at_s
            status = VehicleStatus(armed=True, flight_mode=VehicleStatus.MODE_AUTO,
                                   nav_state=VehicleStatus.NAV_RTL if failsafe else VehicleStatus.NAV_MISSION,
                                   landed_state=VehicleStatus.LANDED_IN_AIR,
                                   failsafe_action=VehicleStatus.FAILSAFE_RTL if failsafe else VehicleStatus.FAILSAFE_NONE)
            status.header.stamp = stamp(t)
            put("/vehicle/status", t, status)
        if k % max(1, round(spec.state_hz / 10)) == 0:  # 10 Hz battery
            current = hover_current * (1.0 + 0.05 * rng.gauss(0, 1))
            charge -= current * 0.1 / 3600.0 / 5.0  # 5 Ah pack
            voltage = 14.0 + 2.8 * charge - 0.01 * current
            battery = BatteryState(voltage=voltage, current=-current, percentage=charge)
            battery.header.stamp = stamp(t)
            put("/sensors/battery", t, battery)
        if k % max(1, round(spec.state_hz)) == 0 and k:  # 1 Hz executive statistics
            overruns = 1 if rng.random() < 0.05 else 0
            stats = ExecutorStats(executor="gnc_core", tick_rate_hz=500.0, ticks=500, overruns=overruns,
                                  load_mean_percent=10 + 3 * rng.random(), load_max_percent=20 + 40 * rng.random())
            stats.header.stamp = stamp(t)
            put("/gnc/executor_stats", t, stats)
        if z > 0.8 * spec.altitude_m and math.dist((px, py), last_capture) >= 15.0:  # distance-triggered captures
            capture = CaptureEvent(index=captured, trigger=CaptureEvent.TRIGGER_DISTANCE, mission_item=-1)
            capture.header.stamp = stamp(t)
            capture.position.x, capture.position.y, capture.position.z = px, py, pz
            put("/payload/captures", t, capture)
            captured, last_capture = captured + 1, (px, py)
    writer.close()
    return Path(path)


def fleet_specs(count: int, duration_s: float, state_hz: float, bulk: bool, vehicles: int = 4) -> list[FlightSpec]:
    """`count` flights spread over `vehicles` vehicles, one a day each, packs wearing out."""
    specs = []
    for k in range(count):
        vehicle = k % vehicles
        flight = k // vehicles
        specs.append(FlightSpec(vehicle=f"synth-{vehicle + 1}", airframe="quad_x" if vehicle % 2 == 0 else "hex_x",
                                seed=k, start_ns=1_790_000_000 * 10**9 + k * 86_400 * 10**9 // vehicles,
                                duration_s=duration_s, state_hz=state_hz, bulk=bulk,
                                wear=min(1.0, flight / max(1, count // vehicles)),
                                failsafe_at_s=0.6 * duration_s if k % 17 == 5 else None))
    return specs


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="catalog_synthetic", description="Write synthetic c4d flights (MCAP).")
    parser.add_argument("out", help="directory (created)")
    parser.add_argument("-n", "--count", type=int, default=10)
    parser.add_argument("--duration", type=float, default=4.0, help="[s] per flight")
    parser.add_argument("--rate", type=float, default=50.0, help="[Hz] state/actuator rate")
    parser.add_argument("--bulk", action="store_true", help="add the IMU topics (real file sizes)")
    args = parser.parse_args(argv)
    if args.count < 1 or args.duration <= 0 or args.rate <= 0:
        parser.error("count >= 1, duration > 0 and rate > 0 required")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for k, spec in enumerate(fleet_specs(args.count, args.duration, args.rate, args.bulk)):
        target = out / f"flight_{k:05d}.mcap"
        if not target.exists():
            write_flight(target, spec)
    print(f"catalog_synthetic: {args.count} flights in {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
