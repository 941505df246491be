"""Plan items ↔ MAVLink mission items (command id, frame, 7 params), without pymavlink.

Why here: QGroundControl `.plan` files and the MAVLink mission protocol carry the same
(command, frame, param1..7) triples; one mapping serves both, so an item survives
upload → download → file export unchanged. Conventions: positions are global with altitude
relative to home (MAV_FRAME_GLOBAL_RELATIVE_ALT / _INT); yaw in MAVLink items is a compass
heading in degrees (NED, clockwise from north), in plans an ENU angle in radians.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from enum import Enum

from c4d_common.geodesy import GeoOrigin

from .plan import GLOBAL, LOCAL, Item, PlanError

NAN = float("nan")
NAV_WAYPOINT, NAV_LOITER_UNLIM, NAV_LOITER_TIME, NAV_RTL, NAV_LAND, NAV_TAKEOFF = 16, 17, 19, 20, 21, 22
DO_CHANGE_SPEED, DO_DIGICAM_CONTROL, DO_SET_CAM_TRIGG_DIST = 178, 203, 206
IMAGE_START_CAPTURE, IMAGE_STOP_CAPTURE = 2000, 2001
FENCE_POLYGON_VERTEX_INCLUSION = 5001
FRAME_GLOBAL, FRAME_MISSION, FRAME_GLOBAL_RELATIVE_ALT = 0, 2, 3
FRAME_GLOBAL_INT, FRAME_GLOBAL_RELATIVE_ALT_INT = 5, 6
RELATIVE_FRAMES = (FRAME_GLOBAL_RELATIVE_ALT, FRAME_GLOBAL_RELATIVE_ALT_INT)
POSITION_FRAMES = (FRAME_GLOBAL, FRAME_GLOBAL_RELATIVE_ALT, FRAME_GLOBAL_INT, FRAME_GLOBAL_RELATIVE_ALT_INT)
SUPPORTED_COMMANDS = {NAV_TAKEOFF: "takeoff", NAV_WAYPOINT: "waypoint", NAV_LOITER_TIME: "loiter",
                      NAV_LOITER_UNLIM: "loiter", NAV_LAND: "land", NAV_RTL: "rtl", DO_CHANGE_SPEED: "change_speed",
                      DO_SET_CAM_TRIGG_DIST: "camera_distance", IMAGE_START_CAPTURE: "camera_start",
                      IMAGE_STOP_CAPTURE: "camera_stop", DO_DIGICAM_CONTROL: "camera_capture"}


class ItemProblem(Enum):
    """What is wrong with a MAVLink mission item (the MAV_MISSION_RESULT a GCS gets depends on it)."""

    FRAME = "frame"  # a frame c4d does not take (or an AMSL frame without a home altitude)
    COMMAND = "command"  # a command c4d does not fly
    VALUE = "value"  # a missing or out-of-range parameter


class MavlinkItemError(PlanError):
    """A MAVLink mission item that cannot become a plan item: `problem` says what kind, the text which."""

    def __init__(self, problem: ItemProblem, text: str) -> None:
        super().__init__(text)
        self.problem = problem


def compass_to_enu_yaw(heading_deg: float) -> float:
    return math.radians(90.0 - heading_deg) if math.isfinite(heading_deg) else NAN


def enu_yaw_to_compass(yaw: float) -> float:
    return (90.0 - math.degrees(yaw)) % 360.0 if math.isfinite(yaw) else NAN


def item_from_mavlink(command: int, frame: int, params: Sequence[float], home_altitude: float | None = None,
                      where: str = "item") -> Item:
    """One plan item from a MAVLink mission item; MavlinkItemError (a PlanError) names what is wrong.

    `params` = param1..4, x/latitude, y/longitude, z/altitude (7 floats, NaN = unset). AMSL
    frames need `home_altitude` to turn the altitude into one above home."""
    kind = SUPPORTED_COMMANDS.get(command)
    if kind is None:
        raise MavlinkItemError(ItemProblem.COMMAND, f"{where}: unsupported MAVLink command {command}")
    if len(params) != 7:
        raise MavlinkItemError(ItemProblem.VALUE, f"{where}: 7 params needed")
    p = [float(v) for v in params]
    if kind in ("takeoff", "waypoint", "loiter", "land"):
        if frame not in POSITION_FRAMES and not (frame == FRAME_MISSION and kind in ("land", "takeoff")):
            raise MavlinkItemError(ItemProblem.FRAME, f"{where}: frame {frame} not supported (use relative altitude, 3 or 6)")
        if frame in (FRAME_GLOBAL, FRAME_GLOBAL_INT):
            if home_altitude is None:
                raise MavlinkItemError(ItemProblem.FRAME, f"{where}: AMSL frame {frame} needs a home altitude")
            p[6] -= home_altitude
    yaw = compass_to_enu_yaw(p[3])
    if kind == "takeoff":
        return Item(kind, LOCAL, NAN, NAN, p[6])
    if kind in ("waypoint", "loiter", "land"):
        if kind == "land" and (not math.isfinite(p[4]) or (p[4] == 0.0 and p[5] == 0.0)):
            return Item(kind)  # land here
        if not (math.isfinite(p[4]) and math.isfinite(p[5]) and math.isfinite(p[6])):
            raise MavlinkItemError(ItemProblem.VALUE, f"{where}: {kind} needs a latitude, a longitude and an altitude")
        if not (-90.0 <= p[4] <= 90.0 and -180.0 <= p[5] <= 180.0):
            raise MavlinkItemError(ItemProblem.VALUE, f"{where}: latitude/longitude out of range")
        if command == NAV_LOITER_UNLIM:
            hold = math.inf
        else:
            hold = p[0] if kind in ("waypoint", "loiter") and math.isfinite(p[0]) else 0.0
        if hold < 0:
            raise MavlinkItemError(ItemProblem.VALUE, f"{where}: negative hold time")
        radius = p[1] if kind == "waypoint" and math.isfinite(p[1]) and p[1] > 0 else 1.0
        return Item(kind, GLOBAL, p[4], p[5], p[6] if kind != "land" else 0.0, radius, hold, yaw)
    if kind == "change_speed":
        if not (math.isfinite(p[1]) and p[1] > 0):
            raise MavlinkItemError(ItemProblem.VALUE, f"{where}: speed must be > 0")
        return Item(kind, speed=p[1])
    if kind == "camera_distance":
        if not (math.isfinite(p[0]) and p[0] >= 0):
            raise MavlinkItemError(ItemProblem.VALUE, f"{where}: trigger distance must be >= 0")
        return Item(kind, camera_distance=p[0])
    return Item(kind)


def item_to_mavlink(item: Item, home: GeoOrigin | None) -> tuple[int, int, list[float]]:
    """(command, frame, params) of a plan item; local items need `home` to become global."""
    nan7 = [NAN] * 7
    if item.type == "takeoff":
        return NAV_TAKEOFF, FRAME_GLOBAL_RELATIVE_ALT, [0.0, 0.0, 0.0, NAN, NAN, NAN, item.z]
    if item.type in ("waypoint", "loiter", "land"):
        if not item.has_position:
            return NAV_LAND, FRAME_GLOBAL_RELATIVE_ALT, [0.0, 0.0, 0.0, NAN, 0.0, 0.0, 0.0]
        lat, lon = item.x, item.y
        if item.frame == LOCAL:
            if home is None:
                raise PlanError("local plan items need a home position to become global")
            lat, lon, _ = home.to_geodetic(item.x, item.y, 0.0)
        yaw = enu_yaw_to_compass(item.yaw)
        if item.type == "land":
            return NAV_LAND, FRAME_GLOBAL_RELATIVE_ALT, [0.0, 0.0, 0.0, yaw, lat, lon, 0.0]
        if item.type == "loiter" and math.isinf(item.hold):
            return NAV_LOITER_UNLIM, FRAME_GLOBAL_RELATIVE_ALT, [0.0, 0.0, 0.0, yaw, lat, lon, item.z]
        command = NAV_WAYPOINT if item.type == "waypoint" else NAV_LOITER_TIME
        radius = item.acceptance_radius if item.type == "waypoint" else 0.0
        return command, FRAME_GLOBAL_RELATIVE_ALT, [item.hold, radius, 0.0, yaw, lat, lon, item.z]
    if item.type == "rtl":
        return NAV_RTL, FRAME_MISSION, [0.0] * 7
    if item.type == "change_speed":
        return DO_CHANGE_SPEED, FRAME_MISSION, [1.0, item.speed, -1.0, 0.0, 0.0, 0.0, 0.0]
    if item.type == "camera_distance":
        return DO_SET_CAM_TRIGG_DIST, FRAME_MISSION, [item.camera_distance, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0]
    command = {"camera_start": IMAGE_START_CAPTURE, "camera_stop": IMAGE_STOP_CAPTURE,
               "camera_capture": DO_DIGICAM_CONTROL}[item.type]
    return command, FRAME_MISSION, [0.0 if math.isnan(v) else v for v in nan7]
