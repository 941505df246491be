"""MAVLink offboard setpoints ⇄ c4d trajectory setpoints (ENU / FLU), ROS-free.

What: `OffboardDecoder.decode(msg, vehicle)` turns SET_POSITION_TARGET_LOCAL_NED,
SET_POSITION_TARGET_GLOBAL_INT and SET_ATTITUDE_TARGET into a `Target` — the plain-Python form of
c4d_interfaces/GuidanceSetpoint that the node publishes on offboard/trajectory_setpoint — or None
when the frame is dropped; every drop is counted per reason (`rejected`) and the first drop of each
kind yields one STATUSTEXT line (`take_warnings`). `position_target_local_ned(target, ms)` is the
reverse for telemetry: the stream the vehicle follows (guidance/offboard) as POSITION_TARGET_LOCAL_NED.

Type masks (MAVLink POSITION_TARGET_TYPEMASK / ATTITUDE_TARGET_TYPEMASK): an ignored field is NaN
in the Target (c4d's "unset"); the control level is the highest one with a field set: any position
axis → POSITION (velocity / acceleration are feed-forwards, a NaN position axis follows its
velocity), else any velocity axis → VELOCITY, else any acceleration axis → ACCELERATION. A field
that is used but not finite makes the frame malformed. The force bit (afx… as forces) is not
supported. SET_ATTITUDE_TARGET: attitude used → ATTITUDE (body yaw rate, if set, is the yaw-rate
feed-forward), attitude ignored and all three body rates used → RATE; thrust is required (it is the
normalised collective thrust, as in c4d).

Frames: LOCAL_NED (the map frame, NED axes), LOCAL_OFFSET_NED (position = offset from the current
position, NED axes), BODY_NED / BODY_OFFSET_NED (x forward, y right, z down along the current
heading, levelled; position = offset from the current position; yaw relative to the current
heading, as ArduPilot and the MAVLink frame definition say). GLOBAL_INT (altitude AMSL) and
GLOBAL_RELATIVE_ALT_INT (altitude above home) via the home the bridge knows (VehicleState.origin,
the origin of the map frame). Other frames are rejected.

Why pure: sign conventions, masks and frames are what a MAVLink user gets wrong first and what a
bridge gets wrong silently; the tests feed pymavlink-encoded frames through this module.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass

from c4d_common import quat
from c4d_common.geodesy import GeoOrigin
from c4d_common.vehicle import Level

from .frames import Vec, attitude_to_enu, enu_to_ned, frd_to_flu, ned_to_enu
from .signing import mavlink

M = mavlink
NAN = math.nan
UNSET: Vec = (NAN, NAN, NAN)

# POSITION_TARGET_TYPEMASK bits
X_IGNORE, Y_IGNORE, Z_IGNORE = 1, 2, 4
VX_IGNORE, VY_IGNORE, VZ_IGNORE = 8, 16, 32
AX_IGNORE, AY_IGNORE, AZ_IGNORE = 64, 128, 256
FORCE_SET, YAW_IGNORE, YAW_RATE_IGNORE = 512, 1024, 2048
# ATTITUDE_TARGET_TYPEMASK bits
ROLL_RATE_IGNORE, PITCH_RATE_IGNORE, YAW_RATE_BODY_IGNORE = 1, 2, 4
THROTTLE_IGNORE, ATTITUDE_IGNORE = 64, 128
KNOWN_ATTITUDE_BITS = ROLL_RATE_IGNORE | PITCH_RATE_IGNORE | YAW_RATE_BODY_IGNORE | THROTTLE_IGNORE | ATTITUDE_IGNORE

LOCAL_FRAMES = {M.MAV_FRAME_LOCAL_NED: "LOCAL_NED", M.MAV_FRAME_LOCAL_OFFSET_NED: "LOCAL_OFFSET_NED",
                M.MAV_FRAME_BODY_NED: "BODY_NED", M.MAV_FRAME_BODY_OFFSET_NED: "BODY_OFFSET_NED"}
BODY_FRAMES = (M.MAV_FRAME_BODY_NED, M.MAV_FRAME_BODY_OFFSET_NED)
OFFSET_FRAMES = (M.MAV_FRAME_LOCAL_OFFSET_NED, *BODY_FRAMES)
GLOBAL_FRAMES = {M.MAV_FRAME_GLOBAL_INT: "GLOBAL_INT", M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT: "GLOBAL_RELATIVE_ALT_INT"}


@dataclass(frozen=True)
class Target:
    """A trajectory setpoint in c4d's frames (GuidanceSetpoint without the header); NaN = unset."""

    level: Level
    position: Vec = UNSET  # map ENU [m]
    velocity: Vec = UNSET  # ENU [m/s]
    acceleration: Vec = UNSET  # ENU [m/s²]
    yaw: float = NAN  # ENU [rad], 0 = east, CCW +
    yaw_rate: float = NAN  # about world up [rad/s]
    orientation: quat.Quat = (NAN, NAN, NAN, NAN)  # body FLU → ENU (ATTITUDE)
    body_rate: Vec = UNSET  # FLU [rad/s] (RATE)
    thrust: float = NAN  # normalised collective [0, 1] (ATTITUDE / RATE)


@dataclass(frozen=True)
class VehicleFrame:
    """What the relative frames need from the estimate: position, heading and the map's origin."""

    position: Vec = UNSET  # map ENU [m]
    yaw: float = NAN  # ENU [rad]
    home: tuple[float, float, float] | None = None  # origin of the map frame: lat, lon [deg], alt AMSL [m]


class Rejected(Exception):
    """A frame that cannot become a setpoint: `reason` is the counter key, `text` the STATUSTEXT."""

    def __init__(self, reason: str, text: str) -> None:
        super().__init__(text)
        self.reason, self.text = reason, text


def ned_yaw_to_enu(yaw: float) -> float:
    """Heading clockwise from north → ENU yaw (counter-clockwise from east), in (-π, π]."""
    return math.remainder(math.pi / 2 - yaw, math.tau)


def _masked(values: Vec, mask: int, bits: tuple[int, int, int], what: str) -> Vec:
    """The axes whose ignore bit is clear, NaN for the others; a used non-finite axis is malformed."""
    out = tuple(NAN if mask & bit else float(v) for v, bit in zip(values, bits, strict=True))
    if any(not math.isfinite(v) for v, bit in zip(out, bits, strict=True) if not mask & bit):
        raise Rejected("malformed", f"offboard: {what} not finite")
    return out  # type: ignore[return-value]


def _scalar(value: float, ignored: bool, what: str) -> float:
    if ignored:
        return NAN
    if not math.isfinite(value):
        raise Rejected("malformed", f"offboard: {what} not finite")
    return float(value)


def _heading_to_enu(v: Vec, yaw: float) -> Vec:
    """Forward / right / down along the heading `yaw` (ENU rad), levelled → ENU."""
    c, s = math.cos(yaw), math.sin(yaw)
    f, r, d = v
    return (f * c + r * s, f * s - r * c, -d)


def _add(a: Vec, b: Vec) -> Vec:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def _level(position: Vec, velocity: Vec, acceleration: Vec) -> Level:
    """The highest level with a field set; each axis of it must be usable (the gateway's rule:
    POSITION needs a position or a velocity per axis, VELOCITY / ACCELERATION all three axes)."""
    if any(math.isfinite(v) for v in position):
        if not all(math.isfinite(p) or math.isfinite(v) for p, v in zip(position, velocity, strict=True)):
            raise Rejected("mask", "offboard: type_mask leaves an axis without position or velocity")
        return Level.POSITION
    for level, values in ((Level.VELOCITY, velocity), (Level.ACCELERATION, acceleration)):
        if any(math.isfinite(v) for v in values):
            if not all(math.isfinite(v) for v in values):
                raise Rejected("mask", f"offboard: a {level.name.lower()} setpoint needs all three axes")
            return level
    raise Rejected("empty", "offboard: type_mask ignores position, velocity and acceleration")


class OffboardDecoder:
    """SET_POSITION_TARGET_* / SET_ATTITUDE_TARGET → `Target`, with per-reason drop counters.

    Why a class: the counters and the "warn once per kind" memory live with the conversion, so the
    node only publishes and forwards the warning lines."""

    MESSAGES = ("SET_POSITION_TARGET_LOCAL_NED", "SET_POSITION_TARGET_GLOBAL_INT", "SET_ATTITUDE_TARGET")

    def __init__(self, sysid: int, compid: int = M.MAV_COMP_ID_AUTOPILOT1) -> None:
        self.sysid, self.compid = sysid, compid
        self.accepted = 0
        self.rejected: Counter[str] = Counter()
        self._warned: set[str] = set()
        self._warnings: list[str] = []

    def addressed(self, msg) -> bool:
        """True for a frame for this vehicle: target system ours or 0 (broadcast), component ours or 0."""
        return msg.target_system in (0, self.sysid) and msg.target_component in (0, self.compid)

    def decode(self, msg, vehicle: VehicleFrame) -> Target | None:
        """The setpoint of one offboard message, or None (not ours: counted as `not_addressed`;
        unusable: counted per reason, warned once per kind)."""
        if not self.addressed(msg):
            self.rejected["not_addressed"] += 1
            return None
        try:
            kind = msg.get_type()
            if kind == "SET_POSITION_TARGET_LOCAL_NED":
                target = self._local(msg, vehicle)
            elif kind == "SET_POSITION_TARGET_GLOBAL_INT":
                target = self._global(msg, vehicle)
            elif kind == "SET_ATTITUDE_TARGET":
                target = self._attitude(msg)
            else:
                raise Rejected("message", f"offboard: {kind} is not a setpoint")
        except Rejected as exc:
            self.rejected[exc.reason] += 1
            key = exc.text if exc.reason in ("frame", "mask") else exc.reason  # each unsupported frame / bit once
            if key not in self._warned:
                self._warned.add(key)
                self._warnings.append(exc.text)
            return None
        self.accepted += 1
        return target

    def take_warnings(self) -> list[str]:
        """STATUSTEXT lines not yet sent (each kind of drop is announced once per bridge run)."""
        out, self._warnings = self._warnings, []
        return out

    # ----------------------------------------------------------------------------- messages
    @staticmethod
    def _common(msg) -> tuple[Vec, Vec, float, float]:
        """Velocity, acceleration (NED axes as sent), yaw, yaw rate (MAVLink conventions), masked."""
        mask = msg.type_mask
        if mask & FORCE_SET:
            raise Rejected("mask", "offboard: force setpoints (type_mask bit 10) not supported")
        velocity = _masked((msg.vx, msg.vy, msg.vz), mask, (VX_IGNORE, VY_IGNORE, VZ_IGNORE), "velocity")
        acceleration = _masked((msg.afx, msg.afy, msg.afz), mask, (AX_IGNORE, AY_IGNORE, AZ_IGNORE), "acceleration")
        yaw = _scalar(msg.yaw, bool(mask & YAW_IGNORE), "yaw")
        yaw_rate = _scalar(msg.yaw_rate, bool(mask & YAW_RATE_IGNORE), "yaw rate")
        return velocity, acceleration, yaw, yaw_rate

    def _local(self, msg, vehicle: VehicleFrame) -> Target:
        frame = msg.coordinate_frame
        if frame not in LOCAL_FRAMES:
            raise Rejected("frame", f"offboard: SET_POSITION_TARGET_LOCAL_NED frame {frame} not supported "
                                    "(LOCAL_NED, LOCAL_OFFSET_NED, BODY_NED, BODY_OFFSET_NED)")
        position = _masked((msg.x, msg.y, msg.z), msg.type_mask, (X_IGNORE, Y_IGNORE, Z_IGNORE), "position")
        velocity, acceleration, yaw, yaw_rate = self._common(msg)
        if frame in OFFSET_FRAMES and not all(math.isfinite(v) for v in vehicle.position):
            raise Rejected("no_estimate", f"offboard: {LOCAL_FRAMES[frame]} needs a position estimate")
        if frame in BODY_FRAMES:
            if not math.isfinite(vehicle.yaw):
                raise Rejected("no_estimate", f"offboard: {LOCAL_FRAMES[frame]} needs a heading estimate")
            h = vehicle.yaw
            position = _add(vehicle.position, _heading_to_enu(position, h))  # NaN axes stay NaN
            velocity, acceleration = _heading_to_enu(velocity, h), _heading_to_enu(acceleration, h)
            yaw = math.remainder(h - yaw, math.tau)  # relative, clockwise +
        else:
            position = ned_to_enu(position)
            if frame == M.MAV_FRAME_LOCAL_OFFSET_NED:
                position = _add(vehicle.position, position)
            velocity, acceleration, yaw = ned_to_enu(velocity), ned_to_enu(acceleration), ned_yaw_to_enu(yaw)
        return Target(_level(position, velocity, acceleration), position, velocity, acceleration, yaw, -yaw_rate)

    def _global(self, msg, vehicle: VehicleFrame) -> Target:
        frame = msg.coordinate_frame
        if frame not in GLOBAL_FRAMES:
            raise Rejected("frame", f"offboard: SET_POSITION_TARGET_GLOBAL_INT frame {frame} not supported "
                                    "(GLOBAL_INT, GLOBAL_RELATIVE_ALT_INT)")
        mask = msg.type_mask
        velocity, acceleration, yaw, yaw_rate = self._common(msg)
        horizontal = not (mask & X_IGNORE and mask & Y_IGNORE)
        if horizontal and mask & (X_IGNORE | Y_IGNORE):
            raise Rejected("mask", "offboard: SET_POSITION_TARGET_GLOBAL_INT needs both latitude and longitude (or none)")
        alt = _scalar(msg.alt, bool(mask & Z_IGNORE), "altitude")
        position = UNSET
        if horizontal or math.isfinite(alt):
            if vehicle.home is None:
                raise Rejected("no_home", "offboard: global setpoints need a home position")
            home = GeoOrigin(*vehicle.home)
            lat, lon = msg.lat_int / 1e7, msg.lon_int / 1e7
            if horizontal and not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
                raise Rejected("malformed", "offboard: latitude / longitude out of range")
            up = alt - home.altitude if frame == M.MAV_FRAME_GLOBAL_INT else alt
            east, north, _ = home.to_enu(lat, lon, home.altitude) if horizontal else (NAN, NAN, 0.0)
            position = (east, north, up)
        velocity, acceleration = ned_to_enu(velocity), ned_to_enu(acceleration)
        return Target(_level(position, velocity, acceleration), position, velocity, acceleration, ned_yaw_to_enu(yaw),
                      -yaw_rate)

    @staticmethod
    def _attitude(msg) -> Target:
        mask = msg.type_mask
        if mask & ~KNOWN_ATTITUDE_BITS & 0xFF:
            raise Rejected("mask", f"offboard: SET_ATTITUDE_TARGET type_mask bits {mask & ~KNOWN_ATTITUDE_BITS:#x} "
                                   "not supported")
        if mask & THROTTLE_IGNORE:
            raise Rejected("mask", "offboard: SET_ATTITUDE_TARGET needs the thrust (throttle ignore bit set)")
        thrust = _scalar(msg.thrust, False, "thrust")
        if not 0.0 <= thrust <= 1.0:
            raise Rejected("malformed", f"offboard: thrust {thrust:.2f} outside [0, 1]")
        rates = _masked((msg.body_roll_rate, msg.body_pitch_rate, msg.body_yaw_rate), mask,
                        (ROLL_RATE_IGNORE, PITCH_RATE_IGNORE, YAW_RATE_BODY_IGNORE), "body rate")
        body_rate = frd_to_flu(rates)
        if not mask & ATTITUDE_IGNORE:
            q = tuple(float(v) for v in msg.q)
            norm = math.sqrt(sum(v * v for v in q)) if all(math.isfinite(v) for v in q) else NAN
            if not abs(norm - 1.0) < 0.01:
                raise Rejected("malformed", "offboard: attitude quaternion not a unit quaternion")
            orientation = attitude_to_enu(quat.normalize(q))  # type: ignore[arg-type]
            return Target(Level.ATTITUDE, orientation=orientation, body_rate=body_rate, yaw_rate=body_rate[2],
                          thrust=thrust)
        if not all(math.isfinite(v) for v in body_rate):
            raise Rejected("mask", "offboard: SET_ATTITUDE_TARGET ignores the attitude and some body rates")
        return Target(Level.RATE, body_rate=body_rate, thrust=thrust)


def _mask_of(values: tuple[float, ...], bits: tuple[int, ...]) -> int:
    return sum(bit for v, bit in zip(values, bits, strict=True) if not math.isfinite(v))


def position_target_local_ned(target: Target, time_boot_ms: int) -> M.MAVLink_position_target_local_ned_message | None:
    """The setpoint the vehicle follows as POSITION_TARGET_LOCAL_NED (None at the ATTITUDE / RATE
    levels, which this message cannot express); unset fields are flagged in type_mask and sent as 0."""
    if target.level not in (Level.POSITION, Level.VELOCITY, Level.ACCELERATION):
        return None
    p, v, a = enu_to_ned(target.position), enu_to_ned(target.velocity), enu_to_ned(target.acceleration)
    yaw = math.remainder(math.pi / 2 - target.yaw, math.tau) if math.isfinite(target.yaw) else NAN
    yaw_rate = -target.yaw_rate
    values = (*p, *v, *a, yaw, yaw_rate)
    mask = _mask_of(values, (X_IGNORE, Y_IGNORE, Z_IGNORE, VX_IGNORE, VY_IGNORE, VZ_IGNORE, AX_IGNORE, AY_IGNORE,
                             AZ_IGNORE, YAW_IGNORE, YAW_RATE_IGNORE))
    sent = [x if math.isfinite(x) else 0.0 for x in values]
    return M.MAVLink_position_target_local_ned_message(time_boot_ms, M.MAV_FRAME_LOCAL_NED, mask, *sent)
