"""COMMAND_LONG / COMMAND_INT → what c4d must do, with the spec's MAV_RESULT on bad input.

What: `translate(msg, ctx)` turns a command into an `Action`: a vehicle command for the mission
node's vehicle/command service (arm, disarm, take-off, land, RTL, hold, set mode, go-to), a
mission-control action (MISSION_START, DO_SET_MODE AUTO.MISSION), a telemetry change
(SET_MESSAGE_INTERVAL, REQUEST_MESSAGE, REQUEST_AUTOPILOT_CAPABILITIES, GET_HOME_POSITION) — or an immediate
COMMAND_ACK result (UNSUPPORTED for unknown commands, DENIED for invalid parameters). The node
executes the action and ACKs with the service's result code (c4d result codes are MAV_RESULT).

Why pure: every branch (units, frames, magic numbers such as the 21196 force-arm key, PX4 mode
numbers) is unit-tested without ROS, and no GCS input can raise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum

from c4d_common.vehicle import MissionAction, Mode
from c4d_common.vehicle import VehicleCommandId as Cmd

from .frames import (
    AUTO_LAND,
    AUTO_LOITER,
    AUTO_MISSION,
    AUTO_RTL,
    AUTO_TAKEOFF,
    PX4_ACRO,
    PX4_AUTO,
    PX4_OFFBOARD,
    PX4_POSCTL,
    PX4_STABILIZED,
)
from .signing import mavlink

M = mavlink
FORCE_KEY = 21196  # MAV_CMD_COMPONENT_ARM_DISARM param2: force (bypass checks)


@dataclass(frozen=True)
class Context:
    home: tuple[float, float, float] | None  # lat, lon, alt AMSL
    takeoff_altitude: float  # MIS_TAKEOFF_ALT
    mission_paused: bool = False  # the plan is active, possibly held (AUTO.LOITER): AUTO.MISSION resumes it


class Kind(StrEnum):
    VEHICLE = "vehicle"  # fields: vehicle/command request (command, altitude, mode, force, latitude, ...)
    MISSION = "mission"  # fields: mission/control request (action: MissionAction, item)
    INTERVAL = "interval"  # fields: msg_id, interval_us
    REQUEST = "request"  # fields: msg_id
    ACK = "ack"  # answer at once with `result` / `reason`


@dataclass
class Action:
    kind: Kind
    result: int = M.MAV_RESULT_ACCEPTED  # for Kind.ACK
    reason: str = ""
    fields: dict = field(default_factory=dict)


def _deny(reason: str) -> Action:
    return Action(Kind.ACK, M.MAV_RESULT_DENIED, reason)


def _finite(*values: float) -> bool:
    return all(isinstance(v, int | float) and math.isfinite(v) for v in values)


def translate(msg, ctx: Context) -> Action:
    """The action for a COMMAND_LONG or COMMAND_INT (already known to be addressed to us)."""
    is_int = msg.get_type() == "COMMAND_INT"
    c = msg.command
    p = [msg.param1, msg.param2, msg.param3, msg.param4]
    if is_int:
        x = msg.x / 1e7 if msg.frame in (M.MAV_FRAME_GLOBAL_INT, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, M.MAV_FRAME_GLOBAL,
                                          M.MAV_FRAME_GLOBAL_RELATIVE_ALT) else float(msg.x)
        y = msg.y / 1e7 if msg.frame in (M.MAV_FRAME_GLOBAL_INT, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, M.MAV_FRAME_GLOBAL,
                                          M.MAV_FRAME_GLOBAL_RELATIVE_ALT) else float(msg.y)
        p += [x, y, msg.z]
        relative = msg.frame in (M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, M.MAV_FRAME_GLOBAL_RELATIVE_ALT)
    else:
        p += [msg.param5, msg.param6, msg.param7]
        relative = False  # COMMAND_LONG positions are AMSL (MAV_FRAME_GLOBAL)
    if c == M.MAV_CMD_COMPONENT_ARM_DISARM:
        if p[0] not in (0.0, 1.0):
            return _deny("param1 must be 1 (arm) or 0 (disarm)")
        return Action(Kind.VEHICLE, fields={"command": Cmd.ARM if p[0] == 1.0 else Cmd.DISARM, "force": p[1] == FORCE_KEY})
    if c == M.MAV_CMD_NAV_TAKEOFF:
        altitude = ctx.takeoff_altitude
        if _finite(p[6]):
            if relative:
                altitude = p[6]
            elif ctx.home is not None:
                altitude = p[6] - ctx.home[2]
            else:
                return Action(Kind.ACK, M.MAV_RESULT_TEMPORARILY_REJECTED, "no home position yet")
        if not 0.5 <= altitude <= 120.0:
            return _deny(f"take-off altitude {altitude:.1f} m above home outside [0.5, 120]")
        return Action(Kind.VEHICLE, fields={"command": Cmd.TAKEOFF, "altitude": float(altitude)})
    if c == M.MAV_CMD_NAV_LAND:
        return Action(Kind.VEHICLE, fields={"command": Cmd.LAND})
    if c == M.MAV_CMD_NAV_RETURN_TO_LAUNCH:
        return Action(Kind.VEHICLE, fields={"command": Cmd.RETURN_TO_LAUNCH})
    if c == M.MAV_CMD_NAV_LOITER_UNLIM and not _finite(p[4]):
        return Action(Kind.VEHICLE, fields={"command": Cmd.HOLD})
    if c == M.MAV_CMD_MISSION_START:
        first = int(p[0]) if _finite(p[0]) and p[0] >= 0 else 0
        return Action(Kind.MISSION, fields={"action": MissionAction.START, "item": first})
    if c == M.MAV_CMD_DO_SET_MODE:
        return _set_mode(p, ctx)
    if c == M.MAV_CMD_DO_REPOSITION:
        return _reposition(p, relative, ctx)
    if c == M.MAV_CMD_SET_MESSAGE_INTERVAL:
        if not (_finite(p[0], p[1]) and p[0] == int(p[0]) and 0 < p[0] < 1 << 24):
            return _deny("param1 must be a message id")
        return Action(Kind.INTERVAL, fields={"msg_id": int(p[0]), "interval_us": p[1]})
    if c == M.MAV_CMD_REQUEST_MESSAGE:
        if not (_finite(p[0]) and p[0] == int(p[0]) and 0 < p[0] < 1 << 24):
            return _deny("param1 must be a message id")
        return Action(Kind.REQUEST, fields={"msg_id": int(p[0])})
    if c == M.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
        return Action(Kind.REQUEST, fields={"msg_id": M.MAVLINK_MSG_ID_AUTOPILOT_VERSION})
    if c == M.MAV_CMD_GET_HOME_POSITION:  # deprecated for REQUEST_MESSAGE, still sent by MAVProxy
        return Action(Kind.REQUEST, fields={"msg_id": M.MAVLINK_MSG_ID_HOME_POSITION})
    return Action(Kind.ACK, M.MAV_RESULT_UNSUPPORTED, f"command {c} not supported")


def translate_set_mode(msg, ctx: Context) -> Action:
    """The action for a SET_MODE message (deprecated, still sent by some GCSs): the same as
    MAV_CMD_DO_SET_MODE with base_mode and the PX4 custom mode's main / sub mode."""
    custom = int(msg.custom_mode)
    return _set_mode([float(msg.base_mode), float((custom >> 16) & 0xFF), float((custom >> 24) & 0xFF)], ctx)


def _set_mode(p: list[float], ctx: Context) -> Action:
    if not (_finite(p[0], p[1]) and int(p[0]) & M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED):
        return _deny("only custom modes (PX4 layout) are supported")
    main, sub = int(p[1]), int(p[2]) if _finite(p[2]) else 0
    if main == PX4_AUTO:
        if sub == AUTO_MISSION:
            return Action(Kind.MISSION, fields={"action": MissionAction.RESUME if ctx.mission_paused else MissionAction.START,
                                             "item": -1})
        vehicle = {AUTO_LOITER: Cmd.HOLD, AUTO_RTL: Cmd.RETURN_TO_LAUNCH, AUTO_LAND: Cmd.LAND}.get(sub)
        if sub == AUTO_TAKEOFF:
            return Action(Kind.VEHICLE, fields={"command": Cmd.TAKEOFF, "altitude": float(ctx.takeoff_altitude)})
        if vehicle is not None:
            return Action(Kind.VEHICLE, fields={"command": vehicle})
        return _deny(f"AUTO sub mode {sub} not supported")
    mode = {PX4_POSCTL: Mode.POSITION, PX4_STABILIZED: Mode.ATTITUDE, PX4_ACRO: Mode.RATE, PX4_OFFBOARD: Mode.OFFBOARD}.get(main)
    if mode is None:
        return _deny(f"main mode {main} not supported")
    return Action(Kind.VEHICLE, fields={"command": Cmd.SET_MODE, "mode": mode})


def _reposition(p: list[float], relative: bool, ctx: Context) -> Action:
    lat, lon, alt = p[4], p[5], p[6]
    if not _finite(lat, lon) or not (-90 <= lat <= 90 and -180 <= lon <= 180):
        return _deny("reposition needs a valid latitude and longitude")
    if ctx.home is None:
        return Action(Kind.ACK, M.MAV_RESULT_TEMPORARILY_REJECTED, "no home position yet")
    if not _finite(alt):
        alt_rel = math.nan  # keep the current altitude: the node fills it in
    else:
        alt_rel = alt if relative else alt - ctx.home[2]
    yaw = math.radians(90.0 - p[3]) if _finite(p[3]) else math.nan
    return Action(Kind.VEHICLE, fields={"command": Cmd.GOTO, "latitude": lat, "longitude": lon, "altitude": alt_rel,
                                     "yaw": yaw})
