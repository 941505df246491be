"""Plan ↔ c4d_interfaces/MissionPlan conversions (the only module that knows both)."""

from __future__ import annotations

import math

from c4d_common.plan import GLOBAL, ITEM_TYPES, LOCAL, Geofence, Item, Plan, PlanError
from c4d_interfaces.msg import FenceCircle, FencePolygon, GeoPoint, MissionItem, MissionPlan
from c4d_interfaces.msg import Geofence as GeofenceMsg

CMD = {"takeoff": MissionItem.CMD_TAKEOFF, "waypoint": MissionItem.CMD_WAYPOINT, "loiter": MissionItem.CMD_LOITER,
       "change_speed": MissionItem.CMD_CHANGE_SPEED, "land": MissionItem.CMD_LAND, "rtl": MissionItem.CMD_RETURN_TO_LAUNCH,
       "camera_start": MissionItem.CMD_CAMERA_TRIGGER_START, "camera_stop": MissionItem.CMD_CAMERA_TRIGGER_STOP,
       "camera_distance": MissionItem.CMD_CAMERA_TRIGGER_DISTANCE, "camera_capture": MissionItem.CMD_CAMERA_CAPTURE}
TYPE = {v: k for k, v in CMD.items()}
assert set(CMD) == set(ITEM_TYPES)


def plan_to_msg(plan: Plan) -> MissionPlan:
    msg = MissionPlan(name=plan.name, plan_id=plan.plan_id, cruise_speed=plan.cruise_speed, rtl_altitude=plan.rtl_altitude)
    for k, item in enumerate(plan.items):
        z = item.z if item.type != "takeoff" else item.z
        msg.items.append(MissionItem(
            seq=k, command=CMD[item.type],
            frame=MissionItem.FRAME_GLOBAL_RELATIVE_ALT if item.frame == GLOBAL else MissionItem.FRAME_LOCAL_ENU,
            x=item.x, y=item.y, z=z, acceptance_radius=item.acceptance_radius, hold_time=item.hold, yaw=item.yaw,
            speed=item.speed, camera_distance=item.camera_distance, autocontinue=True))
    msg.geofence = geofence_to_msg(plan.geofence)
    return msg


def geofence_to_msg(fence: Geofence) -> GeofenceMsg:
    msg = GeofenceMsg(max_altitude=float(fence.max_altitude), max_distance=float(fence.max_distance),
                      min_altitude=float(fence.min_altitude))
    msg.inclusion_polygon = [GeoPoint(latitude=lat, longitude=lon) for lat, lon in fence.polygon]
    msg.exclusion_polygons = [FencePolygon(vertices=[GeoPoint(latitude=lat, longitude=lon) for lat, lon in polygon])
                              for polygon in fence.exclusion_polygons]
    msg.exclusion_circles = [FenceCircle(center=GeoPoint(latitude=lat, longitude=lon), radius=float(radius))
                             for lat, lon, radius in fence.exclusion_circles]
    return msg


def geofence_from_msg(msg: GeofenceMsg) -> Geofence:
    """The message's fence; PlanError names a malformed part (a polygon of < 3 vertices, a non-finite
    coordinate, a circle radius <= 0, a floor at or above the ceiling)."""
    def polygon_of(points, what: str) -> tuple[tuple[float, float], ...]:
        polygon = tuple((float(p.latitude), float(p.longitude)) for p in points)
        if polygon and len(polygon) < 3:
            raise PlanError(f"geofence {what} needs at least 3 vertices")
        if not all(math.isfinite(v) for vertex in polygon for v in vertex):
            raise PlanError(f"geofence {what} has a non-finite vertex")
        return polygon

    exclusions = tuple(polygon_of(p.vertices, f"exclusion polygon {k}") for k, p in enumerate(msg.exclusion_polygons))
    if any(not polygon for polygon in exclusions):
        raise PlanError("geofence exclusion polygon with no vertices")
    circles = []
    for k, c in enumerate(msg.exclusion_circles):
        values = (float(c.center.latitude), float(c.center.longitude), float(c.radius))
        if not all(math.isfinite(v) for v in values) or values[2] <= 0:
            raise PlanError(f"geofence exclusion circle {k}: needs a finite centre and a radius > 0")
        circles.append(values)
    limits = (float(msg.max_altitude), float(msg.max_distance), float(msg.min_altitude))
    if not all(math.isfinite(v) for v in limits):
        raise PlanError("geofence limits must be finite")
    if limits[2] > 0 and limits[0] > 0 and limits[2] >= limits[0]:
        raise PlanError(f"geofence floor {limits[2]:g} m is not below its ceiling {limits[0]:g} m")
    return Geofence(polygon_of(msg.inclusion_polygon, "polygon"), limits[0], limits[1], exclusions, tuple(circles),
                    limits[2])


def plan_from_msg(msg: MissionPlan) -> Plan:
    items = []
    for k, m in enumerate(msg.items):
        kind = TYPE.get(m.command)
        if kind is None:
            raise PlanError(f"item {k}: unknown command {m.command}")
        if m.frame not in (MissionItem.FRAME_GLOBAL_RELATIVE_ALT, MissionItem.FRAME_LOCAL_ENU):
            raise PlanError(f"item {k}: unknown frame {m.frame}")
        if m.seq != k:
            raise PlanError(f"item {k}: seq {m.seq} out of order")
        if kind in ("waypoint", "loiter") and not all(math.isfinite(v) for v in (m.x, m.y, m.z)):
            raise PlanError(f"item {k}: {kind} needs finite coordinates")
        if not (m.acceptance_radius > 0 or kind not in ("waypoint", "loiter")) or m.hold_time < 0:
            raise PlanError(f"item {k}: acceptance_radius must be > 0 and hold_time >= 0")
        items.append(Item(kind, GLOBAL if m.frame == MissionItem.FRAME_GLOBAL_RELATIVE_ALT else LOCAL, m.x, m.y, m.z,
                          m.acceptance_radius if m.acceptance_radius > 0 else 1.0, m.hold_time, m.yaw, m.speed,
                          m.camera_distance))
    return Plan(tuple(items), geofence_from_msg(msg.geofence), msg.name or "plan",
                msg.cruise_speed, msg.rtl_altitude, msg.plan_id)
