"""MAVLink geofence: fence items ↔ the c4d Geofence, FENCE_STATUS and OBSTACLE_DISTANCE.

Fence items (MAV_MISSION_TYPE_FENCE, https://mavlink.io/en/services/geofence.html): a polygon is
`param1` consecutive MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION / _EXCLUSION items (param1 = its
vertex count), a circle one MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION / _EXCLUSION item (param1 = radius
[m]); MAV_CMD_NAV_FENCE_RETURN_POINT is accepted and ignored (c4d returns home). A c4d fence has
one allowed area: one inclusion polygon, any number of exclusion polygons and circles; an inclusion
circle (PX4's way of saying "max distance from this point") has no equivalent and is refused, as
is a second inclusion polygon. The ceiling and the maximum distance come from the GF_MAX_VER_DIST /
GF_MAX_HOR_DIST parameters. `geofence_from_items` raises FenceItemsError with the MISSION_ACK
result and a one-line reason for the STATUSTEXT; `items_from_geofence` is its inverse (downloads
return the fence in force, geofence/active).

FenceWatch: the vehicle position against the fence in force, for FENCE_STATUS (breach status,
type, count of breaches, time of the last one, mitigation: the core's barrier limits the velocity).

`obstacle_distance`: perceived obstacles (horizontal circles in the local ENU frame) as the 72
sectors of 5° of OBSTACLE_DISTANCE, in MAV_FRAME_BODY_FRD (sector 0 straight ahead, clockwise
seen from above), distances in cm from the vehicle to the obstacle's surface. A sector without an
obstacle within range holds max_distance + 1 (the spec's "no obstacle"); UINT16_MAX ("unknown")
is not used: the lidar covers all 360°.
ROS-free; unit-tested in test/test_fence_protocol.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from c4d_common.geodesy import GeoOrigin
from c4d_common.geofence import BreachKind, LocalFence
from c4d_common.plan import Geofence

from .mission_protocol import WireItem
from .signing import mavlink

M = mavlink
RETURN_POINT = M.MAV_CMD_NAV_FENCE_RETURN_POINT
INCLUSION_VERTEX, EXCLUSION_VERTEX = M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
INCLUSION_CIRCLE, EXCLUSION_CIRCLE = M.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION, M.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION
FENCE_FRAMES = (M.MAV_FRAME_GLOBAL_INT, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, M.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT)
SECTORS, SECTOR_DEG = 72, 5
OBSTACLE_MIN_CM = 10  # [cm] nearest distance reported (the vehicle's own size)
OBSTACLE_MAX_CM = 3000  # [cm] the scan's range (sim lidar range_max 30 m): beyond it, "no obstacle"
BREACH_TYPE = {BreachKind.CEILING: M.FENCE_BREACH_MAXALT, BreachKind.FLOOR: M.FENCE_BREACH_MINALT}  # others: BOUNDARY


class FenceItemsError(ValueError):
    """Fence items that make no c4d fence: `result` is the MISSION_ACK type, str() the reason."""

    def __init__(self, result: int, reason: str) -> None:
        super().__init__(reason)
        self.result = result


def geofence_from_items(items: list[WireItem], max_altitude: float = 0.0, max_distance: float = 0.0) -> Geofence:
    """The fence the items describe, with the given ceiling and max distance (module docstring)."""
    inclusion: tuple[tuple[float, float], ...] = ()
    exclusions: list[tuple[tuple[float, float], ...]] = []
    circles: list[tuple[float, float, float]] = []
    k = 0
    while k < len(items):
        item, where = items[k], f"fence item {k}"
        if item.command == RETURN_POINT:
            k += 1
            continue
        if item.frame not in FENCE_FRAMES:
            raise FenceItemsError(M.MAV_MISSION_UNSUPPORTED_FRAME, f"{where}: frame {item.frame} is not a global frame")
        lat, lon = item.params[4], item.params[5]
        if not (math.isfinite(lat) and math.isfinite(lon) and -90 <= lat <= 90 and -180 <= lon <= 180):
            raise FenceItemsError(M.MAV_MISSION_INVALID_PARAM5_X, f"{where}: latitude/longitude out of range")
        if item.command in (INCLUSION_CIRCLE, EXCLUSION_CIRCLE):
            radius = item.params[0]
            if item.command == INCLUSION_CIRCLE:
                raise FenceItemsError(M.MAV_MISSION_UNSUPPORTED, f"{where}: inclusion circles are not supported "
                                                                 "(GF_MAX_HOR_DIST limits the distance from home)")
            if not (math.isfinite(radius) and radius > 0):
                raise FenceItemsError(M.MAV_MISSION_INVALID_PARAM1, f"{where}: circle radius must be > 0 m")
            circles.append((lat, lon, float(radius)))
            k += 1
            continue
        if item.command not in (INCLUSION_VERTEX, EXCLUSION_VERTEX):
            raise FenceItemsError(M.MAV_MISSION_UNSUPPORTED, f"{where}: command {item.command} is not a fence item")
        count = item.params[0]
        if not (math.isfinite(count) and count == int(count) and count >= 3):
            raise FenceItemsError(M.MAV_MISSION_INVALID_PARAM1, f"{where}: a polygon needs >= 3 vertices (param1 "
                                                                f"{count:g})")
        group = items[k:k + int(count)]
        if len(group) < count or any(v.command != item.command or v.params[0] != count for v in group):
            raise FenceItemsError(M.MAV_MISSION_INVALID, f"{where}: polygon of {int(count)} vertices is not "
                                                         f"{int(count)} consecutive items of the same kind")
        vertices = []
        for j, v in enumerate(group):
            vlat, vlon = v.params[4], v.params[5]
            if v.frame not in FENCE_FRAMES or not (math.isfinite(vlat) and math.isfinite(vlon)
                                                   and -90 <= vlat <= 90 and -180 <= vlon <= 180):
                raise FenceItemsError(M.MAV_MISSION_INVALID_PARAM5_X, f"fence item {k + j}: bad vertex")
            vertices.append((vlat, vlon))
        if item.command == EXCLUSION_VERTEX:
            exclusions.append(tuple(vertices))
        elif inclusion:
            raise FenceItemsError(M.MAV_MISSION_UNSUPPORTED, f"{where}: a second inclusion polygon "
                                                             "(c4d keeps one allowed area)")
        else:
            inclusion = tuple(vertices)
        k += int(count)
    return Geofence(inclusion, max_altitude, max_distance, tuple(exclusions), tuple(circles))


def items_from_geofence(fence: Geofence) -> list[WireItem]:
    """The fence's polygons and circles as fence items (what a download returns)."""
    items = []
    for command, polygon in [(INCLUSION_VERTEX, fence.polygon)] + [(EXCLUSION_VERTEX, p) for p in fence.exclusion_polygons]:
        items += [WireItem(command, M.MAV_FRAME_GLOBAL_INT, (float(len(polygon)), 0.0, 0.0, 0.0, lat, lon, 0.0))
                  for lat, lon in polygon]
    items += [WireItem(EXCLUSION_CIRCLE, M.MAV_FRAME_GLOBAL_INT, (radius, 0.0, 0.0, 0.0, lat, lon, 0.0))
              for lat, lon, radius in fence.exclusion_circles]
    return items


@dataclass
class FenceWatch:
    """FENCE_STATUS's inputs: the fence in force against the vehicle's position, breaches counted
    on entry (a breach that lasts is one breach)."""

    fence: LocalFence | None = None  # None: no fence in force (FENCE_STATUS not sent)
    breach_type: int = M.FENCE_BREACH_NONE
    breached: bool = False
    count: int = 0
    last_breach_s: float = 0.0  # [s] monotonic time of the last breach's start

    def set_fence(self, fence: Geofence, home: GeoOrigin | None) -> None:
        self.fence = LocalFence.from_geofence(fence, home) if home is not None and not fence.empty else None
        if self.fence is None:
            self.breached, self.breach_type = False, M.FENCE_BREACH_NONE

    def update(self, position: tuple[float, float, float], flying: bool, now: float) -> None:
        if self.fence is None or not all(math.isfinite(v) for v in position):
            return
        breach = self.fence.breach(position, with_floor=flying)
        if breach is not None and not self.breached:
            self.count, self.last_breach_s = min(self.count + 1, 0xFFFF), now
        self.breached = breach is not None
        self.breach_type = BREACH_TYPE.get(breach.kind, M.FENCE_BREACH_BOUNDARY) if breach else M.FENCE_BREACH_NONE

    def message(self, boot_s: float) -> M.MAVLink_fence_status_message | None:
        if self.fence is None:
            return None
        breach_ms = max(0, int((self.last_breach_s - boot_s) * 1000)) & 0xFFFFFFFF if self.count else 0
        return M.MAVLink_fence_status_message(int(self.breached), self.count, self.breach_type, breach_ms,
                                              M.FENCE_MITIGATE_VEL_LIMIT)


def sector_distances(position: tuple[float, float], yaw: float, obstacles: tuple[tuple[float, float, float], ...],
                     max_cm: int = OBSTACLE_MAX_CM) -> list[int]:
    """72 distances [cm] (module docstring): sector i is centred i·5° clockwise from the heading
    (`yaw`: ENU, counter-clockwise from east); an obstacle fills every sector its circle spans."""
    out = [max_cm + 1] * SECTORS
    for x, y, radius in obstacles:
        dx, dy = x - position[0], y - position[1]
        centre = math.hypot(dx, dy)
        surface_cm = int(round(max(0.0, centre - radius) * 100.0))
        if surface_cm > max_cm:
            continue
        bearing = math.degrees(yaw - math.atan2(dy, dx)) % 360.0  # clockwise from the heading (FRD)
        half = math.degrees(math.asin(radius / centre)) if centre > radius else 180.0  # inside: all around
        for i in range(SECTORS):
            offset = abs((i * SECTOR_DEG - bearing + 180.0) % 360.0 - 180.0)
            if offset <= half + SECTOR_DEG / 2:
                out[i] = min(out[i], max(surface_cm, OBSTACLE_MIN_CM))
    return out


def obstacle_distance(time_usec: int, distances: list[int], max_cm: int = OBSTACLE_MAX_CM) \
        -> M.MAVLink_obstacle_distance_message:
    return M.MAVLink_obstacle_distance_message(time_usec, M.MAV_DISTANCE_SENSOR_LASER, distances, SECTOR_DEG,
                                               OBSTACLE_MIN_CM, max_cm, float(SECTOR_DEG), 0.0, M.MAV_FRAME_BODY_FRD)
