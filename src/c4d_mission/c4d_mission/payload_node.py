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
from typing import Any

from geometry_msgs.msg import Vector3Stamped

from c4d_common.geodesy import GeoOrigin
from c4d_common.plan import Plan, PlanError
from c4d_common.vehicle import MissionStatus
from c4d_interfaces.msg import CaptureEvent, MissionPlan, MissionState, VehicleState, VehicleStatus
from c4d_ros import lifecycle
from c4d_ros import manifest as m
from c4d_ros.component import ComponentError, Host, SpunNode, run_components
from c4d_ros.drain import LatestSampler
from c4d_ros.params import ParameterError, Spec, declare_all
from c4d_ros.plan_msgs import plan_from_msg

from .payload import CameraTrigger, Capture, CaptureLog, camera_mode

GIMBAL_PERIOD_S = 0.02  # 50 Hz is plenty for a gimbal command
STATE_PERIOD_S = 0.02  # the vehicle state is sampled at 50 Hz: captures are interpolated between samples (payload.py)
TRIGGERS = {"waypoint": CaptureEvent.TRIGGER_WAYPOINT, "distance": CaptureEvent.TRIGGER_DISTANCE,
            "command": CaptureEvent.TRIGGER_COMMAND}
PARAMETERS = {
    "output_dir": Spec("c4d_captures", "directory of the per-flight capture logs (GeoJSON + CSV; path)", read_only=True),
    "events_executor": Spec(True, "spin with rclpy's EventsExecutor (less CPU for the 500 Hz state; bool)", read_only=True),
}


def stamp_s(stamp: Any) -> float:
    return float(stamp.sec + stamp.nanosec * 1e-9)


class PayloadNode:
    """Follows mission/plan, mission/state, vehicle/status and the vehicle state; turns the
    CameraTrigger's captures into CaptureEvents, the per-flight CaptureLog and gimbal commands.
    The 500 Hz navigation/state is sampled at 50 Hz from a side node nobody spins (LatestSampler):
    a callback per sample cost this node ~10 % of a core (bench/graph_load.py, issue 16)."""

    def __init__(self, node: Any, side_node: Any, output_dir: Path) -> None:
        self.node, self.output_dir = node, output_dir
        self.plan: Plan | None = None
        self.mission: MissionState | None = None
        self.armed = False
        self.log: CaptureLog | None = None
        self.trigger = CameraTrigger()
        self.origin: GeoOrigin | None = None  # one object per home, so the trigger's path cache stays valid
        self.gimbal_t = 0.0
        self.pub_capture = node.create_publisher(CaptureEvent, m.CAPTURES.name, m.CAPTURES.qos)
        self.pub_gimbal = node.create_publisher(Vector3Stamped, m.GIMBAL.name, m.GIMBAL.qos)
        node.create_subscription(MissionPlan, m.MISSION_PLAN.name, self._on_plan, m.MISSION_PLAN.qos)
        node.create_subscription(MissionState, m.MISSION_STATE.name, self._on_mission, m.MISSION_STATE.qos)
        node.create_subscription(VehicleStatus, m.STATUS.name, self._on_status, m.STATUS.qos)
        self.state_sampler = LatestSampler(side_node, VehicleState, m.NAV_STATE.name, m.NAV_STATE.qos)
        self.state: VehicleState | None = None
        node.create_timer(STATE_PERIOD_S, self._sample_state)

    def _sample_state(self) -> None:
        sample = self.state_sampler.latest()
        if sample is not None and sample is not self.state:
            self.state = sample
            self._on_state(sample)

    def _on_plan(self, msg: MissionPlan) -> None:
        try:
            self.plan = plan_from_msg(msg)
        except PlanError as exc:
            self.node.get_logger().error(f"mission/plan unusable: {exc}")

    def _on_mission(self, msg: MissionState) -> None:
        self.mission = msg

    def _on_status(self, msg: VehicleStatus) -> None:
        if msg.armed and not self.armed:  # a new flight: new files, counting from 0
            stem = time.strftime("captures_%Y%m%dT%H%M%SZ", time.gmtime())
            self.log = CaptureLog(self.output_dir, stem)
            self.trigger = CameraTrigger()
            self.node.get_logger().info(f"capture log {self.log.geojson}")
        self.armed = msg.armed

    def _on_state(self, msg: VehicleState) -> None:
        mission, plan = self.mission, self.plan
        if mission is None or plan is None or mission.plan_id != plan.plan_id:
            return
        if mission.state != MissionStatus.ACTIVE or not self.armed or not msg.valid & VehicleState.VALID_ORIGIN:
            return
        origin = GeoOrigin(msg.origin.latitude, msg.origin.longitude, msg.origin.altitude)
        if self.origin != origin:
            self.origin = origin
        position = (msg.position.x, msg.position.y, msg.position.z)
        captures = self.trigger.update(plan, mission.current_item, mission.last_reached_item, position, self.origin)
        mode, _ = camera_mode(plan, mission.current_item)
        gimbal = Vector3Stamped()
        gimbal.header = msg.header
        gimbal.vector.y = -math.pi / 2 if mode != "off" else 0.0  # pitch down to nadir while surveying
        t = stamp_s(msg.header.stamp)
        if t - self.gimbal_t >= GIMBAL_PERIOD_S:
            self.gimbal_t = t
            self.pub_gimbal.publish(gimbal)
        for c in captures:
            self._publish_capture(c, msg, origin, gimbal.vector.y)

    def _publish_capture(self, c: Capture, msg: VehicleState, origin: GeoOrigin, gimbal_pitch: float) -> None:
        lat, lon, alt = origin.to_geodetic(*c.position)
        event = CaptureEvent(index=c.index, mission_item=c.mission_item, file_name=f"img_{c.index:05d}.jpg",
                             trigger=TRIGGERS[c.trigger])
        event.header = msg.header
        event.geodetic.latitude, event.geodetic.longitude, event.geodetic.altitude = lat, lon, alt
        event.position.x, event.position.y, event.position.z = c.position
        event.orientation = msg.orientation
        event.gimbal_rpy.y = gimbal_pitch
        self.pub_capture.publish(event)
        if self.log is not None:
            self.log.add(c, stamp_s(msg.header.stamp), lat, lon, alt, event.file_name)


def component(rclpy, host: Host) -> lifecycle.ManagedComponent:
    """The payload node as a component (c4d_ros.component): alone or composed with others."""
    node = lifecycle.create_node(rclpy, "payload")
    try:
        values = declare_all(node, PARAMETERS)
    except ParameterError as err:
        node.destroy_node()
        raise ComponentError(str(err)) from None

    def build() -> SpunNode:  # configure (c4d_ros.lifecycle)
        side = rclpy.create_node(m.side_node_name("payload"))
        return SpunNode("payload", node, bool(values["events_executor"]), 0,
                        PayloadNode(node, side, Path(values["output_dir"])), (side,))
    return lifecycle.ManagedComponent("payload", node, build, events_executor=bool(values["events_executor"]))


def main(argv: list[str] | None = None) -> int:
    return run_components([("payload", component)], argv, "payload", composed=False)


if __name__ == "__main__":
    sys.exit(main())
