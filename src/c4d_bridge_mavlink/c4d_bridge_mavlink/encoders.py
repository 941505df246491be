"""Telemetry encoders: the vehicle snapshot (latest ROS values, plain Python) → MAVLink messages.

Why a snapshot: the node copies what it hears into one `Snapshot`; every encoder is a pure
function of it, so the message contents (units, frames, scaling, invalid markers) are unit-tested
without ROS. Conventions follow the MAVLink common spec: lat/lon in degE7, altitudes in mm,
velocities in cm/s (NED), angles in rad (FRD/NED), headings in cdeg, unknown values as the
spec's "unknown" markers (UINT16_MAX, INT16_MAX, -1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from c4d_common import quat
from c4d_common.vehicle import FailsafeAction, Landed, Mode, Nav

from .estimator_status import NavigationView
from .estimator_status import estimator_status as encode_estimator_status
from .fence import FenceWatch, obstacle_distance, sector_distances
from .frames import attitude_to_ned, compass_heading_deg, enu_to_ned, flu_to_frd, px4_custom_mode
from .health_report import VehicleHealth, sensor_bits
from .offboard import Target, position_target_local_ned
from .signing import mavlink

M = mavlink
NAN = float("nan")
CAPABILITIES = (M.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT | M.MAV_PROTOCOL_CAPABILITY_MISSION_INT
                | M.MAV_PROTOCOL_CAPABILITY_COMMAND_INT | M.MAV_PROTOCOL_CAPABILITY_MAVLINK2
                | M.MAV_PROTOCOL_CAPABILITY_MISSION_FENCE)
VERSION = (0 << 24) | (1 << 16) | (0 << 8) | 255  # 0.1.0 release (major, minor, patch, FIRMWARE_VERSION_TYPE)
OFFBOARD_TARGET_FRESH_S = 0.5  # [s] the core's offboard stream timeout: an older target is not followed
OBSTACLES_FRESH_S = 1.0  # [s] perception/surroundings older than this: no OBSTACLE_DISTANCE (scans stopped)
LANDED = {Landed.UNDEFINED: M.MAV_LANDED_STATE_UNDEFINED, Landed.ON_GROUND: M.MAV_LANDED_STATE_ON_GROUND,
          Landed.IN_AIR: M.MAV_LANDED_STATE_IN_AIR, Landed.TAKEOFF: M.MAV_LANDED_STATE_TAKEOFF,
          Landed.LANDING: M.MAV_LANDED_STATE_LANDING}


@dataclass
class Snapshot:
    """The latest of everything the bridge reports; NaN/None = not known yet."""

    boot_s: float = 0.0  # monotonic time of the bridge start (time_boot_ms origin)
    status_known: bool = False  # vehicle/status heard: until then armed / mode / landed are not known
    mission_known: bool = False  # mission/state heard: until then NAV_GOTO may be a plan or a go-to
    armed: bool = False
    flight_mode: int = Mode.AUTO
    nav_state: int = Nav.NONE
    landed_state: int = Landed.UNDEFINED
    failsafe: int = FailsafeAction.NONE
    position: tuple[float, float, float] = (NAN, NAN, NAN)  # ENU [m] from home
    velocity: tuple[float, float, float] = (NAN, NAN, NAN)  # ENU [m/s]
    orientation: quat.Quat | None = None  # body FLU → ENU
    angular_velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)  # FLU [rad/s]
    valid_position: bool = False
    valid_attitude: bool = False
    global_position: tuple[float, float, float] = (NAN, NAN, NAN)  # lat, lon [deg], alt AMSL [m]
    home: tuple[float, float, float] | None = None  # lat, lon, alt AMSL
    gps: tuple[float, float, float, int, float, float] | None = None  # lat, lon, alt, fix_type, eph [m], epv [m]
    battery_voltage: float = NAN
    battery_current: float = NAN
    battery_remaining: float = NAN  # 0–1
    battery_consumed_mah: float = NAN
    throttle: float = 0.0  # 0–1, mean motor output
    load: float = NAN  # 0–1 executor load
    health: VehicleHealth = field(default_factory=VehicleHealth)  # SYS_STATUS sensor bits' inputs
    mission_current: int = 0
    mission_total: int = 0
    mission_state: int = 0  # MISSION_STATE enum
    comm_errors: int = 0
    offboard_target: Target | None = None  # guidance/offboard, the stream the core follows in OFFBOARD
    offboard_target_t: float = -math.inf  # monotonic time it was heard
    fence: FenceWatch = field(default_factory=FenceWatch)  # the fence in force vs the position (FENCE_STATUS)
    obstacles: tuple[tuple[float, float, float], ...] | None = None  # perceived: east, north, radius [m]
    obstacles_t: float = -math.inf  # monotonic time they were heard
    navigation: NavigationView = field(default_factory=NavigationView)  # ESTIMATOR_STATUS's inputs
    extra: dict = field(default_factory=dict)


def time_boot_ms(s: Snapshot, now: float) -> int:
    return max(0, int((now - s.boot_s) * 1000)) & 0xFFFFFFFF


def _i(value: float, scale: float, unknown: int) -> int:
    return int(round(value * scale)) if math.isfinite(value) else unknown


def heartbeat(s: Snapshot) -> M.MAVLink_heartbeat_message | None:
    """The vehicle's HEARTBEAT; None (nothing sent) until its status has been heard — and, while it
    follows setpoints (NAV_GOTO), the mission state that says whether that is a plan or a go-to: a
    restarted bridge must not claim a state it does not know (PX4 sends no heartbeat before it knows
    its own)."""
    if not s.status_known or (s.nav_state == Nav.GOTO and not s.mission_known):
        return None
    base = M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | M.MAV_MODE_FLAG_STABILIZE_ENABLED
    if s.flight_mode in (Mode.AUTO, Mode.OFFBOARD):  # as PX4 flags its OFFBOARD mode
        base |= M.MAV_MODE_FLAG_AUTO_ENABLED | M.MAV_MODE_FLAG_GUIDED_ENABLED
    if s.armed:
        base |= M.MAV_MODE_FLAG_SAFETY_ARMED
    status = M.MAV_STATE_STANDBY
    if s.armed:
        status = M.MAV_STATE_CRITICAL if s.failsafe >= FailsafeAction.HOLD else M.MAV_STATE_ACTIVE
    nav = s.nav_state
    if nav == Nav.GOTO and s.mission_state == M.MISSION_STATE_ACTIVE:
        nav = Nav.MISSION  # the mission node flies plans through the core's go-to interface
    return M.MAVLink_heartbeat_message(M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_PX4, base,
                                       px4_custom_mode(s.flight_mode, nav), status, 3)


def sys_status(s: Snapshot) -> M.MAVLink_sys_status_message:
    bits = sensor_bits(s.health, s.status_known, s.valid_attitude, s.valid_position, s.home is not None)
    return M.MAVLink_sys_status_message(
        bits.present, bits.enabled, bits.health, _i(s.load, 1000, 0) if math.isfinite(s.load) else 0,
        _i(s.battery_voltage, 1000, 0xFFFF), _i(s.battery_current, 100, -1), _i(s.battery_remaining, 100, -1),
        0, min(s.comm_errors, 0xFFFF), 0, 0, 0, 0, 0, 0, 0)


def battery_status(s: Snapshot) -> M.MAVLink_battery_status_message:
    cells = [0xFFFF] * 10
    cells[0] = min(_i(s.battery_voltage, 1000, 0xFFFF), 0xFFFE) if math.isfinite(s.battery_voltage) else 0xFFFF
    return M.MAVLink_battery_status_message(
        0, M.MAV_BATTERY_FUNCTION_ALL, M.MAV_BATTERY_TYPE_LIPO, 0x7FFF, cells, _i(s.battery_current, 100, -1),
        _i(s.battery_consumed_mah, 1, -1), -1, _i(s.battery_remaining, 100, -1), 0,
        M.MAV_BATTERY_CHARGE_STATE_OK if not (s.battery_remaining < 0.3) else M.MAV_BATTERY_CHARGE_STATE_LOW,
        [0, 0, 0, 0], 0, 0)


def attitude(s: Snapshot, now: float) -> M.MAVLink_attitude_message | None:
    if s.orientation is None:
        return None
    roll, pitch, yaw = quat.to_euler(attitude_to_ned(s.orientation))
    p, q, r = flu_to_frd(s.angular_velocity)
    return M.MAVLink_attitude_message(time_boot_ms(s, now), roll, pitch, yaw, p, q, r)


def attitude_quaternion(s: Snapshot, now: float) -> M.MAVLink_attitude_quaternion_message | None:
    if s.orientation is None:
        return None
    w, x, y, z = attitude_to_ned(s.orientation)
    p, q, r = flu_to_frd(s.angular_velocity)
    return M.MAVLink_attitude_quaternion_message(time_boot_ms(s, now), w, x, y, z, p, q, r, [0.0, 0.0, 0.0, 0.0])


def global_position_int(s: Snapshot, now: float) -> M.MAVLink_global_position_int_message | None:
    lat, lon, alt = s.global_position
    if not (s.valid_position and math.isfinite(lat)) or s.home is None:
        return None
    vn, ve, vd = enu_to_ned(s.velocity)
    hdg = _i(compass_heading_deg(s.orientation), 100, 0xFFFF) if s.orientation is not None else 0xFFFF
    return M.MAVLink_global_position_int_message(
        time_boot_ms(s, now), _i(lat, 1e7, 0), _i(lon, 1e7, 0), _i(alt, 1000, 0), _i(alt - s.home[2], 1000, 0),
        _i(vn, 100, 0), _i(ve, 100, 0), _i(vd, 100, 0), hdg % 36000 if hdg != 0xFFFF else hdg)


def local_position_ned(s: Snapshot, now: float) -> M.MAVLink_local_position_ned_message | None:
    if not s.valid_position:
        return None
    x, y, z = enu_to_ned(s.position)
    vx, vy, vz = enu_to_ned(s.velocity)
    return M.MAVLink_local_position_ned_message(time_boot_ms(s, now), x, y, z, vx, vy, vz)


def gps_raw_int(s: Snapshot, now: float) -> M.MAVLink_gps_raw_int_message:
    if s.gps is None:
        return M.MAVLink_gps_raw_int_message(int(now * 1e6), M.GPS_FIX_TYPE_NO_GPS, 0, 0, 0, 0xFFFF, 0xFFFF, 0xFFFF,
                                             0xFFFF, 0xFF, 0, 0, 0, 0, 0, 0)
    lat, lon, alt, fix, eph, epv = s.gps
    ground = math.hypot(s.velocity[0], s.velocity[1]) if math.isfinite(s.velocity[0]) else NAN
    cog = (90.0 - math.degrees(math.atan2(s.velocity[1], s.velocity[0]))) % 360.0 if ground > 0.2 else NAN
    return M.MAVLink_gps_raw_int_message(
        int(now * 1e6), fix, _i(lat, 1e7, 0), _i(lon, 1e7, 0), _i(alt, 1000, 0), min(_i(eph, 100, 0xFFFF), 0xFFFF),
        min(_i(epv, 100, 0xFFFF), 0xFFFF), _i(ground, 100, 0xFFFF), _i(cog, 100, 0xFFFF) % 36000 if math.isfinite(cog)
        else 0xFFFF, 12 if fix >= 3 else 0, 0, _i(eph, 1000, 0), _i(epv, 1000, 0), 0, 0, 0)


def vfr_hud(s: Snapshot) -> M.MAVLink_vfr_hud_message:
    ground = math.hypot(s.velocity[0], s.velocity[1]) if math.isfinite(s.velocity[0]) else 0.0
    heading = int(compass_heading_deg(s.orientation)) if s.orientation is not None else 0
    alt = s.global_position[2] if math.isfinite(s.global_position[2]) else 0.0
    climb = s.velocity[2] if math.isfinite(s.velocity[2]) else 0.0
    return M.MAVLink_vfr_hud_message(ground, ground, heading, int(round(100 * s.throttle)), alt, climb)


def home_position(s: Snapshot, now: float) -> M.MAVLink_home_position_message | None:
    if s.home is None:
        return None
    lat, lon, alt = s.home
    return M.MAVLink_home_position_message(_i(lat, 1e7, 0), _i(lon, 1e7, 0), _i(alt, 1000, 0), 0.0, 0.0, 0.0,
                                           [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, int(now * 1e6))


def position_target(s: Snapshot, now: float) -> M.MAVLink_position_target_local_ned_message | None:
    """POSITION_TARGET_LOCAL_NED: the offboard setpoint the core follows, only in OFFBOARD and while
    the stream is live (heard within OFFBOARD_TARGET_FRESH_S); None (nothing sent) otherwise."""
    if s.flight_mode != Mode.OFFBOARD or s.offboard_target is None or now - s.offboard_target_t > OFFBOARD_TARGET_FRESH_S:
        return None
    return position_target_local_ned(s.offboard_target, time_boot_ms(s, now))


def fence_status(s: Snapshot, now: float) -> M.MAVLink_fence_status_message | None:
    """FENCE_STATUS while a fence is in force (geofence/active), None (nothing sent) otherwise."""
    return s.fence.message(s.boot_s)


def obstacle_distances(s: Snapshot, now: float) -> M.MAVLink_obstacle_distance_message | None:
    """OBSTACLE_DISTANCE from perception/surroundings relative to the heading (fence.sector_distances);
    None without a fresh scan's obstacles, a position or an attitude."""
    if s.obstacles is None or now - s.obstacles_t > OBSTACLES_FRESH_S or not s.valid_position or s.orientation is None:
        return None
    distances = sector_distances((s.position[0], s.position[1]), quat.yaw_of(s.orientation), s.obstacles)
    return obstacle_distance(int(now * 1e6), distances)


def estimator_status(s: Snapshot, now: float) -> M.MAVLink_estimator_status_message | None:
    """ESTIMATOR_STATUS from navigation/state + navigation/status (estimator_status.py)."""
    return encode_estimator_status(s.navigation, max(0, int((now - s.boot_s) * 1e6)))


def extended_sys_state(s: Snapshot) -> M.MAVLink_extended_sys_state_message:
    return M.MAVLink_extended_sys_state_message(M.MAV_VTOL_STATE_UNDEFINED, LANDED.get(s.landed_state, 0))


def autopilot_version(sysid: int) -> M.MAVLink_autopilot_version_message:
    return M.MAVLink_autopilot_version_message(CAPABILITIES, VERSION, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0, 0,
                                               0x0C4D000000000000 | sysid, [0] * 18)


def mission_current(s: Snapshot) -> M.MAVLink_mission_current_message:
    return M.MAVLink_mission_current_message(s.mission_current, s.mission_total, s.mission_state, 0)
