"""`ros2 run c4d_mission payload` — camera triggering and geotagging for missions.

Follows mission/plan and mission/state (latched) and the vehicle state; triggers the
(simulated) camera at waypoints or every N metres as the plan's camera items say; each capture
is published on payload/captures (c4d_interfaces/CaptureEvent, reliable) and appended to
`<output_dir>/captures_<UTC time>.geojson` and `.csv`, one pair per flight (opened on arming).
payload/gimbal (geometry_msgs/Vector3Stamped, roll/pitch/yaw in rad relative to the body)
points the camera at nadir while capturing, forward otherwise.
Parameters: output_dir (default ./c4d_captures), events_executor.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

from c4d_common.geodesy import GeoOrigin
from c4d_common.plan import PlanError

from .payload import CameraTrigger, CaptureLog, camera_mode


def main(argv: list[str] | None = None) -> int:
    from c4d_ros import node_runtime

    rclpy = node_runtime.init(argv)
    from geometry_msgs.msg import Vector3Stamped
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    from c4d_interfaces.msg import CaptureEvent, MissionPlan, MissionState, VehicleState, VehicleStatus
    from c4d_ros.plan_msgs import plan_from_msg

    node = rclpy.create_node("payload")
    output_dir = Path(node.declare_parameter("output_dir", "c4d_captures").value)
    events = bool(node.declare_parameter("events_executor", True).value)
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    pub_capture = node.create_publisher(CaptureEvent, "payload/captures", QoSProfile(depth=50,
                                                                                       reliability=ReliabilityPolicy.RELIABLE))
    pub_gimbal = node.create_publisher(Vector3Stamped, "payload/gimbal", 10)
    world: dict = {"plan": None, "mission": None, "armed": False, "log": None, "gimbal_t": 0.0, "trigger": CameraTrigger()}

    def on_plan(msg) -> None:
        try:
            world["plan"] = plan_from_msg(msg)
        except PlanError as exc:
            node.get_logger().error(f"mission/plan unusable: {exc}")

    def on_status(msg) -> None:
        if msg.armed and not world["armed"]:  # a new flight: new files, counting from 0
            stem = time.strftime("captures_%Y%m%dT%H%M%SZ", time.gmtime())
            world["log"] = CaptureLog(output_dir, stem)
            world["trigger"] = CameraTrigger()
            node.get_logger().info(f"capture log {world['log'].geojson}")
        world["armed"] = msg.armed

    def on_state(msg) -> None:
        mission, plan = world["mission"], world["plan"]
        if mission is None or plan is None or mission.plan_id != plan.plan_id:
            return
        if mission.state != MissionState.STATE_ACTIVE or not world["armed"]:
            return
        position = (msg.position.x, msg.position.y, msg.position.z)
        if not msg.valid & VehicleState.VALID_ORIGIN:
            return
        origin = GeoOrigin(msg.origin.latitude, msg.origin.longitude, msg.origin.altitude)
        if world.get("origin") != origin:
            world["origin"] = origin  # one object per home, so the trigger's path cache stays valid
        captures = world["trigger"].update(plan, mission.current_item, mission.last_reached_item, position,
                                           world["origin"])
        mode, _ = camera_mode(plan, mission.current_item)
        gimbal = Vector3Stamped()
        gimbal.header = msg.header
        gimbal.vector.y = -math.pi / 2 if mode != "off" else 0.0  # pitch down to nadir while surveying
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        if t - world["gimbal_t"] >= 0.02:  # 50 Hz is plenty for a gimbal command
            world["gimbal_t"] = t
            pub_gimbal.publish(gimbal)
        for c in captures:
            lat, lon, alt = origin.to_geodetic(*c.position)
            event = CaptureEvent(index=c.index, mission_item=c.mission_item, file_name=f"img_{c.index:05d}.jpg",
                                 trigger={"waypoint": CaptureEvent.TRIGGER_WAYPOINT, "distance": CaptureEvent.TRIGGER_DISTANCE,
                                          "command": CaptureEvent.TRIGGER_COMMAND}[c.trigger])
            event.header = msg.header
            event.geodetic.latitude, event.geodetic.longitude, event.geodetic.altitude = lat, lon, alt
            event.position.x, event.position.y, event.position.z = c.position
            event.orientation = msg.orientation
            event.gimbal_rpy.y = gimbal.vector.y
            pub_capture.publish(event)
            if world["log"] is not None:
                world["log"].add(c, msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9, lat, lon, alt, event.file_name)

    node.create_subscription(MissionPlan, "mission/plan", on_plan, latched)
    node.create_subscription(MissionState, "mission/state", lambda m: world.__setitem__("mission", m), latched)
    node.create_subscription(VehicleStatus, "vehicle/status", on_status, latched)
    node.create_subscription(VehicleState, "navigation/state", on_state,
                             QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT))
    return node_runtime.spin_node(node, events)


if __name__ == "__main__":
    sys.exit(main())
