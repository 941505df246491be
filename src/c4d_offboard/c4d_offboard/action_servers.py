"""The offboard node's action servers: offboard/takeoff, offboard/land, offboard/goto, offboard/follow_path.

Thin rclpy over `action_logic` (what is refused, the profile, when a goal ends):

- TakeOff / Land ask the core (vehicle/command TAKEOFF / LAND, the mission node forwards) and
  watch vehicle/status until the core reports the take-off held / the vehicle disarmed on the
  ground. A command the vehicle refuses aborts the goal with its one-line reason in
  result.message. Cancel: vehicle/command HOLD.
- GoTo / FollowPath claim the gateway's setpoint stream (`SetpointSink.claim`: external input is
  refused meanwhile), stream a position + velocity feed-forward profile at 50 Hz through the
  gateway (`publish_action_setpoint`, published on guidance/offboard), ask for OFFBOARD after
  1.1 s of stream, fly once OFFBOARD is in force, and at the end (success or cancel) command
  HOLD (the core holds in AUTO where the vehicle is) and release the claim. A cancel first brakes
  along the current velocity (action_brake_decel) so HOLD captures a vehicle already stopped.

One goal at a time, of any of the four actions: a goal that arrives while another runs is
rejected (reason logged) — cancel the running one first. Why not preempt: a preempting goal
would have to inherit a half-entered OFFBOARD and a moving vehicle from another action; a
rejection is explicit and the client decides. Rejections are logged with their reason (ROS 2
goal responses carry none); refusals that come from the vehicle abort with the reason instead.

The execute callbacks block (pacing sleeps, waiting for vehicle/command replies) in a reentrant
callback group: the node is spun by a MultiThreadedExecutor, so replies, status updates and
cancel requests are served on the other thread meanwhile.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from typing import Any

import rclpy
from geometry_msgs.msg import Point
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup

from c4d_common.geodesy import GeoOrigin
from c4d_common.plan import Geofence, PlanError
from c4d_common.quat import yaw_of
from c4d_common.vehicle import CommandResult, Landed, Mode, Nav
from c4d_interfaces.action import FollowPath, GoTo, Land, TakeOff
from c4d_interfaces.msg import GuidanceSetpoint, MissionPlan, VehicleState, VehicleStatus
from c4d_interfaces.srv import VehicleCommand
from c4d_ros.drain import LatestSampler
from c4d_ros.manifest import (
    ACTION_FOLLOW_PATH,
    ACTION_GOTO,
    ACTION_LAND,
    ACTION_TAKEOFF,
    MISSION_PLAN,
    NAV_STATE,
    STATUS,
    VEHICLE_COMMAND,
    side_node_name,
)
from c4d_ros.params import Spec, declare
from c4d_ros.plan_msgs import plan_from_msg

from .action_logic import (
    Brake,
    LandTracker,
    OffboardRun,
    Outcome,
    PathPose,
    PathProfile,
    ProfilePoint,
    TakeoffTracker,
    VehicleView,
    goal_refusal,
    path_refusal,
    radius_or_default,
    speed_or_default,
)
from .sink import SetpointSink

STREAM_HZ = 50.0  # setpoints per second while a GoTo / FollowPath flies (the gateway's limit is 100 Hz)
WATCH_HZ = 10.0  # status checks (and feedback) per second during take-off and landing
FEEDBACK_EVERY = 5  # streamed setpoints per feedback message (10 Hz)
BRAKE_SETTLE_S = 0.3  # [s] of streaming the stop point after a cancel's braking, before HOLD
REPLY_S = 5.0  # [s] wait for a vehicle/command reply
TAKEOFF_TIMEOUT_S, LAND_TIMEOUT_S = 90.0, 120.0  # [s] plus the altitude at 1 m/s / 0.3 m/s

PARAMS = {
    "action_accel": Spec(1.0, "acceleration / deceleration of the GoTo and FollowPath profiles [m/s^2]", 0.1, 5.0),
    "action_brake_decel": Spec(2.5, "deceleration with which a cancelled GoTo / FollowPath stops before it holds "
                                    "[m/s^2]", 0.5, 8.0),
    "action_max_vertical_speed": Spec(1.5, "GoTo / FollowPath speed is lowered so no leg climbs or sinks faster "
                                           "[m/s]", 0.1, 5.0),
}


class ActionServers:
    """The four action servers of the offboard node (module docstring). `sink` is the gateway's
    SetpointSink; `side_node` an unspun node for the navigation/state sampler (created if None)."""

    def __init__(self, node: Any, sink: SetpointSink, side_node: Any = None) -> None:
        self.node, self.sink = node, sink
        self.log = node.get_logger()
        values = {name: declare(node, name, spec) for name, spec in PARAMS.items()}
        self.accel, self.vertical_speed = values["action_accel"], values["action_max_vertical_speed"]
        self.brake_decel = values["action_brake_decel"]
        self.group = ReentrantCallbackGroup()
        self.side = side_node if side_node is not None else rclpy.create_node(side_node_name("offboard"),
                                                                              context=node.context)
        self.state = LatestSampler(self.side, VehicleState, NAV_STATE.name, NAV_STATE.qos)
        self.status: Any = None
        self.fence: Geofence | None = None
        node.create_subscription(VehicleStatus, STATUS.name, self._on_status, STATUS.qos, callback_group=self.group)
        node.create_subscription(MissionPlan, MISSION_PLAN.name, self._on_plan, MISSION_PLAN.qos,
                                 callback_group=self.group)
        self.command = node.create_client(VehicleCommand, VEHICLE_COMMAND.name, callback_group=self.group)
        self.lock = threading.Lock()
        self.active: str | None = None
        checks: dict[str, Callable[[Any], str | None]] = {
            "takeoff": self._takeoff_refusal, "land": self._land_refusal, "goto": self._goto_refusal,
            "follow_path": self._path_refusal}
        self.servers = [
            ActionServer(node, kind, action.name, execute, callback_group=self.group,
                         goal_callback=lambda goal, name=name: self._on_goal(name, checks[name], goal),
                         cancel_callback=lambda _: CancelResponse.ACCEPT)
            for name, kind, action, execute in (
                ("takeoff", TakeOff, ACTION_TAKEOFF, self._takeoff), ("land", Land, ACTION_LAND, self._land),
                ("goto", GoTo, ACTION_GOTO, self._goto), ("follow_path", FollowPath, ACTION_FOLLOW_PATH, self._follow))]

    def destroy(self) -> None:
        for server in self.servers:
            server.destroy()
        self.side.destroy_node()

    # ------------------------------------------------------------------ inputs
    def _on_status(self, msg: Any) -> None:
        self.status = msg

    def _on_plan(self, msg: Any) -> None:
        try:
            self.fence = plan_from_msg(msg).geofence
        except PlanError as exc:
            self.log.warning(f"mission/plan unreadable, keeping the previous geofence: {exc}")

    def _view(self) -> VehicleView | None:
        s, st = self.state.latest(), self.status
        if s is None or st is None:
            return None
        home = GeoOrigin(s.origin.latitude, s.origin.longitude, s.origin.altitude) \
            if s.valid & VehicleState.VALID_ORIGIN else None
        return VehicleView(_enum(Landed, st.landed_state, Landed.UNDEFINED), _xyz(s.position), home)

    def _mode(self) -> Mode:
        return _enum(Mode, self.status.flight_mode, Mode.UNKNOWN) if self.status is not None else Mode.UNKNOWN

    # ------------------------------------------------------------------ goals
    def _on_goal(self, name: str, check: Callable[[Any], str | None], goal: Any) -> GoalResponse:
        with self.lock:
            refusal = f"the {self.active} goal is running (cancel it first)" if self.active else check(goal)
            if refusal is None:
                self.active = name
        if refusal is not None:
            self.log.warning(f"{name} goal rejected: {refusal}")
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    def _takeoff_refusal(self, goal: Any) -> str | None:
        st = self.status
        if st is None:
            return "no vehicle status yet"
        if st.landed_state != VehicleStatus.LANDED_ON_GROUND:
            return f"already flying (landed state {_enum(Landed, st.landed_state, Landed.UNDEFINED).name})"
        return None if math.isfinite(goal.altitude) else "altitude must be finite"

    def _land_refusal(self, goal: Any) -> str | None:
        st = self.status
        return None if st is not None and st.armed else "not armed"

    def _goto_refusal(self, goal: Any) -> str | None:
        return goal_refusal(_xyz(goal.position), self._view(), self.fence)

    def _path_refusal(self, goal: Any) -> str | None:
        poses = [PathPose(p.header.frame_id, _xyz(p.pose.position)) for p in goal.path.poses]
        return path_refusal(goal.path.header.frame_id, poses, self._view(), self.fence)

    # ------------------------------------------------------------------ commands
    def _call(self, command: int, **fields: Any) -> tuple[int, str]:
        """vehicle/command, waited for REPLY_S (this thread blocks; the other one takes the reply)."""
        if not self.command.wait_for_service(timeout_sec=REPLY_S):
            return int(CommandResult.TEMPORARILY_REJECTED), "vehicle/command is not available"
        done = threading.Event()
        future = self.command.call_async(VehicleCommand.Request(command=command, **fields))
        future.add_done_callback(lambda _: done.set())
        if not done.wait(REPLY_S) or future.result() is None:
            return int(CommandResult.FAILED), "vehicle/command did not answer"
        reply = future.result()
        return int(reply.result), str(reply.message)

    def _hold(self, why: str) -> None:
        result, message = self._call(VehicleCommand.Request.CMD_HOLD)
        if result != CommandResult.ACCEPTED:
            self.log.error(f"HOLD after {why} refused: {message}")

    def _finish(self, goal_handle: Any, result: Any, outcome: Outcome, cancelled: bool = False) -> Any:
        result.success, result.message = outcome.success, outcome.message
        if cancelled:
            goal_handle.canceled()
        elif outcome.success:
            goal_handle.succeed()
        else:
            goal_handle.abort()
            self.log.warning(f"goal aborted: {outcome.message}")
        with self.lock:
            self.active = None
        return result

    # ------------------------------------------------------------------ take-off and landing
    def _takeoff(self, goal_handle: Any) -> Any:
        altitude = float(goal_handle.request.altitude)
        tracker = TakeoffTracker(altitude)

        def feedback(z: float) -> Any:
            return TakeOff.Feedback(altitude=z, distance_to_go=tracker.distance_to_go(z))

        def update(st: Any, z: float) -> Outcome | None:
            return tracker.update(st.armed, _enum(Mode, st.flight_mode, Mode.UNKNOWN), _enum(Nav, st.nav_state, Nav.NONE), z)

        result = TakeOff.Result()
        outcome, z, cancelled = self._watch(goal_handle, (VehicleCommand.Request.CMD_TAKEOFF, {"altitude": altitude}),
                                            update, feedback, TAKEOFF_TIMEOUT_S + max(altitude, 0.0))
        result.altitude = z
        return self._finish(goal_handle, result, outcome, cancelled)

    def _land(self, goal_handle: Any) -> Any:
        tracker = LandTracker()

        def update(st: Any, z: float) -> Outcome | None:
            return tracker.update(st.armed, _enum(Landed, st.landed_state, Landed.UNDEFINED),
                                  _enum(Mode, st.flight_mode, Mode.UNKNOWN), _enum(Nav, st.nav_state, Nav.NONE))

        z0 = self._z() if math.isfinite(self._z()) else 0.0
        outcome, _, cancelled = self._watch(goal_handle, (VehicleCommand.Request.CMD_LAND, {}), update,
                                            lambda z: Land.Feedback(altitude=z), LAND_TIMEOUT_S + max(z0, 0.0) / 0.3)
        return self._finish(goal_handle, Land.Result(), outcome, cancelled)

    def _z(self) -> float:
        s = self.state.latest()
        return float(s.position.z) if s is not None else math.nan

    def _watch(self, goal_handle: Any, command: tuple[int, dict[str, Any]], update: Callable[[Any, float], Outcome | None],
               feedback: Callable[[float], Any], timeout_s: float) -> tuple[Outcome, float, bool]:
        """Send `command`, then watch the status at WATCH_HZ until `update` ends the goal, it is
        cancelled (HOLD) or `timeout_s` passes. Returns (outcome, altitude, cancelled)."""
        result, message = self._call(command[0], **command[1])
        if result != CommandResult.ACCEPTED:
            return Outcome(False, f"refused by the vehicle: {message}"), self._z(), False
        deadline = time.monotonic() + timeout_s
        for _ in _paced(WATCH_HZ, self.node.context):
            z = self._z()
            if goal_handle.is_cancel_requested:
                self._hold("a cancel")
                return Outcome(False, "cancelled: holding"), z, True
            outcome = update(self.status, z) if self.status is not None else None
            if outcome is not None:
                return outcome, z, False
            if time.monotonic() > deadline:
                return Outcome(False, f"not done within {timeout_s:.0f} s"), z, False
            goal_handle.publish_feedback(feedback(z))
        return Outcome(False, "shutting down"), self._z(), False

    # ------------------------------------------------------------------ offboard goals
    def _goto(self, goal_handle: Any) -> Any:
        g = goal_handle.request
        start = self._start()
        profile = PathProfile.build([start, _xyz(g.position)], speed_or_default(g.speed), self.accel, self.vertical_speed)
        yaw = float(g.yaw)

        def feedback(run: OffboardRun, position: tuple[float, float, float]) -> Any:
            return GoTo.Feedback(distance_to_go=math.dist(position, profile.points[-1]), position=_point(position))

        outcome, position, cancelled, _ = self._fly(goal_handle, "goto", profile, radius_or_default(g.acceptance_radius),
                                                    lambda _: yaw, feedback)
        result = GoTo.Result(position=_point(position))
        return self._finish(goal_handle, result, outcome, cancelled)

    def _follow(self, goal_handle: Any) -> Any:
        g = goal_handle.request
        poses = g.path.poses
        profile = PathProfile.build([self._start()] + [_xyz(p.pose.position) for p in poses],
                                    speed_or_default(g.speed), self.accel, self.vertical_speed)
        yaws = [_pose_yaw(p.pose.orientation) for p in poses]

        def feedback(run: OffboardRun, position: tuple[float, float, float]) -> Any:
            return FollowPath.Feedback(current_pose=run.last.segment, distance_to_go=run.distance_to_go(position))

        outcome, _, cancelled, run = self._fly(goal_handle, "follow_path", profile, radius_or_default(math.nan),
                                               lambda sp: yaws[sp.segment], feedback)
        result = FollowPath.Result(poses_reached=profile.passed(run.last.s))
        return self._finish(goal_handle, result, outcome, cancelled)

    def _start(self) -> tuple[float, float, float]:
        s = self.state.latest()
        assert s is not None  # the goal check needed an estimate
        return _xyz(s.position)

    def _fly(self, goal_handle: Any, name: str, profile: PathProfile, radius: float,
             yaw: Callable[[ProfilePoint], float],
             feedback: Callable[[OffboardRun, tuple[float, float, float]], Any]
             ) -> tuple[Outcome, tuple[float, float, float], bool, OffboardRun]:
        """Claim the stream, fly `profile` in OFFBOARD (action_logic.OffboardRun), hold, release.
        Returns (outcome, final estimated position, cancelled, run)."""
        self.sink.claim(name)
        run = OffboardRun(profile, radius, time.monotonic())
        pending: Any = None
        position = profile.points[0]
        try:
            for k in _paced(STREAM_HZ, self.node.context):
                s = self.state.latest()
                position = _xyz(s.position)
                speed = math.sqrt(s.velocity.x ** 2 + s.velocity.y ** 2 + s.velocity.z ** 2)
                if goal_handle.is_cancel_requested:
                    if self._mode() == Mode.OFFBOARD:
                        self._brake(Brake(position, _xyz(s.velocity), self.brake_decel), yaw(run.last))
                    self._hold(f"cancelling {name}")
                    return Outcome(False, "cancelled: holding"), position, True, run
                outcome = None
                if pending is not None and pending.done():
                    reply, pending = pending.result(), None
                    if reply is not None and reply.result != CommandResult.ACCEPTED:
                        outcome = run.refused(reply.message, reply.result == CommandResult.TEMPORARILY_REJECTED)
                step = run.step(time.monotonic(), self._mode(), position, speed)
                self.sink.publish_action_setpoint(self._setpoint(step.setpoint, yaw(step.setpoint)))
                if step.request_offboard and pending is None:
                    pending = self.command.call_async(VehicleCommand.Request(command=VehicleCommand.Request.CMD_SET_MODE,
                                                                             mode=VehicleStatus.MODE_OFFBOARD))
                outcome = outcome or step.outcome
                if outcome is not None:
                    if outcome.success or self._mode() == Mode.OFFBOARD:
                        self._hold(f"{name} {'reached' if outcome.success else 'failed'}")
                    return outcome, position, False, run
                if k % FEEDBACK_EVERY == 0:
                    goal_handle.publish_feedback(feedback(run, position))
            return Outcome(False, "shutting down"), position, False, run
        finally:
            self.sink.claim(None)

    def _brake(self, brake: Brake, yaw: float) -> None:
        """Stream `brake` until the vehicle should have stopped (or OFFBOARD is left)."""
        start = time.monotonic()
        for _ in _paced(STREAM_HZ, self.node.context):
            t = time.monotonic() - start
            self.sink.publish_action_setpoint(self._setpoint(brake.at(t), yaw))
            if t >= brake.duration + BRAKE_SETTLE_S or self._mode() != Mode.OFFBOARD:
                return

    def _setpoint(self, sp: ProfilePoint, yaw: float) -> Any:
        msg = GuidanceSetpoint(control_level=GuidanceSetpoint.LEVEL_POSITION, yaw=yaw, yaw_rate=math.nan,
                               thrust=math.nan, max_horizontal_speed=math.nan, max_vertical_speed=math.nan)
        msg.header.stamp = self.node.get_clock().now().to_msg()
        msg.header.frame_id = "map"
        msg.position.x, msg.position.y, msg.position.z = sp.position
        msg.velocity.x, msg.velocity.y, msg.velocity.z = sp.velocity
        msg.acceleration.x = msg.acceleration.y = msg.acceleration.z = math.nan
        return msg


def _paced(hz: float, context: Any) -> Any:
    """Yield 0, 1, 2, ... at `hz` on absolute monotonic deadlines (sleeping, never spinning) while
    the context is up."""
    period, k = 1.0 / hz, 0
    deadline = time.monotonic()
    while rclpy.ok(context=context):
        yield k
        k += 1
        deadline += period
        delay = deadline - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        else:
            deadline = time.monotonic()  # late (a stall): no burst of catch-up steps


def _xyz(p: Any) -> tuple[float, float, float]:
    return float(p.x), float(p.y), float(p.z)


def _point(p: tuple[float, float, float]) -> Any:
    return Point(x=p[0], y=p[1], z=p[2])


def _pose_yaw(q: Any) -> float:
    """Heading of a path pose; NaN (keep) for a zero quaternion (orientation not given)."""
    if q.w == 0 and q.x == 0 and q.y == 0 and q.z == 0:
        return math.nan
    return yaw_of((q.w, q.x, q.y, q.z))


def _enum(kind: Any, value: int, default: Any) -> Any:
    try:
        return kind(value)
    except ValueError:
        return default
