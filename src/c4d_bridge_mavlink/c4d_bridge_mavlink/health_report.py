"""What the bridge tells a GCS about the vehicle's health: SYS_STATUS sensor bits and failsafe texts.

SYS_STATUS (`sensor_bits`): stock GCSs read `onboard_control_sensors_present/enabled/health` bit by
bit, and MAVSDK's `health.is_armable` is the health of MAV_SYS_STATUS_PREARM_CHECK. The bits come
from what the vehicle itself reports, never a constant:
- sensors: perception/health, one status per sensor (hardware id → level OK): imu → 3D gyro and
  accel, mag, baro → absolute pressure, gps, range_down → laser position. A sensor not heard yet
  is present and enabled, not healthy.
- AHRS: navigation/state's attitude valid; XY position control also needs a valid position.
- rate / attitude / altitude / position control and motor outputs: the core is there (its latched
  vehicle/status heard) and health does not count it dead or stalled.
- battery: health/summary has no battery_low / battery_critical event active.
- PREARM_CHECK: what the mission node's pre-arm checks need that the bridge can see — the core
  there, every perception sensor heard and OK, the estimate valid (attitude, position, home). The
  battery reserve (mission `min_battery`) and the plan's geofence are checked at ARM only.

Failsafe texts (`FailsafeAnnouncer`): health/summary's `failsafe` (an action name, 10 Hz) becomes
one STATUSTEXT per action taken (HOLD and up) and one "failsafe cleared" when such an action ends.
A WARN is not a failsafe: it is never announced, so its end is not a "cleared" either (a WARN
coming and going on the ground used to produce a "failsafe cleared" nobody had been told about).

ROS-free: the node copies the messages' fields in; unit-tested in test_health_report.py.
"""

from __future__ import annotations

import functools
import operator
from collections.abc import Mapping
from dataclasses import dataclass, field

from c4d_common.vehicle import FailsafeAction

from .signing import mavlink

M = mavlink
PERCEPTION_BITS: dict[str, int] = {  # perception/health hardware id → SYS_STATUS bits
    "imu": M.MAV_SYS_STATUS_SENSOR_3D_GYRO | M.MAV_SYS_STATUS_SENSOR_3D_ACCEL,
    "mag": M.MAV_SYS_STATUS_SENSOR_3D_MAG,
    "baro": M.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE,
    "gps": M.MAV_SYS_STATUS_SENSOR_GPS,
    "range_down": M.MAV_SYS_STATUS_SENSOR_LASER_POSITION,
}
CORE_BITS = (M.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL | M.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
             | M.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL | M.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS)
POSITION_BITS = M.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
PRESENT = (functools.reduce(operator.or_, PERCEPTION_BITS.values()) | CORE_BITS | POSITION_BITS | M.MAV_SYS_STATUS_AHRS
           | M.MAV_SYS_STATUS_SENSOR_BATTERY | M.MAV_SYS_STATUS_PREARM_CHECK)
BATTERY_EVENTS = ("battery_low", "battery_critical")  # c4d_health.policy.Event values in health/summary "active"
CORE = "core"  # the GNC core's node name in health/summary dead_nodes / stalled_nodes


def _names(listing: str) -> set[str]:
    return {name.strip() for name in listing.split(",") if name.strip()}


@dataclass
class VehicleHealth:
    """What the bridge last heard about the vehicle's health (see the module docstring)."""

    sensor_ok: dict[str, bool] = field(default_factory=dict)  # perception/health: hardware id → level OK
    core_lost: bool = False  # health/summary: the core is dead or stalled
    battery_warning: bool = False  # health/summary: battery_low or battery_critical active

    def on_summary(self, values: Mapping[str, str]) -> None:
        """health/summary's key/values: active events, dead and stalled nodes."""
        lost = _names(values.get("dead_nodes", "")) | _names(values.get("stalled_nodes", ""))
        self.core_lost = CORE in lost
        self.battery_warning = bool(_names(values.get("active", "")) & set(BATTERY_EVENTS))


@dataclass(frozen=True)
class SensorBits:
    present: int
    enabled: int
    health: int

    @property
    def armable(self) -> bool:
        return bool(self.health & M.MAV_SYS_STATUS_PREARM_CHECK)


def sensor_bits(h: VehicleHealth, status_known: bool, attitude_valid: bool, position_valid: bool,
                home_known: bool) -> SensorBits:
    """SYS_STATUS present / enabled / health bits of the vehicle as heard (module docstring)."""
    healthy = 0
    for name, bits in PERCEPTION_BITS.items():
        if h.sensor_ok.get(name, False):
            healthy |= bits
    core = status_known and not h.core_lost
    if core:
        healthy |= CORE_BITS
    if attitude_valid:
        healthy |= M.MAV_SYS_STATUS_AHRS
    if core and attitude_valid and position_valid:
        healthy |= POSITION_BITS
    if not h.battery_warning:
        healthy |= M.MAV_SYS_STATUS_SENSOR_BATTERY
    sensors_ok = bool(h.sensor_ok) and all(h.sensor_ok.values()) and all(n in h.sensor_ok for n in PERCEPTION_BITS)
    if core and sensors_ok and attitude_valid and position_valid and home_known:
        healthy |= M.MAV_SYS_STATUS_PREARM_CHECK
    return SensorBits(PRESENT, PRESENT, healthy)


@dataclass(frozen=True)
class Announcement:
    severity: int  # MAV_SEVERITY
    text: str


class FailsafeAnnouncer:
    """health/summary's failsafe action → the STATUSTEXTs a GCS gets: each action taken (HOLD and
    up) once, and "failsafe cleared" only after an announced action ends (module docstring)."""

    def __init__(self) -> None:
        self.announced = FailsafeAction.NONE

    def update(self, action: FailsafeAction, reason: str) -> Announcement | None:
        if action >= FailsafeAction.HOLD:
            if action == self.announced:
                return None
            self.announced = action
            return Announcement(M.MAV_SEVERITY_CRITICAL, f"failsafe {action.name}: {reason}")
        if self.announced >= FailsafeAction.HOLD:
            self.announced = FailsafeAction.NONE
            return Announcement(M.MAV_SEVERITY_NOTICE, "failsafe cleared")
        return None
