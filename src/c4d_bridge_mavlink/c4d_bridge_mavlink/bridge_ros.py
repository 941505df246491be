"""The bridge's ROS side: subscriptions into the telemetry Snapshot, service calls for MAVLink
commands / missions / parameters, event messages (STATUSTEXT, MISSION_ITEM_REACHED,
CAMERA_TRIGGER), link statistics and the GCS heartbeat topic for health.

Why separate from bridge_node: the node is the loop; this is every ROS type in one place, so the
protocol modules stay ROS-free and the loop stays readable.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

from c4d_common.geodesy import GeoOrigin
from c4d_common.mavlink_items import ItemProblem, MavlinkItemError, item_from_mavlink, item_to_mavlink
from c4d_common.plan import Geofence, Plan, PlanError
from c4d_common.vehicle import CommandResult, FailsafeAction, Landed, Level, MissionAction, MissionStatus, UploadRefusal
from c4d_ros import manifest as topics
from c4d_ros.drain import LatestSampler

from .encoders import Snapshot
from .external_inputs import GnssSample, OdometrySample, PoseSample
from .fence import FenceItemsError, geofence_from_items, items_from_geofence
from .health_report import FailsafeAnnouncer
from .manual import PilotSetpoint
from .mission_protocol import FENCE, MISSION, WireItem
from .offboard import Target
from .params import ParamSpec
from .signing import mavlink
from .statustext import StatusTextChunker

M = mavlink
MISSION_STATE = {MissionStatus.NO_PLAN: M.MISSION_STATE_NO_MISSION, MissionStatus.READY: M.MISSION_STATE_NOT_STARTED,
                 MissionStatus.ACTIVE: M.MISSION_STATE_ACTIVE, MissionStatus.PAUSED: M.MISSION_STATE_PAUSED,
                 MissionStatus.COMPLETED: M.MISSION_STATE_COMPLETE, MissionStatus.ABORTED: M.MISSION_STATE_PAUSED}
WIRE_FRAME = {M.MAV_FRAME_GLOBAL_RELATIVE_ALT: M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT}  # downloads use the _INT frames
ITEM_RESULT = {ItemProblem.FRAME: M.MAV_MISSION_UNSUPPORTED_FRAME, ItemProblem.COMMAND: M.MAV_MISSION_UNSUPPORTED,
               ItemProblem.VALUE: M.MAV_MISSION_INVALID}  # MISSION_ACK type for an item the plan cannot take
# MISSION_ACK type for a plan the mission node refused: ERROR ("not accepting mission commands right now")
# when the same upload may pass later (no home / battery state yet), DENIED while a plan runs.
FENCE_WATCH_S = 0.1  # [s] the position is judged against the fence this often (FENCE_STATUS's breach count)
UPLOAD_REFUSAL_RESULT = {UploadRefusal.NO_HOME: M.MAV_MISSION_ERROR, UploadRefusal.BATTERY_UNKNOWN: M.MAV_MISSION_ERROR,
                         UploadRefusal.MISSION_ACTIVE: M.MAV_MISSION_DENIED, UploadRefusal.INVALID: M.MAV_MISSION_INVALID}


def target_to_msg(t: Target):
    """offboard.Target → c4d_interfaces/GuidanceSetpoint in `map` (header stamp left to the caller)."""
    from c4d_interfaces.msg import GuidanceSetpoint

    out = GuidanceSetpoint(control_level=int(t.level), yaw=t.yaw, yaw_rate=t.yaw_rate, thrust=t.thrust,
                           max_horizontal_speed=math.nan, max_vertical_speed=math.nan)
    out.header.frame_id = "map"
    out.position.x, out.position.y, out.position.z = t.position
    out.velocity.x, out.velocity.y, out.velocity.z = t.velocity
    out.acceleration.x, out.acceleration.y, out.acceleration.z = t.acceleration
    out.orientation.w, out.orientation.x, out.orientation.y, out.orientation.z = t.orientation
    out.body_rate.x, out.body_rate.y, out.body_rate.z = t.body_rate
    return out


def target_from_msg(m) -> Target | None:
    """c4d_interfaces/GuidanceSetpoint → offboard.Target (None for an unknown level)."""
    try:
        level = Level(m.control_level)
    except ValueError:
        return None
    o = m.orientation
    return Target(level, (m.position.x, m.position.y, m.position.z), (m.velocity.x, m.velocity.y, m.velocity.z),
                  (m.acceleration.x, m.acceleration.y, m.acceleration.z), m.yaw, m.yaw_rate, (o.w, o.x, o.y, o.z),
                  (m.body_rate.x, m.body_rate.y, m.body_rate.z), m.thrust)


def failsafe_action(name: str) -> FailsafeAction:
    """health/summary's failsafe value (an action name) as the enum; unknown names count as NONE."""
    return FailsafeAction.__members__.get(name, FailsafeAction.NONE)


@dataclass
class Reported:
    """What the GCS was last told, so that events are sent once per change."""

    reached: int = -1  # last MISSION_ITEM_REACHED
    dead: str = ""  # dead nodes of the last "node lost" STATUSTEXT


class RosSide:
    def __init__(self, node) -> None:
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
        from geometry_msgs.msg import PoseWithCovarianceStamped
        from nav_msgs.msg import Odometry
        from rclpy.executors import SingleThreadedExecutor
        from sensor_msgs.msg import BatteryState, NavSatFix
        from std_msgs.msg import Header

        from c4d_interfaces.msg import (
            CaptureEvent,
            EstimatorStatus,
            ExecutorStats,
            GuidanceSetpoint,
            MissionPlan,
            MissionState,
            Surroundings,
            VehicleState,
            VehicleStatus,
        )
        from c4d_interfaces.msg import Geofence as GeofenceMsg
        from c4d_interfaces.srv import MissionControl, SetGeofence, UploadMission, VehicleCommand

        self.node = node
        self.snapshot = Snapshot(boot_s=time.monotonic())
        side = rclpy.create_node(topics.side_node_name(node.get_name()))
        self.state = LatestSampler(side, VehicleState, topics.NAV_STATE.name, topics.NAV_STATE.qos)
        self.surroundings = LatestSampler(side, Surroundings, topics.SURROUNDINGS.name, topics.SURROUNDINGS.qos)
        self.surroundings_seen: object = None
        for msg_type, topic, callback in (
                (VehicleStatus, topics.STATUS, self._on_status), (BatteryState, topics.BATTERY, self._on_battery),
                (NavSatFix, topics.P_GPS, self._on_gps), (MissionState, topics.MISSION_STATE, self._on_mission),
                (MissionPlan, topics.MISSION_PLAN, self._on_plan), (DiagnosticStatus, topics.HEALTH_SUMMARY, self._on_health),
                (CaptureEvent, topics.CAPTURES, self._on_capture), (ExecutorStats, topics.EXECUTOR_STATS, self._on_stats),
                (DiagnosticArray, topics.P_HEALTH, self._on_sensors), (GeofenceMsg, topics.GEOFENCE, self._on_fence),
                (EstimatorStatus, topics.NAV_STATUS, self._on_nav_status)):
            node.create_subscription(msg_type, topic.name, callback, topic.qos)
        self.pub_heartbeat = node.create_publisher(Header, topics.GCS_HEARTBEAT.name, topics.GCS_HEARTBEAT.qos)
        self.pub_pilot = node.create_publisher(GuidanceSetpoint, topics.PILOT_SETPOINT.name, topics.PILOT_SETPOINT.qos)
        self.pub_offboard = node.create_publisher(GuidanceSetpoint, topics.OFFBOARD_TRAJECTORY.name,
                                                  topics.OFFBOARD_TRAJECTORY.qos)
        node.create_subscription(GuidanceSetpoint, topics.OFFBOARD_SETPOINT.name, self._on_offboard,
                                 topics.OFFBOARD_SETPOINT.qos)
        self.pub_stats = node.create_publisher(DiagnosticArray, topics.LINK_STATS.name, topics.LINK_STATS.qos)
        # MAVLink position inputs (external_inputs.py); created always (the manifest names the bridge a producer)
        self.pub_ext_pose = node.create_publisher(PoseWithCovarianceStamped, topics.EXTERNAL_POSE.name,
                                                  topics.EXTERNAL_POSE.qos)
        self.pub_ext_odometry = node.create_publisher(Odometry, topics.EXTERNAL_ODOMETRY.name, topics.EXTERNAL_ODOMETRY.qos)
        self.pub_ext_gnss = node.create_publisher(NavSatFix, topics.EXTERNAL_GNSS.name, topics.EXTERNAL_GNSS.qos)
        self.PoseWithCovarianceStamped, self.Odometry, self.NavSatFix = PoseWithCovarianceStamped, Odometry, NavSatFix
        self.external_frame_id = "odom"
        self.vehicle = node.create_client(VehicleCommand, topics.VEHICLE_COMMAND.name)
        self.upload = node.create_client(UploadMission, topics.MISSION_UPLOAD.name)
        self.control = node.create_client(MissionControl, topics.MISSION_CONTROL.name)
        self.set_fence = node.create_client(SetGeofence, topics.SET_GEOFENCE.name)
        self.SetGeofence = SetGeofence
        self.param_clients: dict[str, object] = {}
        self.get_clients: dict[str, object] = {}
        self.live_nodes: list[str] = []  # nodes with live MAVLink parameters (their values are read once up)
        self.live_asked: set[str] = set()
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(node)
        self.Header, self.DiagnosticArray, self.DiagnosticStatus = Header, DiagnosticArray, DiagnosticStatus
        self.VehicleCommand, self.UploadMission, self.MissionControl = VehicleCommand, UploadMission, MissionControl
        self.last = Reported()
        self.failsafes = FailsafeAnnouncer()
        self.active_fence = Geofence()  # geofence/active: the fence in force (downloads, FENCE_STATUS)
        self.fence_uploaded = False  # a GCS set the fence: MAVLink plans fly under it (they bring none)
        self.fence_checked = -math.inf
        self.plan_msg = None
        self.pending_params: list[tuple[ParamSpec, float]] = []
        self.router = self.missions = self.params = None
        self.texts = StatusTextChunker()

    def bind(self, router, missions, params) -> None:
        self.router, self.missions, self.params = router, missions, params
        self.pending_params = [(spec, params.get(spec.name)) for spec in params.table  # persisted: push once up
                               if spec.node and not spec.live and params.get(spec.name) != spec.default]
        self.live_nodes = sorted({spec.node for spec in params.table if spec.live})
        from rcl_interfaces.msg import ParameterEvent

        self.node.create_subscription(ParameterEvent, "/parameter_events", self._on_parameter_event, 100)

    # ------------------------------------------------------------------ loop hooks
    def spin_once(self) -> None:
        self.executor.spin_once(timeout_sec=0.0)

    def tick(self, now: float) -> None:
        s = self.state.latest()
        if s is not None:
            from c4d_interfaces.msg import VehicleState

            snap = self.snapshot
            snap.position = (s.position.x, s.position.y, s.position.z)
            snap.velocity = (s.velocity.x, s.velocity.y, s.velocity.z)
            snap.angular_velocity = (s.angular_velocity.x, s.angular_velocity.y, s.angular_velocity.z)
            snap.valid_attitude = bool(s.valid & VehicleState.VALID_ATTITUDE)
            snap.valid_position = bool(s.valid & VehicleState.VALID_POSITION_XY)
            nav, cov = snap.navigation, s.position_covariance
            nav.state_heard, nav.valid = True, s.valid
            nav.sigma_h = math.sqrt(0.5 * (cov[0] + cov[4])) if cov[0] > 0 and cov[4] > 0 else math.nan
            nav.sigma_v = math.sqrt(cov[8]) if cov[8] > 0 else math.nan
            q = s.orientation
            snap.orientation = (q.w, q.x, q.y, q.z) if snap.valid_attitude else None
            if s.valid & VehicleState.VALID_GLOBAL:
                snap.global_position = (s.geodetic.latitude, s.geodetic.longitude, s.geodetic.altitude)
            if s.valid & VehicleState.VALID_ORIGIN:
                home = (s.origin.latitude, s.origin.longitude, s.origin.altitude)
                if snap.home != home:
                    snap.home = home
                    snap.fence.set_fence(self.active_fence, GeoOrigin(*home))
                    if self.plan_msg is not None:
                        self._on_plan(self.plan_msg)  # local items can now become global
        around = self.surroundings.latest()
        if around is not None and around is not self.surroundings_seen:
            self.surroundings_seen = around
            self.snapshot.obstacles = tuple((o.position.x, o.position.y, float(o.radius)) for o in around.obstacles)
            self.snapshot.obstacles_t = now
        if now - self.fence_checked >= FENCE_WATCH_S:
            self.fence_checked = now
            snap = self.snapshot
            snap.fence.update(snap.position, snap.armed and snap.landed_state == Landed.IN_AIR, now)
        if self.pending_params:
            for spec, value in list(self.pending_params):
                if self._param_client(spec.node).service_is_ready():
                    self.set_node_parameters(spec.node, [(spec, value)], lambda results: None)
                    self.pending_params.remove((spec, value))
        for node_name in self.live_nodes:
            if node_name not in self.live_asked:
                self._read_live(node_name)
        if self.params is not None:
            self.params.pump(now)

    def shutdown(self) -> None:
        """Stop the private executor and destroy the node; the rclpy context is the process runner's."""
        self.executor.shutdown()
        self.node.destroy_node()

    # ------------------------------------------------------------------ topics in
    def _on_status(self, msg) -> None:
        s = self.snapshot
        s.armed, s.flight_mode, s.nav_state, s.landed_state = msg.armed, msg.flight_mode, msg.nav_state, msg.landed_state
        s.status_known = True

    def _on_nav_status(self, msg) -> None:
        """navigation/status: the fused sources and the GNSS integrity verdict (ESTIMATOR_STATUS)."""
        nav = self.snapshot.navigation
        nav.status_heard, nav.horizontal_source, nav.height_source = True, msg.horizontal_source, msg.height_source
        nav.gnss_state, nav.gnss_score = msg.gnss.state, msg.gnss.score

    def _on_offboard(self, msg) -> None:
        """guidance/offboard (the gateway's validated stream): echoed as POSITION_TARGET_LOCAL_NED."""
        self.snapshot.offboard_target = target_from_msg(msg)
        self.snapshot.offboard_target_t = time.monotonic()

    def _on_sensors(self, msg) -> None:
        """perception/health: one status per sensor, OK or not (SYS_STATUS sensor bits)."""
        for status in msg.status:
            self.snapshot.health.sensor_ok[status.hardware_id] = status.level == self.DiagnosticStatus.OK

    def _on_battery(self, msg) -> None:
        s = self.snapshot
        s.battery_voltage, s.battery_current = msg.voltage, msg.current
        s.battery_remaining = msg.percentage
        if math.isfinite(msg.capacity) and math.isfinite(msg.charge):
            s.battery_consumed_mah = max(0.0, (msg.capacity - msg.charge) * 1000.0)

    def _on_gps(self, msg) -> None:
        fix = M.GPS_FIX_TYPE_3D_FIX if msg.status.status >= 0 else M.GPS_FIX_TYPE_NO_FIX
        eph = math.sqrt(msg.position_covariance[0]) if msg.position_covariance[0] > 0 else math.nan
        epv = math.sqrt(msg.position_covariance[8]) if msg.position_covariance[8] > 0 else math.nan
        self.snapshot.gps = (msg.latitude, msg.longitude, msg.altitude, fix, eph, epv)

    def _on_stats(self, msg) -> None:
        self.snapshot.load = msg.load_mean_percent / 100.0

    def _on_mission(self, msg) -> None:
        s = self.snapshot
        if self.missions is not None:  # the GCS's numbering (a home row it uploaded counts)
            self.missions.active_plan_id = msg.plan_id
        wire = (lambda i: self.missions.wire_seq(msg.plan_id, i)) if self.missions is not None else (lambda i: i)
        s.mission_current, s.mission_total = wire(msg.current_item), wire(msg.total_items)
        s.mission_state, s.mission_known = MISSION_STATE.get(msg.state, 0), True
        if msg.last_reached_item >= 0 and msg.last_reached_item != self.last.reached and self.router:
            self.router.send(M.MAVLink_mission_item_reached_message(wire(msg.last_reached_item)))
        self.last.reached = msg.last_reached_item

    def _on_plan(self, msg) -> None:
        """The active plan, as the MISSION (and FENCE) items a download returns."""
        from c4d_ros.plan_msgs import plan_from_msg

        self.plan_msg = msg
        if self.missions is None:
            return
        home = GeoOrigin(*self.snapshot.home) if self.snapshot.home else None
        try:
            plan = plan_from_msg(msg)
            items = []
            for item in plan.items:
                command, frame, params = item_to_mavlink(item, home)
                items.append(WireItem(command, WIRE_FRAME.get(frame, frame), tuple(params)))
        except PlanError as exc:
            self.node.get_logger().warning(f"active plan not downloadable yet: {exc}")
            return
        self.missions.stored[MISSION] = items

    def _on_fence(self, msg) -> None:
        """geofence/active: what a FENCE download returns and what FENCE_STATUS judges."""
        from c4d_ros.plan_msgs import geofence_from_msg

        try:
            fence = geofence_from_msg(msg)
        except PlanError as exc:  # the mission node validates what it publishes: never expected
            self.node.get_logger().error(f"{topics.GEOFENCE.name} unusable: {exc}")
            return
        self.active_fence = fence
        if self.missions is not None:
            self.missions.stored[FENCE] = items_from_geofence(fence)
        self.snapshot.fence.set_fence(fence, GeoOrigin(*self.snapshot.home) if self.snapshot.home else None)

    def _on_health(self, msg) -> None:
        values = {kv.key: kv.value for kv in msg.values}
        failsafe, dead = values.get("failsafe", FailsafeAction.NONE.name), values.get("dead_nodes", "")
        action = failsafe_action(failsafe)
        self.snapshot.failsafe = action
        self.snapshot.health.on_summary(values)
        said = self.failsafes.update(action, values.get("reason", ""))
        if said is not None:
            self.statustext(said.severity, said.text)
        if dead != self.last.dead and dead:
            self.statustext(M.MAV_SEVERITY_ERROR, f"node lost: {dead}")
        self.last.dead = dead

    def _on_capture(self, msg) -> None:
        if self.router:
            stamp_us = msg.header.stamp.sec * 1_000_000 + msg.header.stamp.nanosec // 1000
            self.router.send(M.MAVLink_camera_trigger_message(stamp_us, msg.index))

    # ------------------------------------------------------------------ MAVLink out
    def statustext(self, severity: int, text: str) -> None:
        if self.router:
            for chunk in self.texts.messages(severity, text):  # whole, in MAVLink 2 chunks when long
                self.router.send(chunk)

    def ack(self, msg, result: int, reason: str = "", command: int | None = None) -> None:
        """COMMAND_ACK to the sender of `msg` (for `command`; default its own), the reason as STATUSTEXT."""
        self.router.send(M.MAVLink_command_ack_message(msg.command if command is None else command, result, 0, 0,
                                                       msg.get_srcSystem(), msg.get_srcComponent()))
        if reason and result != M.MAV_RESULT_ACCEPTED:
            self.statustext(M.MAV_SEVERITY_WARNING, reason)

    def gcs_heartbeat(self) -> None:
        h = self.Header()
        h.stamp = self.node.get_clock().now().to_msg()
        h.frame_id = "gcs"
        self.pub_heartbeat.publish(h)

    def publish_link_stats(self, router, schedulers, link, now: float, offboard=None, external=None) -> None:
        from diagnostic_msgs.msg import KeyValue

        array = self.DiagnosticArray()
        array.header.stamp = self.node.get_clock().now().to_msg()
        status_t = self.DiagnosticStatus
        array.status.append(status_t(level=status_t.OK if link.up else status_t.WARN, name="bridge/link",
                                     hardware_id="gcs", message="GCS link up" if link.up else "no GCS heartbeat",
                                     values=[KeyValue(key="losses", value=str(link.losses)),
                                             KeyValue(key="since_heartbeat_s", value=f"{link.since_heartbeat_s or -1:.2f}")]))
        if offboard is not None:  # offboard.OffboardDecoder: MAVLink setpoints used / dropped per reason
            counts = {"accepted": offboard.accepted, **{f"rejected_{k}": v for k, v in sorted(offboard.rejected.items())}}
            array.status.append(status_t(level=status_t.OK, name="bridge/offboard", hardware_id="mavlink",
                                         message=f"{offboard.accepted} setpoints, {offboard.rejected.total()} dropped",
                                         values=[KeyValue(key=k, value=str(v)) for k, v in counts.items()]))
        if external is not None:  # external_inputs.ExternalInputs: position inputs forwarded / dropped per reason
            counts = external.stats()
            array.status.append(status_t(level=status_t.OK, name="bridge/external", hardware_id="mavlink",
                                         message=f"{external.accepted.total()} position inputs, "
                                                 f"{external.rejected.total()} dropped",
                                         values=[KeyValue(key=k, value=v) for k, v in counts.items()]))
        for name, endpoint in router.endpoints.items():
            st, ls = endpoint.stats, schedulers[name].link_stats(now)
            worst = max((r.max_delay_ratio for r in schedulers[name].stream_stats()), default=0.0)
            values = {"rx_bytes": st.rx_bytes, "tx_bytes": st.tx_bytes, "rx_frames": st.rx_frames, "tx_frames": st.tx_frames,
                      "rx_errors": st.rx_errors, "unsigned_rejected": st.errors.get("unsigned", 0),
                      "bad_signature": st.errors.get("bad_signature", 0), "junk_datagrams": st.junk,
                      "telemetry_bytes_s": f"{ls.bytes_per_second:.0f}",
                      "utilisation": f"{ls.utilisation:.3f}", "queue_drops": ls.dropped,
                      "max_delay_ratio": f"{worst:.3f}", "queue_max_bytes": ls.queue_max_bytes}
            array.status.append(status_t(level=status_t.OK, name=f"bridge/endpoint {name}", hardware_id=name,
                                         message="ok", values=[KeyValue(key=k, value=str(v)) for k, v in values.items()]))
        self.pub_stats.publish(array)

    # ------------------------------------------------------------------ services
    def _call(self, client, request, done) -> None:
        if not client.service_is_ready():
            done(None)
            return
        client.call_async(request).add_done_callback(lambda f: done(f.result()))

    def vehicle_command(self, fields: dict, ack) -> None:
        from c4d_interfaces.msg import GeoPoint

        req = self.VehicleCommand.Request(command=fields["command"], altitude=float(fields.get("altitude", 0.0)),
                                           mode=int(fields.get("mode", 0)), force=bool(fields.get("force", False)),
                                           yaw=float(fields.get("yaw", math.nan)))
        if "latitude" in fields:
            alt = fields["altitude"] if math.isfinite(fields["altitude"]) else self.snapshot.position[2]
            req.target = GeoPoint(latitude=fields["latitude"], longitude=fields["longitude"], altitude=float(alt))
        self._call(self.vehicle, req, lambda r: ack(M.MAV_RESULT_TEMPORARILY_REJECTED, "mission node not reachable")
                   if r is None else ack(r.result, r.message))

    def mission_control(self, fields: dict, ack) -> None:
        item = int(fields.get("item", 0))
        if fields["action"] == MissionAction.START and self.missions is not None:
            item = self.missions.plan_index(item)  # MISSION_START's first item counts an uploaded home row
        item = max(0, item)
        self._call(self.control, self.MissionControl.Request(action=fields["action"], item=item),
                   lambda r: ack(M.MAV_RESULT_TEMPORARILY_REJECTED, "mission node not reachable") if r is None
                   else ack(r.result, r.message))

    def _param_fence(self) -> Geofence:
        p = self.params
        return Geofence((), p.get("GF_MAX_VER_DIST"), p.get("GF_MAX_HOR_DIST"))

    def upload_fence(self, items: list[WireItem]) -> None:
        """A complete FENCE upload: the fence (items + GF_MAX_VER_DIST / GF_MAX_HOR_DIST) replaces the
        one in force at once through geofence/set (in flight too); the mission node's verdict is the
        MISSION_ACK, a refusal's reason a STATUSTEXT (fence.py for the items)."""
        finish = self.missions.finish_upload
        limits = self._param_fence()
        try:
            fence = geofence_from_items(items, limits.max_altitude, limits.max_distance)
        except FenceItemsError as exc:
            self.statustext(M.MAV_SEVERITY_WARNING, f"fence rejected: {exc}")
            return finish(exc.result)

        def verdict(reply) -> None:
            if reply is None:
                self.statustext(M.MAV_SEVERITY_WARNING, "fence rejected: mission node not reachable")
                return finish(M.MAV_MISSION_ERROR)
            if reply.result != CommandResult.ACCEPTED:
                self.statustext(M.MAV_SEVERITY_WARNING, f"fence rejected: {reply.message}")
                return finish(M.MAV_MISSION_DENIED)
            self.fence_uploaded = True
            if ";" in reply.message:  # a leg the new fence blocks was stopped (mission paused)
                self.statustext(M.MAV_SEVERITY_WARNING, reply.message.split(";", 1)[1].strip())
            finish(M.MAV_MISSION_ACCEPTED)

        from c4d_ros.plan_msgs import geofence_to_msg

        self._call(self.set_fence, self.SetGeofence.Request(fence=geofence_to_msg(fence)), verdict)

    def upload_mission(self, mission_type: int, items: list[WireItem]) -> None:
        """Complete upload from a GCS: FENCE items replace the fence in force (upload_fence); MISSION
        items become a plan validated by the mission node, whose verdict is the MISSION_ACK."""
        finish = self.missions.finish_upload
        if mission_type == FENCE:
            return self.upload_fence(items)
        if not items:
            if self.snapshot.mission_state == M.MISSION_STATE_ACTIVE:
                return finish(M.MAV_MISSION_DENIED)
            return self.mission_control({"action": MissionAction.CLEAR}, lambda r, reason="": finish(
                M.MAV_MISSION_ACCEPTED if r == CommandResult.ACCEPTED else M.MAV_MISSION_DENIED))
        home_alt = self.snapshot.home[2] if self.snapshot.home else None
        try:
            plan_items = tuple(item_from_mavlink(i.command, i.frame, i.params, home_alt, where=f"item {k + 1}")
                               for k, i in enumerate(items))
        except MavlinkItemError as exc:
            self.statustext(M.MAV_SEVERITY_WARNING, str(exc))
            return finish(ITEM_RESULT[exc.problem])
        p = self.params
        # after a fence upload the plan brings no fence: it flies under the uploaded one (mission fence.py)
        plan = Plan(plan_items, Geofence() if self.fence_uploaded else self._param_fence(), "mavlink",
                    p.get("MPC_XY_CRUISE"), p.get("RTL_RETURN_ALT"))
        from c4d_ros.plan_msgs import plan_to_msg

        def verdict(reply) -> None:
            if reply is None:
                self.statustext(M.MAV_SEVERITY_WARNING, "mission node not reachable")
                return finish(M.MAV_MISSION_ERROR)
            if not reply.accepted:
                self.statustext(M.MAV_SEVERITY_WARNING, reply.errors[0] if reply.errors else "mission rejected")
                return finish(UPLOAD_REFUSAL_RESULT.get(UploadRefusal(reply.refusal), M.MAV_MISSION_INVALID))
            finish(M.MAV_MISSION_ACCEPTED, reply.plan_id)

        self._call(self.upload, self.UploadMission.Request(plan=plan_to_msg(plan)), verdict)

    def clear_mission(self, mission_type: int) -> int:
        if mission_type in (MISSION, M.MAV_MISSION_TYPE_ALL):
            if self.snapshot.mission_state == M.MISSION_STATE_ACTIVE:
                return M.MAV_MISSION_DENIED
            self.mission_control({"action": MissionAction.CLEAR}, lambda r, reason="": None)
        if mission_type in (FENCE, M.MAV_MISSION_TYPE_ALL):  # the fence in force: the GF_* limits alone
            def done(reply) -> None:
                if reply is None or reply.result != CommandResult.ACCEPTED:
                    self.statustext(M.MAV_SEVERITY_WARNING, "fence not cleared: " +
                                    ("mission node not reachable" if reply is None else reply.message))
            from c4d_ros.plan_msgs import geofence_to_msg

            self.fence_uploaded = True
            self._call(self.set_fence, self.SetGeofence.Request(fence=geofence_to_msg(self._param_fence())), done)
        return M.MAV_MISSION_ACCEPTED

    def set_current_item(self, seq: int) -> bool:
        if not 0 <= seq < len(self.missions.stored[MISSION]):
            return False
        self.mission_control({"action": MissionAction.SET_CURRENT, "item": seq}, lambda r, reason="": None)
        return True

    def _param_client(self, node_name: str):
        from rcl_interfaces.srv import SetParameters

        if node_name not in self.param_clients:
            self.param_clients[node_name] = self.node.create_client(SetParameters, f"{node_name}/set_parameters")
        return self.param_clients[node_name]

    def set_node_parameters(self, node_name: str, entries: list[tuple[ParamSpec, float]], done) -> None:
        """Set the ROS parameters behind MAVLink `entries` on `node_name` in one request; done(one
        (ok, reason) per entry) — an entry mapped onto several ROS parameters is ok when all are — or
        done(None) when the node does not answer."""
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter

        params = [Parameter(ros, value=float(value)).to_parameter_msg() for spec, value in entries for ros in spec.ros_names]
        request = SetParameters.Request(parameters=params)

        def answered(reply) -> None:
            if reply is None or len(reply.results) != len(params):
                return done(None)
            results, k = [], 0
            for spec, _ in entries:
                own = reply.results[k:k + len(spec.ros_names)]
                k += len(spec.ros_names)
                refused = [r.reason for r in own if not r.successful]
                results.append((not refused, "; ".join(refused)))
            done(results)

        self._call(self._param_client(node_name), request, answered)

    def _read_live(self, node_name: str) -> None:
        """The live parameters' values in force on `node_name` (once its service is up)."""
        from rcl_interfaces.srv import GetParameters
        from rclpy.parameter import parameter_value_to_python

        if node_name not in self.get_clients:
            self.get_clients[node_name] = self.node.create_client(GetParameters, f"{node_name}/get_parameters")
        client = self.get_clients[node_name]
        if not client.service_is_ready():
            return
        self.live_asked.add(node_name)
        names = self.params.live_names(node_name)

        def answered(reply) -> None:
            if reply is None or len(reply.values) != len(names):
                self.live_asked.discard(node_name)  # ask again
                return
            values = zip(names, reply.values, strict=True)
            self.params.node_values(node_name, {n: parameter_value_to_python(v) for n, v in values})

        self._call(client, GetParameters.Request(names=names), answered)

    def _on_parameter_event(self, event) -> None:
        from rclpy.parameter import parameter_value_to_python

        if self.params is None:
            return
        node_name = event.node.lstrip("/")
        if node_name in self.live_nodes:
            self.params.node_values(node_name, {p.name: parameter_value_to_python(p.value) for p in event.changed_parameters},
                                    announce=True)

    def publish_offboard(self, target: Target) -> None:
        """A MAVLink offboard setpoint (offboard.OffboardDecoder) on offboard/trajectory_setpoint,
        stamped now (receive time: MAVLink's time_boot_ms is the sender's clock)."""
        out = target_to_msg(target)
        out.header.stamp = self.node.get_clock().now().to_msg()
        self.pub_offboard.publish(out)

    def ros_now(self) -> float:
        """The node's clock now [s] (sim time in a simulated graph): external samples are stamped on it."""
        return self.node.get_clock().now().nanoseconds * 1e-9

    def _header(self, header, stamp: float) -> None:
        ns = max(0, int(round(stamp * 1e9)))
        header.stamp.sec, header.stamp.nanosec = ns // 1_000_000_000, ns % 1_000_000_000
        header.frame_id = self.external_frame_id

    @staticmethod
    def _fill_pose(pose, sample: PoseSample) -> None:
        """geometry_msgs/PoseWithCovariance from a PoseSample."""
        pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = sample.position
        o = pose.pose.orientation
        o.w, o.x, o.y, o.z = sample.orientation
        pose.covariance = list(sample.covariance)

    def publish_external_pose(self, sample: PoseSample) -> None:
        """VISION_POSITION_ESTIMATE / ATT_POS_MOCAP → navigation/external/pose."""
        out = self.PoseWithCovarianceStamped()
        self._header(out.header, sample.stamp)
        self._fill_pose(out.pose, sample)
        self.pub_ext_pose.publish(out)

    def publish_external_odometry(self, sample: OdometrySample) -> None:
        """ODOMETRY → navigation/external/odometry (twist in base_link, FLU)."""
        out = self.Odometry()
        self._header(out.header, sample.pose.stamp)
        out.child_frame_id = "base_link"
        self._fill_pose(out.pose, sample.pose)
        out.twist.twist.linear.x, out.twist.twist.linear.y, out.twist.twist.linear.z = sample.velocity
        out.twist.twist.angular.x, out.twist.twist.angular.y, out.twist.twist.angular.z = sample.angular_velocity
        out.twist.covariance = list(sample.twist_covariance)
        self.pub_ext_odometry.publish(out)

    def publish_external_gnss(self, sample: GnssSample) -> None:
        """GPS_INPUT → navigation/external/gnss."""
        out = self.NavSatFix()
        self._header(out.header, sample.stamp)
        out.header.frame_id = "gps"
        out.status.status, out.status.service = sample.status, out.status.SERVICE_GPS
        out.latitude, out.longitude, out.altitude = sample.latitude, sample.longitude, sample.altitude
        out.position_covariance = list(sample.covariance)
        out.position_covariance_type = sample.covariance_type
        self.pub_ext_gnss.publish(out)

    def publish_pilot(self, sp: PilotSetpoint) -> None:
        """A pilot setpoint (manual.PilotInput) as guidance/pilot at the ATTITUDE or RATE level."""
        from c4d_interfaces.msg import GuidanceSetpoint

        out = GuidanceSetpoint(control_level=GuidanceSetpoint.LEVEL_ATTITUDE if sp.level == "attitude" else
                               GuidanceSetpoint.LEVEL_RATE, yaw=math.nan, yaw_rate=float(sp.yaw_rate), thrust=float(sp.thrust),
                               max_horizontal_speed=math.nan, max_vertical_speed=math.nan)
        out.header.stamp = self.node.get_clock().now().to_msg()
        out.header.frame_id = "map"
        out.position.x = out.position.y = out.position.z = math.nan
        out.velocity.x = out.velocity.y = out.velocity.z = math.nan
        out.acceleration.x = out.acceleration.y = out.acceleration.z = math.nan
        out.orientation.w, out.orientation.x, out.orientation.y, out.orientation.z = sp.orientation
        out.body_rate.x, out.body_rate.y, out.body_rate.z = sp.body_rate
        self.pub_pilot.publish(out)
