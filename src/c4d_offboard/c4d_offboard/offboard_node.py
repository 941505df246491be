"""`ros2 run c4d_offboard offboard` — the gateway through which external nodes steer c4d.

Subscribes the public inputs offboard/trajectory_setpoint (GuidanceSetpoint, any level),
offboard/pose (PoseStamped → POSITION + yaw) and offboard/twist (TwistStamped → VELOCITY + yaw
rate, `map` or `base_link`), checks each with gateway.Gateway (level, NaN/inf, frame, stamp,
rate limit, the fence in force on geofence/active) and republishes what passes on guidance/offboard, the
core's OFFBOARD input. offboard/status (DiagnosticStatus, latched) reports the stream and every
counter at 1 Hz and on change. docs/offboard.md is the user's page.

The action servers (c4d_offboard.action_servers) live in this node: they steer through the
SetpointSink protocol (sink.py) that `OffboardNode` implements. Their execute callbacks block,
so the node spins on its own MultiThreadedExecutor (2 threads): the inputs, timers and
subscriptions here share one mutually exclusive callback group, the action servers bring theirs.
"""

from __future__ import annotations

import math
import sys
import threading
import time
from dataclasses import asdict
from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped, TwistStamped
from rcl_interfaces.msg import SetParametersResult

from c4d_common.geodesy import GeoOrigin
from c4d_common.geofence import LocalFence
from c4d_common.plan import Geofence, PlanError
from c4d_common.quat import yaw_of
from c4d_interfaces.msg import Geofence as GeofenceMsg
from c4d_interfaces.msg import GuidanceSetpoint, VehicleState
from c4d_ros import lifecycle
from c4d_ros import manifest as m
from c4d_ros.component import ComponentError, Host
from c4d_ros.drain import LatestSampler
from c4d_ros.params import ParameterError, Spec, declare_all
from c4d_ros.plan_msgs import geofence_from_msg

from . import inputs
from .action_servers import ActionServers
from .gateway import Decision, Gateway, Limits, Reject, Setpoint

PARAMETERS = {
    "max_age_s": Spec(0.5, "external setpoints stamped longer ago than this are refused as stale [s]", 0.01, 10.0),
    "max_future_s": Spec(0.1, "external setpoints stamped further ahead than this are refused as future-dated [s]",
                         0.0, 5.0),
    "max_rate_hz": Spec(100.0, "at most this many external setpoints per second go on to the core; the excess is "
                               "counted as rate_limited [Hz]", 1.0, 1000.0),
    "live_timeout_s": Spec(0.5, "offboard/status says stream_live while the last forwarded setpoint is at most this "
                                "old [s]", 0.05, 10.0),
}
STATUS_PERIOD_S = 1.0  # offboard/status at least this often
WATCH_PERIOD_S = 0.1  # status changes (stream live, owner, fence) and the navigation sample are looked at this often
WARN_THROTTLE_S = 2.0  # one rejection / clamp warning per this long at most
EXECUTOR_THREADS = 2


def limits_of(values: dict[str, Any]) -> Limits:
    return Limits(float(values["max_age_s"]), float(values["max_future_s"]), float(values["max_rate_hz"]),
                  float(values["live_timeout_s"]))


class OffboardNode:
    """The gateway's ROS side and the SetpointSink of the action servers. Callbacks of the inputs
    and timers run in `group` one at a time; the action servers call publish_action_setpoint /
    claim from their own threads, so every use of the gateway holds `lock`."""

    def __init__(self, node: Any, side_node: Any, limits: Limits) -> None:
        from rclpy.callback_groups import MutuallyExclusiveCallbackGroup

        self.node, self.log = node, node.get_logger()
        self.lock = threading.Lock()
        self.gateway = Gateway(limits)
        self.group = MutuallyExclusiveCallbackGroup()
        self.geofence: Geofence | None = None
        self.origin: GeoOrigin | None = None
        self.heading: float | None = None
        self.shown: tuple[object, ...] = ()
        self.status_t = -math.inf
        self.pub = node.create_publisher(GuidanceSetpoint, m.OFFBOARD_SETPOINT.name, m.OFFBOARD_SETPOINT.qos)
        self.pub_status = node.create_publisher(DiagnosticStatus, m.OFFBOARD_STATUS.name, m.OFFBOARD_STATUS.qos)
        g = self.group
        node.create_subscription(GuidanceSetpoint, m.OFFBOARD_TRAJECTORY.name, self._on_trajectory,
                                 m.OFFBOARD_TRAJECTORY.qos, callback_group=g)
        node.create_subscription(PoseStamped, m.OFFBOARD_POSE.name, self._on_pose, m.OFFBOARD_POSE.qos, callback_group=g)
        node.create_subscription(TwistStamped, m.OFFBOARD_TWIST.name, self._on_twist, m.OFFBOARD_TWIST.qos,
                                 callback_group=g)
        node.create_subscription(GeofenceMsg, m.GEOFENCE.name, self._on_fence, m.GEOFENCE.qos, callback_group=g)
        self.state = LatestSampler(side_node, VehicleState, m.NAV_STATE.name, m.NAV_STATE.qos)
        node.create_timer(WATCH_PERIOD_S, self._watch, callback_group=g)
        node.add_on_set_parameters_callback(self._on_parameters)

    # --- external inputs -----------------------------------------------------------------------
    def _now(self) -> float:
        return float(self.node.get_clock().now().nanoseconds * 1e-9)

    def _offer(self, sp: Setpoint, stamp: Any) -> None:
        with self.lock:
            decision = self.gateway.offer(sp, self._now(), time.monotonic())
        self._forward(decision, stamp, "external")

    def _on_trajectory(self, msg: GuidanceSetpoint) -> None:
        self._offer(inputs.from_trajectory(msg), msg.header.stamp)

    def _on_pose(self, msg: PoseStamped) -> None:
        self._offer(inputs.from_pose(msg), msg.header.stamp)

    def _on_twist(self, msg: TwistStamped) -> None:
        self._sample_state()
        sp = inputs.from_twist(msg, self.heading)
        if isinstance(sp, Reject):
            with self.lock:
                decision = self.gateway.refuse(sp)
            self._forward(decision, msg.header.stamp, "external")
        else:
            self._offer(sp, msg.header.stamp)

    def _forward(self, decision: Decision, stamp: Any, source: str) -> None:
        if decision.setpoint is not None:
            self.pub.publish(inputs.to_msg(decision.setpoint, stamp))
            if decision.clamped:
                self.log.warning(f"{source} position target outside the geofence: clamped to "
                                 f"({', '.join(f'{v:.1f}' for v in decision.setpoint.position)})",
                                 throttle_duration_sec=WARN_THROTTLE_S)
        elif decision.reason is not None:
            self.log.warning(f"{source} setpoint refused: {decision.reason.value}", throttle_duration_sec=WARN_THROTTLE_S)

    # --- SetpointSink (sink.py): the action servers --------------------------------------------
    def publish_action_setpoint(self, sp: GuidanceSetpoint) -> None:
        with self.lock:
            decision = self.gateway.offer_action(inputs.from_trajectory(sp))
        self._forward(decision, sp.header.stamp, "action")

    def claim(self, owner: str | None) -> None:
        with self.lock:
            self.gateway.owner = owner
        self._publish_status()

    # --- context: fence, heading ---------------------------------------------------------------
    def _on_fence(self, msg: GeofenceMsg) -> None:
        try:
            fence: Geofence | None = geofence_from_msg(msg)
        except PlanError as exc:
            self.log.error(f"{m.GEOFENCE.name} unusable, not applied: {exc}")
            fence = None
        self.geofence = fence
        self._update_fence()

    def _sample_state(self) -> None:
        msg = self.state.latest()
        if msg is None:
            return
        self.heading = yaw_of((msg.orientation.w, msg.orientation.x, msg.orientation.y, msg.orientation.z)) \
            if msg.valid & VehicleState.VALID_HEADING else None
        origin = GeoOrigin(msg.origin.latitude, msg.origin.longitude, msg.origin.altitude) \
            if msg.valid & VehicleState.VALID_ORIGIN else None
        if origin != self.origin:
            self.origin = origin
            self._update_fence()

    def _update_fence(self) -> None:
        fence = self.geofence
        active = fence is not None and self.origin is not None and not fence.empty
        local = LocalFence.from_geofence(fence, self.origin) if active else None  # type: ignore[arg-type]
        with self.lock:
            self.gateway.fence = local

    # --- status and parameters -----------------------------------------------------------------
    def _watch(self) -> None:
        self._sample_state()
        t = time.monotonic()
        with self.lock:
            g = self.gateway
            shown = (g.live(t), g.owner, g.fence is not None)
        if shown != self.shown or t - self.status_t >= STATUS_PERIOD_S:
            self._publish_status()

    def _publish_status(self) -> None:
        t = time.monotonic()
        with self.lock:
            g = self.gateway
            self.shown = (g.live(t), g.owner, g.fence is not None)
            values = g.status(t)
        live, owner = self.shown[0], self.shown[1]
        message = f"action {owner} steering" if owner else "stream live" if live else "no stream"
        self.status_t = t
        self.pub_status.publish(DiagnosticStatus(level=DiagnosticStatus.OK, name="offboard", message=message,
                                                 hardware_id="c4d_offboard",
                                                 values=[KeyValue(key=k, value=v) for k, v in values.items()]))

    def _on_parameters(self, params: list[Any]) -> SetParametersResult:
        """Apply max_age_s / max_future_s / max_rate_hz / live_timeout_s at once (rclpy has already
        refused values outside their descriptor's range or of another type, with the reason)."""
        with self.lock:
            values = asdict(self.gateway.limits)
        for p in params:
            if p.name in PARAMETERS:
                if not math.isfinite(float(p.value)):
                    return SetParametersResult(successful=False, reason=f"{p.name}: {p.value} is not a finite number")
                values[p.name] = float(p.value)
        with self.lock:
            self.gateway.set_limits(limits_of(values))
        return SetParametersResult(successful=True)


class OffboardComponent:
    """c4d_ros.component protocol: the node spins on its own MultiThreadedExecutor in a thread (the
    action servers' execute callbacks block), so no shared executor spins it (`nodes` is empty).
    `step` watches that thread: a callback that raised ends the process (the supervisor restarts it)."""

    name = "offboard"
    nodes: tuple[Any, ...] = ()
    events_executor = False
    rt_priority = 0
    period_s = 0.5

    def __init__(self, node: Any, side_node: Any, gateway: OffboardNode) -> None:
        from rclpy.executors import MultiThreadedExecutor

        self.node, self.side_node, self.gateway = node, side_node, gateway
        self.actions = ActionServers(node, gateway, side_node)  # one side node for both navigation/state samplers
        self.executor = MultiThreadedExecutor(num_threads=EXECUTOR_THREADS)
        self.executor.add_node(node)
        self.error: BaseException | None = None
        self.stopped = threading.Event()
        self.thread = threading.Thread(target=self._spin, name="offboard-executor", daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        try:
            self.executor.spin()
        except BaseException as exc:  # reported by step() in the main thread
            if not self.stopped.is_set():
                self.error = exc

    def step(self, budget_s: float) -> None:
        if self.error is not None:
            raise RuntimeError(f"offboard: executor stopped: {type(self.error).__name__}: {self.error}") from self.error
        if budget_s > 0:
            self.stopped.wait(budget_s)

    def release(self) -> None:
        """Lifecycle cleanup: the executor thread stopped, the action servers and the side node gone; the node stays."""
        self.stopped.set()
        self.executor.shutdown(timeout_sec=2.0)
        self.thread.join(timeout=2.0)
        self.actions.destroy()  # and the side node it was given

    def close(self) -> int:
        self.release()
        self.node.destroy_node()
        return 1 if self.error is not None else 0


def component(rclpy, host: Host) -> lifecycle.ManagedComponent:
    """The offboard node as a component (c4d_ros.component): alone or composed with others."""
    node = lifecycle.create_node(rclpy, "offboard")
    try:
        values = declare_all(node, PARAMETERS)
    except ParameterError as err:
        node.destroy_node()
        raise ComponentError(str(err)) from None

    def build() -> OffboardComponent:  # configure (c4d_ros.lifecycle)
        side = rclpy.create_node(m.side_node_name("offboard"))
        try:
            return OffboardComponent(node, side, OffboardNode(node, side, limits_of(values)))
        except ParameterError as err:  # the action servers' parameters (action_*)
            side.destroy_node()
            raise ComponentError(str(err)) from None
    return lifecycle.ManagedComponent("offboard", node, build, period_s=OffboardComponent.period_s, spun=False)


def main(argv: list[str] | None = None) -> int:
    from c4d_ros.component import run_components

    return run_components([("offboard", component)], argv, "offboard", composed=False)


if __name__ == "__main__":
    sys.exit(main())
