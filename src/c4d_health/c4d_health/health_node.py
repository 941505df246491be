"""`ros2 run c4d_health health` — monitors, diagnostics, failsafe requests.

Monitors (10 Hz): node liveliness (each watched node's periodic topic silent longer than
`node_timeout_s` of the monitor's own running time — the offboard gateway's 1 Hz offboard/status
2.5 s, once heard: dead if also gone from the ROS graph,
stalled if still in it — the graph sampled once a second: liveness.py), GNSS health
(perception/health), estimator validity (navigation/state), battery state of charge
(sensors/battery), geofence (geofence/active — the fence in force, incl. exclusion zones and the
floor while flying — against the position), obstacles (perception/surroundings, sampled at the
tick: obstacle_near inside the detection range, obstacle_collision_risk inside the protection
radius),
ground link (a heartbeat topic, when `link_topic` is set), executor overruns and core stalls
(gnc/executor_stats: core_stall.py), the offboard stream (guidance/offboard, sampled at the
tick, silent for `offboard_loss_timeout_s` while the core is in OFFBOARD: offboard_loss), the
navigation's sources and GNSS integrity (navigation/status: gnss_spoofed / gnss_jammed without
another healthy horizontal source, *_switched with one; gps_loss not while one is in use), the
lifecycle states of the liveness-watched nodes (`/<node>/transition_event`: node_inactive,
lifecycle_watch.py); the conditions are judged by events.py. Publishes `diagnostics`
(DiagnosticArray, 1 Hz, one status per monitor) and `health/summary` (DiagnosticStatus: overall
level, active events, failsafe action and reason, dead, stalled and inactive nodes). The failsafe policy
(config/failsafe.yaml, parameter `policy_file`) turns events into hold / RTL / land /
terminate, requested once per escalation through the mission's vehicle/command (RTL needs the
mission), falling back to the core's gnc/command (commands.py).
The policy's thresholds and timeouts (top-level fields, events.<event>.delay_s / then_after_s) are
live parameters (live_policy.py, docs/parameters.md): checked when set (a refusal says why, e.g. a
critical battery threshold not below the low one), swapped in whole at the next tick boundary
(logged with the tick), persisted per vehicle (health.yaml) when `vehicle` is set.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from lifecycle_msgs.msg import TransitionEvent
from nav_msgs.msg import Odometry
from sensor_msgs.msg import BatteryState
from std_msgs.msg import Header

from c4d_common.geodesy import GeoOrigin
from c4d_common.geofence import Point3
from c4d_common.plan import Geofence, PlanError
from c4d_common.share import share_file
from c4d_common.tunable import TunableError, VehicleStore
from c4d_common.vehicle import CommandResult, Landed, Mode
from c4d_interfaces.msg import (
    EstimatorStatus,
    ExecutorStats,
    GnssIntegrity,
    GuidanceSetpoint,
    MissionState,
    Surroundings,
    VehicleState,
    VehicleStatus,
)
from c4d_interfaces.msg import Geofence as GeofenceMsg
from c4d_interfaces.srv import VehicleCommand
from c4d_ros import lifecycle, manifest
from c4d_ros.component import ComponentError, Host, SpunNode, run_components
from c4d_ros.drain import LatestSampler
from c4d_ros.live_params import LiveParameters, describe
from c4d_ros.params import ParameterError, Spec, declare_all
from c4d_ros.plan_msgs import geofence_from_msg

from .commands import FailsafeCommand, failsafe_command
from .core_stall import CORE, CoreStallMonitor, CoreStallReport, StatsWindow
from .events import LINK_TIMEOUT_S, Estimate, GnssReport, HealthSnapshot, LinkWatch, NavigationStatus, OffboardWatch, evaluate
from .lifecycle_watch import LifecycleWatch
from .live_policy import policy_table, policy_with
from .liveness import GraphPresence, LivenessMonitor, classify
from .policy import Action, Event, FailsafeArbiter, FailsafePolicy, PolicyError

NAME = "health"
TICK_S = 0.1  # monitor period
DIAGNOSTICS_PERIOD_S = 1.0
GRAPH_SAMPLE_S = 1.0  # the ROS graph's node names are sampled this often (dead vs stalled)
WATCHED = {  # node: topic that proves it alive (>= 5 Hz)
    "core": manifest.STATUS,
    "navigation": manifest.NAV_ODOMETRY,
    "perception": manifest.P_HEALTH,
    "mission": manifest.MISSION_STATE,
    "sim": manifest.BATTERY,
}
# the offboard gateway: its status comes at 1 Hz (not >= 5 Hz), so its own timeout; optional in
# a graph (judged only once heard: a graph without it is not a graph with a dead node)
GATEWAY = ("offboard", manifest.OFFBOARD_STATUS)
GATEWAY_TIMEOUT_S = 2.5  # 2.5 periods of offboard/status
IN_AIR = (Landed.IN_AIR, Landed.TAKEOFF, Landed.LANDING)
OFFBOARD_STREAM = "offboard"  # the liveness name of the guidance/offboard stream
PARAMETERS = {
    "policy_file": Spec("", "failsafe policy YAML file [path]; empty: the bundled config/failsafe.yaml", read_only=True,
                        empty=lambda: default_policy()),
    "link_topic": Spec("", f"ground-link heartbeat topic (std_msgs/Header) [topic name], lost after {LINK_TIMEOUT_S:g} s "
                       f"of silence; empty: not watched; the MAVLink bridge's is {manifest.GCS_HEARTBEAT.name}", read_only=True),
    "unwatched_nodes": Spec([""], f"nodes whose liveness is not monitored [node names among {', '.join(WATCHED)}, "
                            f"{GATEWAY[0]}]", read_only=True),
    "vehicle": Spec("", "vehicle whose changed thresholds persist in $XDG_DATA_HOME/c4d/vehicles/<vehicle>/health.yaml "
                    "and are restored at start; empty: not persisted [name]", read_only=True),
}


def default_policy() -> Path:
    """The installed config/failsafe.yaml of c4d_health (the source tree's copy when not installed)."""
    return share_file("c4d_health", "config", "failsafe.yaml")


@dataclass(frozen=True)
class HealthConfig:
    """The health node's parameters, checked: the policy, the link topic, the watched nodes."""

    policy: FailsafePolicy
    link_topic: str
    watched: dict[str, manifest.Topic]
    watch_gateway: bool = True
    vehicle: str = ""

    @classmethod
    def declare(cls, node: Any) -> HealthConfig:
        """Declare the parameters on `node`; ParameterError / PolicyError name what is wrong."""
        values = declare_all(node, PARAMETERS)
        unwatched = {name for name in values["unwatched_nodes"] if name}
        known = {*WATCHED, GATEWAY[0]}
        if unwatched - known:
            raise ParameterError(f"parameter 'unwatched_nodes': unknown node(s) {', '.join(sorted(unwatched - known))} "
                                 f"(watched: {', '.join(sorted(known))})")
        policy = FailsafePolicy.from_yaml(values["policy_file"] or default_policy())
        return cls(policy, values["link_topic"], {n: t for n, t in WATCHED.items() if n not in unwatched},
                   GATEWAY[0] not in unwatched, values["vehicle"])


GNSS_TESTS = {GnssIntegrity.TEST_INNOVATION: "innovation", GnssIntegrity.TEST_JUMP: "jump",
              GnssIntegrity.TEST_INERTIAL: "inertial", GnssIntegrity.TEST_EXTERNAL: "external",
              GnssIntegrity.TEST_LOSS: "loss", GnssIntegrity.TEST_DEGRADED: "degraded"}


def navigation_of(msg: EstimatorStatus) -> NavigationStatus:
    """The part of navigation/status that health judges."""
    alarms = ", ".join(name for bit, name in GNSS_TESTS.items() if msg.gnss.alarms & bit)
    return NavigationStatus(int(msg.horizontal_source), bool(msg.external_healthy), int(msg.gnss.state),
                            float(msg.gnss.score), alarms)


def estimate_of(msg: VehicleState) -> Estimate:
    """The part of navigation/state that health judges."""
    home = GeoOrigin(msg.origin.latitude, msg.origin.longitude, msg.origin.altitude) \
        if msg.valid & VehicleState.VALID_ORIGIN else None
    position: Point3 = (msg.position.x, msg.position.y, msg.position.z)
    return Estimate(bool(msg.valid & VehicleState.VALID_ATTITUDE), bool(msg.valid & VehicleState.VALID_POSITION_XY),
                    position, home)


class HealthNode:
    """Maps the graph to the health logic: subscriptions keep the latest inputs, a 10 Hz tick
    evaluates the events (events.py), lets the arbiter (policy.py) pick the failsafe action,
    requests each escalation once and publishes health/summary and diagnostics."""

    def __init__(self, node: Any, side_node: Any, config: HealthConfig, live: LiveParameters | None = None) -> None:
        self.node, self.config, self.live = node, config, live
        self.ticks = 0
        self.arbiter = FailsafeArbiter(config.policy)
        self.liveness = LivenessMonitor(config.watched, config.policy.node_timeout_s, TICK_S, self._now())
        gateway = (GATEWAY[0],) if config.watch_gateway else ()
        self.gateway = LivenessMonitor(gateway, max(GATEWAY_TIMEOUT_S, config.policy.node_timeout_s), TICK_S, self._now(),
                                       optional=gateway)
        self.graph = GraphPresence(GRAPH_SAMPLE_S)
        self.lifecycle = LifecycleWatch(config.watched)
        self.core_stall = CoreStallMonitor(config.policy.core_stall, TICK_S, self._now())
        self.offboard_stream = LivenessMonitor((OFFBOARD_STREAM,), config.policy.offboard_loss_timeout_s, TICK_S,
                                               self._now())
        self.armed = self.in_air = self.flying = False
        self.mode: Mode | None = None  # the core's, from vehicle/status
        self.gnss: GnssReport | None = None
        self.navigation: NavigationStatus | None = None
        self.battery_soc: float | None = None
        self.geofence: Geofence | None = None
        self.overruns_total: int | None = None
        self.new_overruns = 0
        self.link_heard: float | None = None
        self.dead: tuple[str, ...] = ()
        self.stalled: tuple[str, ...] = ()
        self.core_stall_report: CoreStallReport | None = None
        self.last_diagnostics = 0.0
        self.pub_diagnostics = node.create_publisher(DiagnosticArray, manifest.DIAGNOSTICS.name, manifest.DIAGNOSTICS.qos)
        self.pub_summary = node.create_publisher(DiagnosticStatus, manifest.HEALTH_SUMMARY.name, manifest.HEALTH_SUMMARY.qos)
        self.mission_cmd = node.create_client(VehicleCommand, manifest.VEHICLE_COMMAND.name)
        self.core_cmd = node.create_client(VehicleCommand, manifest.CORE_COMMAND.name)
        # 500 Hz: sampled at the 10 Hz tick instead of waking the executor for every sample
        self.state = LatestSampler(side_node, VehicleState, manifest.NAV_STATE.name, manifest.NAV_STATE.qos)
        # up to 100 Hz: a new sample seen at the tick proves the stream alive (0.1 s resolution is plenty for 0.5 s)
        self.offboard = LatestSampler(side_node, GuidanceSetpoint, manifest.OFFBOARD_SETPOINT.name,
                                      manifest.OFFBOARD_SETPOINT.qos)
        self.offboard_seen: object = None
        # 10-20 Hz: only the latest matters at the 10 Hz tick
        self.surroundings = LatestSampler(side_node, Surroundings, manifest.SURROUNDINGS.name, manifest.SURROUNDINGS.qos)
        self._subscribe()
        node.create_timer(TICK_S, self._tick)

    def _now(self) -> float:
        return self.node.get_clock().now().nanoseconds * 1e-9

    def _subscribe(self) -> None:
        """One subscription per topic: its data handler and/or the liveness of the node it proves alive."""
        owners = {topic: name for name, topic in self.config.watched.items()}
        for topic, msg_type, handle in (
                (manifest.STATUS, VehicleStatus, self._on_status),
                (manifest.P_HEALTH, DiagnosticArray, self._on_perception_health),
                (manifest.BATTERY, BatteryState, self._on_battery),
                (manifest.GEOFENCE, GeofenceMsg, self._on_fence),
                (manifest.EXECUTOR_STATS, ExecutorStats, self._on_stats),
                (manifest.NAV_STATUS, EstimatorStatus, self._on_navigation_status),
                (manifest.NAV_ODOMETRY, Odometry, None),
                (manifest.MISSION_STATE, MissionState, None)):
            if handle is not None or topic in owners:
                self.node.create_subscription(msg_type, topic.name, self._listener(handle, owners.get(topic)), topic.qos)
        for name in self.config.watched:  # every managed node's standard topic (default QoS: reliable, volatile)
            self.node.create_subscription(TransitionEvent, f"{name}/transition_event",
                                          partial(self._on_transition, name), 10)
        if self.config.link_topic:
            self.node.create_subscription(Header, self.config.link_topic, self._on_link, manifest.GCS_HEARTBEAT.qos)
        if self.config.watch_gateway:
            name, topic = GATEWAY
            self.node.create_subscription(DiagnosticStatus, topic.name, lambda _: self.gateway.heard(name, self._now()),
                                          topic.qos)

    def _listener(self, handle: Callable[[Any], None] | None, owner: str | None) -> Callable[[Any], None]:
        def on_message(msg: Any) -> None:
            if owner is not None:
                self.liveness.heard(owner, self._now())
            if handle is not None:
                handle(msg)
        return on_message

    def _on_transition(self, name: str, msg: TransitionEvent) -> None:
        self.lifecycle.on_transition(name, msg.goal_state.id)

    def _on_status(self, msg: VehicleStatus) -> None:
        self.armed, self.in_air = bool(msg.armed), msg.landed_state in IN_AIR
        self.flying = self.armed and msg.landed_state == Landed.IN_AIR
        mode = Mode(msg.flight_mode) if msg.flight_mode in Mode._value2member_map_ else Mode.UNKNOWN
        if mode == Mode.OFFBOARD and self.mode not in (None, Mode.OFFBOARD) and self.arbiter.clear(Event.OFFBOARD_LOSS):
            # the operator switched back to OFFBOARD (the core accepts it only with a live stream): taken over
            self.node.get_logger().info("offboard_loss failsafe cleared: OFFBOARD re-entered with a live stream")
        self.mode = mode

    def _on_perception_health(self, msg: DiagnosticArray) -> None:
        for s in msg.status:
            if s.hardware_id == "gps":
                self.gnss = GnssReport(s.level == DiagnosticStatus.OK, s.message)

    def _on_navigation_status(self, msg: EstimatorStatus) -> None:
        self.navigation = navigation_of(msg)

    def _on_battery(self, msg: BatteryState) -> None:
        self.battery_soc = float(msg.percentage)

    def _on_fence(self, msg: GeofenceMsg) -> None:
        try:
            fence = geofence_from_msg(msg)
        except PlanError as exc:  # the mission node validates what it publishes: never expected
            self.node.get_logger().error(f"{manifest.GEOFENCE.name} unusable, keeping the previous fence: {exc}")
            return
        self.geofence = None if fence.empty else fence

    def _on_stats(self, msg: ExecutorStats) -> None:
        total = int(msg.overruns_total)
        previous, self.overruns_total = self.overruns_total, total
        self.new_overruns = total - previous if previous is not None and total > previous else 0
        self.core_stall.on_stats(self._now(), StatsWindow(float(msg.tick_rate_hz), float(msg.load_max_percent),
                                                          int(msg.skipped_ticks)))

    def _on_link(self, msg: Any) -> None:
        self.link_heard = self._now()

    def _offboard_watch(self, t: float) -> OffboardWatch | None:
        """Whether the core is in OFFBOARD and when guidance/offboard was last heard (monitor running time)."""
        latest = self.offboard.latest()
        if latest is not None and latest is not self.offboard_seen:  # a sample taken since the last tick
            self.offboard_seen = latest
            self.offboard_stream.heard(OFFBOARD_STREAM, t)
        self.offboard_stream.silent(t)  # discounts the monitor's own stalls
        if self.mode is None:
            return None
        return OffboardWatch(self.mode == Mode.OFFBOARD, self.offboard_stream.last_seen[OFFBOARD_STREAM])

    def snapshot(self, t: float) -> HealthSnapshot:
        state = self.state.latest()
        link = LinkWatch(self.config.link_topic, self.link_heard) if self.config.link_topic else None
        around = self.surroundings.latest()
        obstacles = tuple((o.position.x, o.position.y, float(o.radius)) for o in around.obstacles) \
            if around is not None else None
        return HealthSnapshot(self.dead, self.gnss, estimate_of(state) if state is not None else None, self.battery_soc,
                              self.geofence, link, self.new_overruns, self.stalled, self.core_stall_report,
                              self._offboard_watch(t), self.flying, obstacles, self.navigation,
                              self.lifecycle.not_active(self.armed))

    def retune(self, changes: dict[str, float]) -> None:
        """Live threshold changes, in force from this tick on: the frozen policy swapped whole into the
        arbiter, the event evaluation and the monitors that copied a timeout."""
        policy = policy_with(self.config.policy, changes)
        self.config = replace(self.config, policy=policy)
        self.arbiter.policy = policy
        self.liveness.timeout_s = policy.node_timeout_s
        self.gateway.timeout_s = max(GATEWAY_TIMEOUT_S, policy.node_timeout_s)
        self.core_stall.limits = policy.core_stall
        self.core_stall.silence.timeout_s = policy.core_stall.stats_timeout_s
        self.offboard_stream.timeout_s = policy.offboard_loss_timeout_s
        self.node.get_logger().info(f"parameters applied at health tick {self.ticks}: {describe(changes)}")

    def _tick(self) -> None:
        t = self._now()
        self.ticks += 1
        changes = self.live.take() if self.live is not None else {}
        if changes:  # validated when set; the tick boundary: no evaluation sees half a change
            self.retune(changes)
        if not self.armed and self.arbiter.action != Action.NONE:
            self.arbiter.reset()
        if self.graph.due(t):
            self.graph.update(t, (name for name, _ in self.node.get_node_names_and_namespaces()))
        silence = classify(self.liveness.silent(t) + self.gateway.silent(t), self.graph.names)
        self.dead, self.stalled = silence.dead, silence.stalled
        self.core_stall_report = self.core_stall.check(t, self.graph.present(CORE))
        active = evaluate(self.snapshot(t), self.config.policy, t)
        before = self.arbiter.action
        action = self.arbiter.update(t, active, self.in_air)
        if action > before:  # the action only escalates until reset: request each escalation once
            self._request(action)
        self._publish_summary(action, active)
        if t - self.last_diagnostics >= DIAGNOSTICS_PERIOD_S:
            self.last_diagnostics = t
            self._publish_diagnostics(active)

    def _request(self, action: Action) -> None:
        # a stalled mission would not answer: ask the core directly
        via_mission = self.mission_cmd.service_is_ready() and "mission" not in self.dead + self.stalled
        command = failsafe_command(action, via_mission)
        if command is None:
            return
        client = self.mission_cmd if via_mission else self.core_cmd
        future = client.call_async(self._command_request(command))
        future.add_done_callback(lambda f: self._on_reply(f.result(), action, via_mission))
        self.node.get_logger().warning(f"failsafe {action.name}: {self.arbiter.reason}")

    @staticmethod
    def _command_request(command: FailsafeCommand) -> Any:
        return VehicleCommand.Request(command=int(command.command), mode=int(command.mode), force=True)

    def _on_reply(self, reply: Any, action: Action, via_mission: bool) -> None:
        if reply is not None and reply.result == CommandResult.ACCEPTED:
            return
        self.node.get_logger().error(f"failsafe {action.name} refused: {reply.message if reply else 'no reply'}")
        fallback = failsafe_command(action, via_mission=False)
        if via_mission and fallback is not None:  # fall back to the core directly
            self.core_cmd.call_async(self._command_request(fallback))

    def _publish_summary(self, action: Action, active: dict[str, str]) -> None:
        acting = action >= Action.HOLD
        level = DiagnosticStatus.ERROR if acting else (DiagnosticStatus.WARN if active else DiagnosticStatus.OK)
        message = f"failsafe {action.name}: {self.arbiter.reason}" if acting else \
            ("; ".join(f"{k}: {v}" for k, v in active.items()) or "ok")
        summary = DiagnosticStatus(level=level, name="c4d/health", hardware_id="vehicle", message=message)
        summary.values = [KeyValue(key="failsafe", value=action.name), KeyValue(key="reason", value=self.arbiter.reason),
                          KeyValue(key="active", value=",".join(sorted(active))),
                          KeyValue(key="dead_nodes", value=active.get(Event.NODE_DEAD, "")),
                          KeyValue(key="stalled_nodes", value=active.get(Event.NODE_STALLED, "")),
                          KeyValue(key="inactive_nodes", value=active.get(Event.NODE_INACTIVE, ""))]
        self.pub_summary.publish(summary)

    def _publish_diagnostics(self, active: dict[str, str]) -> None:
        array = DiagnosticArray()
        array.header.stamp = self.node.get_clock().now().to_msg()
        for event in Event:
            array.status.append(DiagnosticStatus(level=DiagnosticStatus.ERROR if event in active else DiagnosticStatus.OK,
                                                 name=f"health/{event}", hardware_id="vehicle",
                                                 message=active.get(event, "ok")))
        self.pub_diagnostics.publish(array)


def component(rclpy, host: Host) -> lifecycle.ManagedComponent:
    """The health node as a component (c4d_ros.component): alone or composed with others."""
    node = lifecycle.create_node(rclpy, NAME)

    def build() -> SpunNode:  # configure (c4d_ros.lifecycle): parameters and the failsafe policy file read and checked
        try:
            config = HealthConfig.declare(node)
            store = VehicleStore.of(config.vehicle, NAME) if config.vehicle else None
            live = LiveParameters(node, policy_table(config.policy), store, node.get_logger().info)
        except (ParameterError, PolicyError, TunableError) as exc:
            raise ComponentError(str(exc)) from None
        config = replace(config, policy=policy_with(config.policy, live.values))
        side = rclpy.create_node(manifest.side_node_name(NAME))
        return SpunNode(NAME, node, False, 0, HealthNode(node, side, config, live), (side,))
    return lifecycle.ManagedComponent(NAME, node, build)


def main(argv: list[str] | None = None) -> int:
    return run_components([(NAME, component)], argv, NAME, composed=False)


if __name__ == "__main__":
    sys.exit(main())
