"""Plan ↔ c4d_interfaces/MissionPlan conversions (the only module that knows both)."""

from __future__ import annotations

import math

from c4d_common.plan import GLOBAL, ITEM_TYPES, LOCAL, Geofence, Item, Plan, PlanError
from c4d_interfaces.msg import GeoPoint, MissionItem, MissionPlan

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
    msg.geofence.inclusion_polygon = [GeoPoint(latitude=lat, longitude=lon) for lat, lon in plan.geofence.polygon]
    msg.geofence.max_altitude = plan.geofence.max_altitude
    msg.geofence.max_distance = plan.geofence.max_distance
    return msg


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
    polygon = tuple((p.latitude, p.longitude) for p in msg.geofence.inclusion_polygon)
    if polygon and len(polygon) < 3:
        raise PlanError("geofence polygon needs at least 3 vertices")
    return Plan(tuple(items), Geofence(polygon, msg.geofence.max_altitude, msg.geofence.max_distance), msg.name or "plan",
                msg.cruise_speed, msg.rtl_altitude, msg.plan_id)
