"""`ros2 run c4d_mission mission` — mission management and command executor.

Services: mission/upload (validate item by item, then replace the plan atomically),
mission/download, mission/control (start, pause, resume, clear, set current), vehicle/command
(arm / take-off with pre-arm checks: estimator valid with home set, every sensor healthy,
battery above the reserve, inside the geofence; RTL and go-to (loiter at a global target,
checked against the geofence unless `force`) are flown by the mission node; disarm, land,
hold and set mode are forwarded to the core's gnc/command; once the core accepts, hold and set
mode pause the mission (resumed by mission/control resume), land and disarm abort it; a refused
command changes nothing). Publishes guidance/setpoint (50 Hz while a mission or RTL
flies, and only while the core is in AUTO: it owns no stream in OFFBOARD or a pilot mode),
mission/state (on change and at 5 Hz), mission/plan (latched) and geofence/active (latched: the
fence in force — the accepted plan's, or one set through the geofence/set service, which applies
at once in flight; rules in fence.py and docs/mission.md). Mode changes reach the core only
through its latched gnc/command interface.
Parameters: plan_file (loaded and validated once home is known), min_battery (0.2),
takeoff_altitude (2.5 m: least take-off altitude of a plan without a take-off item),
hover_current_a (endurance estimate, 20 A), state_file (the mission journal: plan, progress and
the fence in force persisted on every change, so a restarted node resumes an active mission and
republishes the fence; empty: none).

The node only maps ROS to logic: pre-arm checks (prearm.PreArmChecks), command arbitration and
plan acceptance (arbitration.CommandArbiter), plan execution (executor.MissionExecutor), the
journal and the resume decision after a restart (mission_journal).
"""

from __future__ import annotations

import math
import sys
import time
from functools import partial
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from sensor_msgs.msg import BatteryState

from c4d_common import quat
from c4d_common.geodesy import GeoOrigin
from c4d_common.geofence import LocalFence
from c4d_common.plan import Plan, PlanError
from c4d_common.plan_files import load_plan
from c4d_common.plan_validation import VehicleLimits, flight_time_left
from c4d_common.vehicle import (
    Command,
    CommandResult,
    FailsafeAction,
    Landed,
    MissionStatus,
    Mode,
    UploadRefusal,
    VehicleCommandId,
)
from c4d_interfaces.msg import (
    EstimatorStatus,
    GnssIntegrity,
    GuidanceSetpoint,
    MissionPlan,
    MissionState,
    VehicleState,
    VehicleStatus,
)
from c4d_interfaces.msg import Geofence as GeofenceMsg
from c4d_interfaces.srv import DownloadMission, MissionControl, SetGeofence, UploadMission, VehicleCommand
from c4d_ros import lifecycle
from c4d_ros import manifest as m
from c4d_ros.component import ComponentError, Host, SpunNode, run_components
from c4d_ros.drain import LatestSampler
from c4d_ros.params import ParameterError, Spec, declare_all
from c4d_ros.plan_msgs import geofence_from_msg, geofence_to_msg, plan_from_msg, plan_to_msg
from c4d_ros.stamps import s_to_stamp

from .arbitration import Acceptance, CommandArbiter, Decision, VehicleView, goto_target
from .executor import Checkpoint, MissionExecutor, Vehicle
from .fence import FenceSource
from .mission_journal import JournalEntry, JournalError, MissionJournal, VehicleCheck, resume_status
from .prearm import PreArmChecks, PreArmInputs

UNTRUSTED_GNSS = {GnssIntegrity.STATE_SPOOFED: "spoofed", GnssIntegrity.STATE_JAMMED: "jammed"}
SOURCE_SENSORS = {VehicleState.SOURCE_GNSS: "gps", VehicleState.SOURCE_BARO: "baro"}  # source -> sensor name

TICK_S = 0.02  # guidance rate 50 Hz
STATE_HEARTBEAT_S = 0.2  # mission/state also at 5 Hz when nothing changes (health's liveness)
STATUS_WARN_S = 3.0  # after a restart, a journalled plan still waiting for vehicle/status is reported after this long
PARAMETERS = {
    "plan_file": Spec("", "plan loaded and validated once home is known (c4d YAML or QGC .plan path; empty: none)",
                      read_only=True),
    "min_battery": Spec(0.2, "remaining charge below which ARM / TAKEOFF is refused [fraction 0..1]", 0.0, 1.0,
                        read_only=True),
    "takeoff_altitude": Spec(2.5, "take-off before a waypoint flown from the ground (a plan without a take-off item): "
                             "to the waypoint's altitude, at least this (PX4 MIS_TAKEOFF_ALT) [m above home]", 0.5, 120.0,
                             read_only=True),
    "hover_current_a": Spec(20.0, "hover current for the plan's endurance estimate [A]", 0.1, 1000.0, read_only=True),
    "state_file": Spec("", "mission journal: plan and progress, resumed after a restart [file path]; empty: no persistence",
                       read_only=True),
}


class MissionNode:
    """mission/* and vehicle/command services, guidance/setpoint and mission/state publishers over
    the ROS-free PreArmChecks and CommandArbiter."""

    def __init__(self, node: Any, side_node: Any, plan_file: str, min_battery: float, hover_current_a: float,
                 state_file: str = "", takeoff_altitude: float = 2.5) -> None:
        self.node, self.plan_file, self.hover_current_a = node, plan_file, hover_current_a
        self.prearm = PreArmChecks(min_battery)
        self.arbiter = CommandArbiter(VehicleLimits(takeoff_altitude=takeoff_altitude))
        self.state: VehicleState | None = None
        self.status: VehicleStatus | None = None
        self.battery: BatteryState | None = None
        self.sensor_ok: dict[str, bool] = {}  # perception/health: hardware id -> level OK
        self.nav_status: EstimatorStatus | None = None  # navigation/status: sources, GNSS integrity
        self.last_state_key: tuple[int, int, int, int] | None = None
        self.last_state_pub = 0.0
        self.journal = MissionJournal(state_file) if state_file else None
        self.journalled: Checkpoint | None = None  # the last checkpoint written
        self.journal_ok = True
        self.pending = self._read_journal()  # a plan to take back once home (and the vehicle status) is known
        self.status_warn_at: float | None = time.monotonic() + STATUS_WARN_S  # None once warned
        self.plan_file_tried = self.pending is not None and self.pending.plan is not None
        self.journalled_fence = self.arbiter.fence.revision  # the fence revision last written
        if self.pending is not None and self.pending.fence is not None:  # geodetic: in force at once, no home needed
            self.arbiter.fence.restore(*self.pending.fence)
            self.journalled_fence = self.arbiter.fence.revision
        self.published_fence = 0  # the fence revision last published on geofence/active
        self.pub_fence = node.create_publisher(GeofenceMsg, m.GEOFENCE.name, m.GEOFENCE.qos)
        self._publish_fence()
        self.pub_setpoint = node.create_publisher(GuidanceSetpoint, m.SETPOINT.name, m.SETPOINT.qos)
        self.pub_state = node.create_publisher(MissionState, m.MISSION_STATE.name, m.MISSION_STATE.qos)
        self.pub_plan = node.create_publisher(MissionPlan, m.MISSION_PLAN.name, m.MISSION_PLAN.qos)
        # its own callback group: the vehicle/command service awaits this client's response, which
        # a mutually exclusive (default) group would never run while the service callback is pending
        self.core = node.create_client(VehicleCommand, m.CORE_COMMAND.name, callback_group=ReentrantCallbackGroup())
        # 500 Hz: sampled at the 50 Hz tick instead of waking the executor for every sample
        self.state_sampler = LatestSampler(side_node, VehicleState, m.NAV_STATE.name, m.NAV_STATE.qos)
        self._subscribe()
        node.create_service(UploadMission, m.MISSION_UPLOAD.name, self._on_upload)
        node.create_service(DownloadMission, m.MISSION_DOWNLOAD.name, self._on_download)
        node.create_service(MissionControl, m.MISSION_CONTROL.name, self._on_control)
        node.create_service(VehicleCommand, m.VEHICLE_COMMAND.name, self._on_vehicle_command)
        node.create_service(SetGeofence, m.SET_GEOFENCE.name, self._on_set_geofence)
        node.create_timer(TICK_S, self._tick, callback_group=self.loop)

    def _subscribe(self) -> None:
        # the guidance tick and its inputs in a group of their own (issue 14.2): the default group is
        # held by a vehicle/command awaiting the core's answer, and sharing it froze guidance and the
        # mission/state heartbeat (health's liveness) for as long as the core took — for ever if lost
        self.loop = MutuallyExclusiveCallbackGroup()
        for msg_type, topic, handle in ((VehicleStatus, m.STATUS, partial(setattr, self, "status")),
                                        (BatteryState, m.BATTERY, partial(setattr, self, "battery")),
                                        (DiagnosticArray, m.P_HEALTH, self._on_health),
                                        (EstimatorStatus, m.NAV_STATUS, partial(setattr, self, "nav_status"))):
            self.node.create_subscription(msg_type, topic.name, handle, topic.qos, callback_group=self.loop)

    # ------------------------------------------------------------------ inputs
    def _now(self) -> float:
        return float(self.node.get_clock().now().nanoseconds * 1e-9)

    def _home(self) -> GeoOrigin | None:
        s = self.state
        if s is None or not s.valid & VehicleState.VALID_ORIGIN:
            return None
        return GeoOrigin(s.origin.latitude, s.origin.longitude, s.origin.altitude)

    def _position(self) -> tuple[float, float, float]:
        s = self.state
        return (s.position.x, s.position.y, s.position.z) if s is not None else (0.0, 0.0, 0.0)

    def _view(self) -> VehicleView:
        st = self.status
        landed = Landed(st.landed_state) if st is not None else Landed.UNDEFINED
        return VehicleView(self._home(), bool(st is not None and st.armed), landed, self._position())

    def _prearm_inputs(self) -> PreArmInputs:
        needed = VehicleState.VALID_ATTITUDE | VehicleState.VALID_POSITION_XY | VehicleState.VALID_ORIGIN
        ready = self.state is not None and self.state.valid & needed == needed
        home, active = self._home(), self.arbiter.fence.fence
        fence = LocalFence.from_geofence(active, home) if not active.empty and home is not None else None
        battery = self.battery.percentage if self.battery is not None else None
        return PreArmInputs(ready, self._position(), self.sensor_ok, battery, fence, self._unused_sensors(),
                            self._gnss_untrusted())

    def _gnss_untrusted(self) -> str:
        """The GNSS integrity verdict when it is spoofed or jammed and the estimate is not carried by an
        external source (navigation/status); "" otherwise."""
        s = self.nav_status
        if s is None or s.horizontal_source == VehicleState.SOURCE_EXTERNAL:
            return ""
        return UNTRUSTED_GNSS.get(s.gnss.state, "")

    def _unused_sensors(self) -> frozenset[str]:
        """The position sensors (perception/health hardware ids) the estimate is not fused from now
        (navigation/state's horizontal/height source): a GNSS-denied setup arms without a fix."""
        s = self.state
        if s is None:
            return frozenset()
        used = {s.horizontal_source, s.height_source}
        return frozenset(name for source, name in SOURCE_SENSORS.items() if source not in used)

    def _on_health(self, msg: Any) -> None:
        for status in msg.status:
            self.sensor_ok[status.hardware_id] = status.level == DiagnosticStatus.OK

    def _on_state(self, msg: Any) -> None:
        self.state = msg
        if self.plan_file and self.arbiter.mission.plan is None and self._home() is not None and not self.plan_file_tried \
                and self._endurance() is not None:  # validated in full: home and battery state known
            self.plan_file_tried = True
            try:
                verdict = self._accept(load_plan(self.plan_file))
                if verdict.errors:
                    self.node.get_logger().error(f"plan_file {self.plan_file} rejected: {'; '.join(map(str, verdict.errors))}")
            except PlanError as exc:
                self.node.get_logger().error(f"plan_file: {exc}")

    # ------------------------------------------------------------------ journal
    def _read_journal(self) -> JournalEntry | None:
        if self.journal is None:
            return None
        try:
            entry = self.journal.load()
        except JournalError as exc:
            self.node.get_logger().warning(f"mission journal unusable, starting clean: {exc}")
            return None
        return entry if entry is not None and (entry.plan is not None or entry.fence is not None) else None

    def _restore(self) -> bool:
        """Take back the journalled plan once home and the vehicle status are known; True when done.
        Resumes an active mission only if the vehicle still flies it (mission_journal.resume_status)."""
        entry, home, st = self.pending, self._home(), self.status
        if entry is None or entry.plan is None:
            return True
        if home is None or st is None:
            # Never judged blind: the vehicle still flying the plan is known only from its status
            # (latched by the core, which holds position meanwhile). Under load a restarted process
            # can take seconds to discover it; deciding without it paused a mission the vehicle
            # was still flying (CI, issue 14).
            if self.status_warn_at is not None and time.monotonic() >= self.status_warn_at:
                self.status_warn_at = None
                missing = " and ".join(n for n, v in (("home", home), (m.STATUS.name, st)) if v is None)
                self.node.get_logger().warning(f"journalled plan {entry.plan.plan_id} waits for {missing} "
                                               "before deciding whether to resume it")
            return False
        self.pending = None
        if self.arbiter.mission.plan is not None:  # a plan uploaded meanwhile is newer
            return True
        vehicle = VehicleCheck(bool(st.armed), Landed(st.landed_state), Mode(st.flight_mode), FailsafeAction(st.failsafe_action))
        verdict = resume_status(entry.checkpoint.status, vehicle)
        plan, k, n = entry.plan, entry.checkpoint.current, len(entry.plan.items)
        self.arbiter.restore(plan, home, entry.checkpoint, verdict.status)
        if entry.fence is None:  # a journal from before the fence was journalled: the plan's is in force
            self.arbiter.fence.plan_accepted(plan)
            self._publish_fence()
        self.pub_plan.publish(plan_to_msg(plan))
        log = self.node.get_logger()
        if verdict.resumed:
            log.info(f"resumed plan {plan.plan_id} '{plan.name}' at item {k}/{n} after restart")
        elif entry.checkpoint.status == MissionStatus.ACTIVE:
            log.warning(f"plan {plan.plan_id} '{plan.name}' restored at item {k}/{n} after restart, "
                        f"not resumed: {verdict.reason}; mission {verdict.status.name.lower()}")
        else:
            log.info(f"plan {plan.plan_id} '{plan.name}' restored after restart ({verdict.reason})")
        return True

    def _write_journal(self) -> None:
        """Persist the plan and progress when they changed since the last write (never per tick)."""
        mission, fence = self.arbiter.mission, self.arbiter.fence
        checkpoint = mission.checkpoint()
        if self.journal is None or (checkpoint == self.journalled and fence.revision == self.journalled_fence):
            return
        self.journalled_fence = fence.revision
        in_force = (fence.fence, fence.source) if fence.source != FenceSource.NONE else None
        try:
            self.journal.save(JournalEntry(mission.plan, checkpoint, in_force))
            self.journalled, self.journal_ok = checkpoint, True
        except OSError as exc:
            if self.journal_ok:  # once per failure streak, retried at the next change
                self.node.get_logger().warning(f"mission journal not written ({self.journal.path}): {exc}")
            self.journal_ok = False
            self.journalled = checkpoint

    def _publish_fence(self) -> None:
        """geofence/active (latched) once per change of the fence in force."""
        fence = self.arbiter.fence
        if fence.source == FenceSource.NONE or fence.revision == self.published_fence:
            return
        self.published_fence = fence.revision
        self.pub_fence.publish(geofence_to_msg(fence.fence))
        what = "cleared" if fence.fence.empty else "in force"
        self.node.get_logger().info(f"geofence {what} (from the {fence.source.value})")

    # ------------------------------------------------------------------ services
    def _endurance(self) -> float | None:
        """Flight time left [s] from the latest battery report (its charge, or percentage x capacity);
        None while no report has come (the arbiter then refuses plans: BATTERY_UNKNOWN)."""
        b = self.battery
        if b is None:
            return None
        charge = b.charge if math.isfinite(b.charge) else b.percentage * b.capacity
        return flight_time_left(charge, self.hover_current_a)

    def _accept(self, plan: Plan) -> Acceptance:
        """Offer `plan` to the arbiter; publish and log it when accepted."""
        verdict = self.arbiter.accept(plan, self._home(), self._endurance())
        if verdict.plan is not None and verdict.validation is not None:
            self.pub_plan.publish(plan_to_msg(verdict.plan))
            self.node.get_logger().info(
                f"plan {verdict.plan.plan_id} '{verdict.plan.name}' accepted: {len(verdict.plan.items)} items, "
                f"{verdict.validation.path_length:.0f} m, ~{verdict.validation.duration:.0f} s")
            self._publish_fence()
        return verdict

    def _on_upload(self, request: Any, response: Any) -> Any:
        try:
            plan = plan_from_msg(request.plan)
        except PlanError as exc:
            response.accepted, response.refusal, response.errors = False, int(UploadRefusal.INVALID), [str(exc)]
            return response
        verdict = self._accept(plan)
        response.errors, response.warnings = [str(e) for e in verdict.errors], [str(w) for w in verdict.warnings]
        response.accepted, response.refusal = verdict.plan is not None, int(verdict.refusal)
        mission = self.arbiter.mission
        response.plan_id = mission.plan.plan_id if response.accepted and mission.plan else 0
        if response.accepted and request.start:
            mission.start()
        return response

    def _on_download(self, request: Any, response: Any) -> Any:
        plan = self.arbiter.mission.plan
        response.has_plan = plan is not None
        if plan is not None:
            response.plan = plan_to_msg(plan)
        response.state = self._state_msg()
        return response

    def _on_control(self, request: Any, response: Any) -> Any:
        decision = self.arbiter.control(request.action, request.item)
        for command in decision.core:
            self._send_core(command)
        response.result, response.message = int(decision.result), decision.message
        response.state = self._state_msg()
        return response

    def _on_set_geofence(self, request: Any, response: Any) -> Any:
        """geofence/set: validate (malformed → refused with the reason), then the arbiter decides
        (vehicle outside → refused unless force; a blocked leg → HOLD); published at once."""
        try:
            fence = geofence_from_msg(request.fence)
        except PlanError as exc:
            response.result, response.message = int(CommandResult.DENIED), str(exc)
            self.node.get_logger().warning(f"geofence/set refused: {exc}")
            return response
        decision = self.arbiter.set_geofence(fence, bool(request.force), self._view())
        for command in decision.core:
            self._send_core(command)
        response.result, response.message = int(decision.result), decision.message
        if decision.result == CommandResult.ACCEPTED:
            self._publish_fence()
            self._drain_notices()
        else:
            self.node.get_logger().warning(f"geofence/set refused: {decision.message}")
        return response

    def _drain_notices(self) -> None:
        for notice in self.arbiter.notices:
            self.node.get_logger().warning(notice)
        self.arbiter.notices.clear()

    async def _on_vehicle_command(self, request: Any, response: Any) -> Any:
        c = request.command
        if c in (VehicleCommandId.ARM, VehicleCommandId.TAKEOFF) and not request.force:
            refusal = self.prearm.check(self._prearm_inputs())
            if refusal is not None:
                response.result = int(CommandResult.TEMPORARILY_REJECTED)
                response.message = f"pre-arm check failed: {refusal}"
                return response
        t = request.target
        target = goto_target(t.latitude, t.longitude, t.altitude, request.yaw) if c == VehicleCommandId.GOTO else None
        decision: Decision = self.arbiter.command(c, self._view(), request.force, target)
        if not decision.forward:
            response.result, response.message = int(decision.result), decision.message
            return response
        if not self.core.service_is_ready():
            response.result, response.message = int(CommandResult.TEMPORARILY_REJECTED), "GNC core not reachable"
            self.arbiter.core_replied(c, response.result)  # not sent: nothing changes
            return response
        forwarded = await self.core.call_async(request)
        response.result, response.message = forwarded.result, forwarded.message
        self.arbiter.core_replied(c, forwarded.result)
        return response

    # ------------------------------------------------------------------ guidance
    def _send_core(self, command: Command, altitude: float = 0.0) -> Any:
        return self.core.call_async(VehicleCommand.Request(command=int(command), altitude=float(altitude)))

    def _core_answered(self, runner: MissionExecutor, command: Command, future: Any) -> None:
        reply = future.result()
        if reply is not None and reply.result != CommandResult.ACCEPTED:
            self.node.get_logger().warning(f"core refused {command.name.lower()}: {reply.message}; retrying")
            runner.request_rejected(command, reply.message)

    def _vehicle(self) -> Vehicle:
        s, st = self.state, self.status
        q = (s.orientation.w, s.orientation.x, s.orientation.y, s.orientation.z)
        in_air = st.landed_state in (Landed.IN_AIR, Landed.LANDING)
        return Vehicle(self._position(), st.armed, in_air, st.nav_state, quat.yaw_of(q))

    def _tick(self) -> None:
        sample = self.state_sampler.latest()
        if sample is not None and sample is not self.state:
            self._on_state(sample)
        if self.pending is not None and not self._restore():
            return
        t = self._now()
        if self.state is not None and self.status is not None:  # guidance needs both, the heartbeat neither
            for runner, out in self.arbiter.step(t, TICK_S, self._vehicle()):
                for command, value in out.requests:
                    self._send_core(command, value).add_done_callback(partial(self._core_answered, runner, command))
                if out.setpoint is not None and self.status.flight_mode == Mode.AUTO:
                    # the core follows guidance/setpoint in AUTO only (it owns no stream in OFFBOARD or a pilot mode)
                    self.pub_setpoint.publish(setpoint_msg(t, *out.setpoint))
        self._drain_notices()
        mission = self.arbiter.mission
        key = (mission.plan.plan_id if mission.plan else 0, int(mission.status), mission.current, mission.last_reached)
        if key != self.last_state_key or t - self.last_state_pub >= STATE_HEARTBEAT_S:
            self.pub_state.publish(self._state_msg())
            self.last_state_key, self.last_state_pub = key, t
        self._write_journal()

    def _state_msg(self) -> Any:
        mission = self.arbiter.mission
        msg = MissionState()
        msg.header.stamp = s_to_stamp(self._now())
        msg.plan_id = mission.plan.plan_id if mission.plan else 0
        msg.state = int(mission.status)
        msg.current_item = mission.current
        msg.total_items = len(mission.plan.items) if mission.plan else 0
        msg.last_reached_item = mission.last_reached
        msg.progress = float(mission.progress)
        msg.distance_to_item = math.nan
        return msg


def setpoint_msg(t: float, position: tuple[float, float, float], velocity: tuple[float, float, float], yaw: float) -> Any:
    """A position-level GuidanceSetpoint with velocity feed-forward (the executor's output)."""

    sp = GuidanceSetpoint(control_level=GuidanceSetpoint.LEVEL_POSITION, yaw=float(yaw), yaw_rate=math.nan,
                          thrust=math.nan, max_horizontal_speed=math.nan, max_vertical_speed=math.nan)
    sp.header.stamp, sp.header.frame_id = s_to_stamp(t), "map"
    sp.position.x, sp.position.y, sp.position.z = (float(v) for v in position)
    sp.velocity.x, sp.velocity.y, sp.velocity.z = (float(v) for v in velocity)
    sp.acceleration.x = sp.acceleration.y = sp.acceleration.z = math.nan
    return sp


def component(rclpy, host: Host) -> lifecycle.ManagedComponent:
    """The mission node as a component (c4d_ros.component): alone or composed with others. Its
    executor is the SingleThreadedExecutor: the vehicle/command service is a coroutine."""
    node = lifecycle.create_node(rclpy, "mission")
    try:
        values = declare_all(node, PARAMETERS)
    except ParameterError as err:
        node.destroy_node()
        raise ComponentError(str(err)) from None

    def build() -> SpunNode:  # configure (c4d_ros.lifecycle)
        side = rclpy.create_node(m.side_node_name("mission"))
        try:
            return SpunNode("mission", node, False, 0, MissionNode(node, side, **values), (side,))
        except ParameterError as err:
            side.destroy_node()
            raise ComponentError(str(err)) from None
    return lifecycle.ManagedComponent("mission", node, build)


def main(argv: list[str] | None = None) -> int:
    return run_components([("mission", component)], argv, "mission", composed=False)


if __name__ == "__main__":
    sys.exit(main())
