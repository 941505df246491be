"""`Vehicle`: one c4d vehicle seen from a script — blocking commands and actions over rclpy.

The Vehicle owns an rclpy context (its own, so a script's other ROS use is untouched), one node
and a background executor thread that takes replies, feedback and the status; the blocking calls
wait on those with timeouts. High-rate navigation/state is not spun: it is taken on demand from
an unspun subscription (an executor callback per 500 Hz sample would cost a fifth of a core).
"""

from __future__ import annotations

import math
import os
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import rclpy
from action_msgs.msg import GoalStatus
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path
from rcl_interfaces.msg import Log
from rclpy.action import ActionClient
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from c4d_interfaces.action import FollowPath, GoTo, Land, TakeOff
from c4d_interfaces.msg import GuidanceSetpoint, VehicleState, VehicleStatus
from c4d_interfaces.srv import VehicleCommand

from .errors import ActionFailed, CommandRefused, GoalRejected, NotConnected, VehicleTimeout
from .offboard import OffboardStream

NAN = math.nan
LATCHED = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
NEWEST = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
READY = VehicleState.VALID_ORIGIN | VehicleState.VALID_POSITION_XY | VehicleState.VALID_POSITION_Z
REASON_WAIT_S = 1.0  # [s] to read a rejected goal's reason from /rosout
SERVER_NODE = "offboard"  # the node serving the offboard/* actions (its log carries rejection reasons)


class Vehicle:
    """A c4d vehicle: `Vehicle(); v.arm(); v.takeoff(5); v.goto(10, 0, 5); v.land(); v.close()`.

    Positions are in `map` (ENU, metres from home: x east, y north, z up), headings in radians
    (ENU: 0 = east, counter-clockwise positive). Each blocking call raises a `VehicleError`
    subclass with the vehicle's reason: CommandRefused, GoalRejected, ActionFailed,
    VehicleTimeout, NotConnected. `namespace` is the graph's namespace, `domain_id` its
    ROS_DOMAIN_ID (default: the environment's)."""

    def __init__(self, namespace: str = "", domain_id: int | None = None, connect_timeout: float = 30.0) -> None:
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        try:
            self.node = rclpy.create_node(f"c4d_client_{os.getpid()}_{id(self) & 0xFFFF:x}", namespace=namespace,
                                          context=self.context)
            self._status: VehicleStatus | None = None
            self._status_changed = threading.Condition()
            self.node.create_subscription(VehicleStatus, "vehicle/status", self._on_status, LATCHED)
            self._rejections: deque[tuple[float, str]] = deque(maxlen=50)
            self.node.create_subscription(Log, "/rosout", self._on_log, QoSProfile(depth=50))
            self._side = rclpy.create_node(f"_c4d_client_samples_{os.getpid()}", namespace=namespace,
                                           context=self.context)  # never spun (module docstring)
            self._state_sub = self._side.create_subscription(VehicleState, "navigation/state", lambda _: None, NEWEST)
            self._state: VehicleState | None = None
            self.commands = self.node.create_client(VehicleCommand, "vehicle/command")
            self.setpoint_pub = self.node.create_publisher(GuidanceSetpoint, "offboard/trajectory_setpoint", NEWEST)
            self.actions = {name: ActionClient(self.node, kind, f"offboard/{name}") for name, kind in
                            (("takeoff", TakeOff), ("land", Land), ("goto", GoTo), ("follow_path", FollowPath))}
            self.connect_timeout = connect_timeout
            self.executor = SingleThreadedExecutor(context=self.context)
            self.executor.add_node(self.node)
            self._spinner = threading.Thread(target=self._spin, name="c4d_client executor", daemon=True)
            self._spinner.start()
        except BaseException:
            rclpy.shutdown(context=self.context)
            raise
        self.closed = False

    # ------------------------------------------------------------------ life cycle
    def _spin(self) -> None:
        try:
            self.executor.spin()
        except Exception:  # the context was shut down under the executor by close()
            if not self.closed:
                raise

    def close(self) -> None:
        """Stop the executor thread and the node, shut the context down (idempotent)."""
        if self.closed:
            return
        self.closed = True
        self.executor.shutdown(timeout_sec=2.0)
        self._spinner.join(timeout=2.0)
        self.node.destroy_node()
        self._side.destroy_node()
        rclpy.shutdown(context=self.context)

    def __enter__(self) -> Vehicle:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # ------------------------------------------------------------------ what the vehicle reports
    def _on_status(self, msg: VehicleStatus) -> None:
        with self._status_changed:
            self._status = msg
            self._status_changed.notify_all()

    def _on_log(self, msg: Log) -> None:
        if msg.name.rsplit(".", 1)[-1] == SERVER_NODE and "goal rejected:" in msg.msg:
            self._rejections.append((msg.stamp.sec + msg.stamp.nanosec * 1e-9, msg.msg))

    @property
    def status(self) -> VehicleStatus | None:
        """The newest vehicle/status (armed, flight_mode, nav_state, landed_state, failsafe, ...)."""
        return self._status

    @property
    def state(self) -> VehicleState | None:
        """The newest navigation/state (position, velocity, attitude, validity, home), taken now.
        (The same take loop as c4d_ros.drain.LatestSampler: the client may not import c4d_ros.)"""
        sub = self._state_sub
        while True:
            with sub.handle:
                taken = sub.handle.take_message(sub.msg_type, sub.raw)
            if taken is None:
                return self._state
            self._state = taken[0]

    @property
    def position(self) -> tuple[float, float, float]:
        """Estimated position in map ENU [m] (NotConnected before the first estimate)."""
        s = self.wait_ready()
        return s.position.x, s.position.y, s.position.z

    def wait_for(self, condition: Callable[[VehicleStatus], bool], timeout: float) -> bool:
        """Block until `condition(status)` holds (True) or `timeout` [s] passes (False)."""
        end = time.monotonic() + timeout
        with self._status_changed:
            while self._status is None or not condition(self._status):
                left = end - time.monotonic()
                if left <= 0:
                    return False
                self._status_changed.wait(min(left, 0.2))
            return True

    def wait_ready(self, timeout: float | None = None) -> VehicleState:
        """Block until the status and a position estimate with a home are there; the estimate."""
        wait = self.connect_timeout if timeout is None else timeout
        end = time.monotonic() + wait
        while True:
            s = self.state
            if self._status is not None and s is not None and s.valid & READY == READY:
                return s
            if time.monotonic() > end:
                missing = "vehicle/status" if self._status is None else "a navigation/state with position and home"
                raise NotConnected("vehicle", f"no {missing} within {wait:g} s")
            time.sleep(0.05)

    # ------------------------------------------------------------------ vehicle/command
    def command(self, command: int, timeout: float = 10.0, **fields: Any) -> str:
        """Send a VehicleCommand (CMD_*, with its fields); the vehicle's message when accepted,
        CommandRefused with its reason otherwise."""
        name = _command_name(command)
        if not self.commands.wait_for_service(timeout_sec=self.connect_timeout):
            raise NotConnected(name, "vehicle/command is not available")
        reply = self._wait(self.commands.call_async(VehicleCommand.Request(command=command, **fields)), timeout, name)
        if reply.result != VehicleCommand.Response.RESULT_ACCEPTED:
            raise CommandRefused(name, reply.message or f"result {reply.result}", reply.result)
        return str(reply.message)

    def arm(self, timeout: float = 10.0) -> None:
        """Arm (pre-arm checks apply) and wait until the status shows it."""
        self.wait_ready()
        self.command(VehicleCommand.Request.CMD_ARM, timeout)
        if not self.wait_for(lambda st: st.armed, timeout):
            raise VehicleTimeout("arm", f"accepted but the status did not show armed within {timeout:g} s")

    def disarm(self, force: bool = False, timeout: float = 10.0) -> None:
        """Disarm (refused in the air unless `force`) and wait until the status shows it."""
        self.command(VehicleCommand.Request.CMD_DISARM, timeout, force=force)
        if not self.wait_for(lambda st: not st.armed, timeout):
            raise VehicleTimeout("disarm", f"accepted but the status still shows armed after {timeout:g} s")

    def hold(self) -> None:
        """Hold position where the vehicle is (AUTO hold)."""
        self.command(VehicleCommand.Request.CMD_HOLD)

    def set_mode(self, mode: int) -> None:
        """Switch to VehicleStatus.MODE_* (OFFBOARD needs a live stream: use `offboard()`)."""
        self.command(VehicleCommand.Request.CMD_SET_MODE, mode=mode)

    # ------------------------------------------------------------------ actions
    def takeoff(self, altitude: float = 0.0, timeout: float = 90.0) -> float:
        """Arm if needed, climb to `altitude` [m above home] (<= 0: the airframe default) and hold;
        returns the altitude reached."""
        self.wait_ready()
        return float(self.run_action("takeoff", TakeOff.Goal(altitude=float(altitude)), timeout).altitude)

    def land(self, timeout: float = 120.0) -> None:
        """Land where the vehicle is and wait until it has disarmed on the ground."""
        self.run_action("land", Land.Goal(), timeout)

    def goto(self, x: float, y: float, z: float, yaw: float = NAN, speed: float = NAN,
             acceptance_radius: float = NAN, timeout: float = 120.0) -> tuple[float, float, float]:
        """Fly to (x, y, z) in map ENU [m] in OFFBOARD at `speed` [m/s] (NaN: 2 m/s) and hold there;
        returns the estimated position at the end."""
        goal = GoTo.Goal(yaw=float(yaw), speed=float(speed), acceptance_radius=float(acceptance_radius))
        goal.position.x, goal.position.y, goal.position.z = float(x), float(y), float(z)
        p = self.run_action("goto", goal, timeout).position
        return p.x, p.y, p.z

    def follow_path(self, points: Iterable[Sequence[float]], speed: float = NAN, timeout: float = 300.0) -> int:
        """Fly through `points` ((x, y, z) or (x, y, z, yaw) in map ENU) at `speed` [m/s] and hold
        at the last; returns how many were passed."""
        return int(self.run_action("follow_path", FollowPath.Goal(path=make_path(points), speed=float(speed)),
                                   timeout).poses_reached)

    def run_action(self, name: str, goal: Any, timeout: float, feedback: Callable[[Any], None] | None = None) -> Any:
        """Send `goal` to offboard/<name>, wait for its result; a timeout or an interrupt (Ctrl-C)
        cancels the goal (the vehicle holds) before raising."""
        client = self.actions[name]
        if not client.wait_for_server(timeout_sec=self.connect_timeout):
            raise NotConnected(name, f"action server offboard/{name} is not available")
        sent = self.node.get_clock().now().nanoseconds * 1e-9
        handle = self._wait(client.send_goal_async(goal, feedback_callback=feedback), 10.0, name)
        if not handle.accepted:
            raise GoalRejected(name, self._rejection_reason(name, sent))
        try:
            wrapped = self._wait(handle.get_result_async(), timeout, name)
        except BaseException:
            self._wait(handle.cancel_goal_async(), 5.0, f"cancel {name}")
            raise
        result = wrapped.result
        if wrapped.status == GoalStatus.STATUS_SUCCEEDED and getattr(result, "success", True):
            return result
        raise ActionFailed(name, result.message or f"goal status {wrapped.status}", wrapped.status)

    def _rejection_reason(self, name: str, sent: float) -> str:
        end = time.monotonic() + REASON_WAIT_S
        while True:
            for stamp, text in reversed(self._rejections):
                if stamp >= sent - 0.5 and text.startswith(f"{name} goal rejected:"):
                    return text.split("goal rejected:", 1)[1].strip()
            if time.monotonic() > end:
                return f"rejected (the reason is in the {SERVER_NODE} node's log)"
            time.sleep(0.05)

    # ------------------------------------------------------------------ offboard streaming
    def offboard(self, rate_hz: float = 50.0, enter: bool = True) -> OffboardStream:
        """`with v.offboard() as ob: ob.set_position(...)` — stream setpoints at `rate_hz` from a
        background thread and (`enter`) switch to OFFBOARD after 1.1 s of stream; on exit HOLD
        and stop streaming."""
        self.wait_ready()
        return OffboardStream(self, rate_hz, enter)

    # ------------------------------------------------------------------ helpers
    def _wait(self, future: Any, timeout: float, what: str) -> Any:
        done = threading.Event()
        future.add_done_callback(lambda _: done.set())
        if not done.wait(timeout):
            raise VehicleTimeout(what, f"no answer within {timeout:g} s")
        if future.exception() is not None:
            raise NotConnected(what, str(future.exception()))
        return future.result()


def make_path(points: Iterable[Sequence[float]]) -> Path:
    """A nav_msgs/Path in `map` from (x, y, z) or (x, y, z, yaw) tuples (no yaw: keep heading)."""
    path = Path()
    path.header.frame_id = "map"
    for p in points:
        pose = PoseStamped()
        pose.header.frame_id = "map"
        pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = (float(v) for v in p[:3])
        yaw = float(p[3]) if len(p) > 3 else NAN
        if math.isfinite(yaw):
            pose.pose.orientation.z, pose.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
        else:
            pose.pose.orientation.w = 0.0  # zero quaternion: the server keeps the heading
        path.poses.append(pose)
    return path


def _command_name(command: int) -> str:
    for name in dir(VehicleCommand.Request):
        if name.startswith("CMD_") and getattr(VehicleCommand.Request, name) == command:
            return name[4:].lower()
    return f"command {command}"
