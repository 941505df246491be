"""`ros2 run c4d_health health` — monitors, diagnostics, failsafe requests.

Monitors (10 Hz): node liveliness (each watched node's periodic topic silent longer than
`node_timeout_s` of the monitor's own running time: liveness.py), GNSS health
(perception/health), estimator validity (navigation/state), battery state of charge
(sensors/battery), geofence (mission/plan against the position),
ground link (a heartbeat topic, when `link_topic` is set), executor overruns
(gnc/executor_stats). Publishes `diagnostics` (DiagnosticArray, 1 Hz, one status per monitor)
and `health/summary` (DiagnosticStatus: overall level, active events, failsafe action and
reason, dead nodes). The failsafe policy (config/failsafe.yaml, parameter `policy_file`)
turns events into hold / RTL / land / terminate, requested once per escalation through the
mission's vehicle/command (RTL needs the mission), falling back to the core's gnc/command.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from c4d_common.geodesy import GeoOrigin
from c4d_common.share import share_file
from c4d_ros.drain import LatestSampler

from .liveness import LivenessMonitor
from .policy import Action, FailsafeArbiter, FailsafePolicy, PolicyError

TICK_S = 0.1  # monitor period
WATCHED = {  # node: topic that proves it alive (>= 5 Hz)
    "core": "vehicle/status",
    "navigation": "navigation/odometry",
    "perception": "perception/health",
    "mission": "mission/state",
    "sim": "sensors/battery",
}


def default_policy() -> Path:
    """The installed config/failsafe.yaml of c4d_health (the source tree's copy when not installed)."""
    return share_file("c4d_health", "config", "failsafe.yaml")


def main(argv: list[str] | None = None) -> int:
    from c4d_ros import node_runtime

    rclpy = node_runtime.init(argv)
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from nav_msgs.msg import Odometry
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import BatteryState
    from std_msgs.msg import Header

    from c4d_common.plan_validation import leg_inside
    from c4d_interfaces.msg import ExecutorStats, MissionPlan, MissionState, VehicleState, VehicleStatus
    from c4d_interfaces.srv import VehicleCommand
    from c4d_ros.plan_msgs import plan_from_msg

    node = rclpy.create_node("health")
    try:
        path = node.declare_parameter("policy_file", "").value
        policy = FailsafePolicy.from_yaml(path or default_policy())
    except PolicyError as exc:
        return node_runtime.fail("health", str(exc), node)
    link_topic = node.declare_parameter("link_topic", "").value
    watched = dict(WATCHED)
    for name in node.declare_parameter("unwatched_nodes", [""]).value:
        watched.pop(name, None)
    arbiter = FailsafeArbiter(policy)
    best = QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    pub_diag = node.create_publisher(DiagnosticArray, "diagnostics", 10)
    pub_summary = node.create_publisher(DiagnosticStatus, "health/summary", latched)
    mission_cmd = node.create_client(VehicleCommand, "vehicle/command")
    core_cmd = node.create_client(VehicleCommand, "gnc/command")
    w: dict = {"dead": [], "state": None, "status": None, "battery": None, "plan": None, "gps": None, "overruns": None,
               "overruns_new": 0, "link": None, "requested": Action.NONE, "last_diag": 0.0}

    def now() -> float:
        return node.get_clock().now().nanoseconds * 1e-9

    liveness = LivenessMonitor(watched, policy.node_timeout_s, TICK_S, now())

    def seen(name: str):
        def mark(msg) -> None:
            liveness.heard(name, now())
        return mark

    for name, topic in watched.items():
        types = {"vehicle/status": VehicleStatus, "navigation/odometry": Odometry, "perception/health": DiagnosticArray,
                 "mission/state": MissionState, "sensors/battery": BatteryState}
        qos = latched if topic in ("vehicle/status", "mission/state") else (10 if topic == "perception/health" else best)
        node.create_subscription(types[topic], topic, seen(name), qos)

    def on_health(msg) -> None:
        for s in msg.status:
            if s.hardware_id == "gps":
                w["gps"] = (s.level, s.message)

    def on_stats(msg) -> None:
        if w["overruns"] is not None and msg.overruns_total > w["overruns"]:
            w["overruns_new"] = msg.overruns_total - w["overruns"]
        else:
            w["overruns_new"] = 0
        w["overruns"] = msg.overruns_total

    node.create_subscription(DiagnosticArray, "perception/health", on_health, 10)
    # 500 Hz: sampled at the 10 Hz tick instead of waking the executor for every sample
    state_sampler = LatestSampler(rclpy.create_node("_health_samples"), VehicleState, "navigation/state",
                                  QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
    node.create_subscription(VehicleStatus, "vehicle/status", lambda m: w.__setitem__("status", m), latched)
    node.create_subscription(BatteryState, "sensors/battery", lambda m: w.__setitem__("battery", m), best)
    node.create_subscription(MissionPlan, "mission/plan", lambda m: w.__setitem__("plan", plan_from_msg(m)), latched)
    node.create_subscription(ExecutorStats, "gnc/executor_stats", on_stats, 10)
    if link_topic:
        node.create_subscription(Header, link_topic, lambda m: w.__setitem__("link", now()), best)

    def events(t: float, dead: list[str]) -> dict[str, str]:
        active: dict[str, str] = {}
        if dead:
            active["node_dead"] = ", ".join(dead)  # sorted by the monitor
        if w["gps"] is not None and w["gps"][0] != DiagnosticStatus.OK:
            active["gps_loss"] = f"GNSS {w['gps'][1]}"
        s = w["state"]
        needed = VehicleState.VALID_ATTITUDE | VehicleState.VALID_POSITION_XY
        if s is not None and s.valid & needed != needed:
            active["estimator_invalid"] = "position or attitude estimate not valid"
        b = w["battery"]
        if b is not None and math.isfinite(b.percentage):
            if b.percentage < policy.battery_critical:
                active["battery_critical"] = f"{b.percentage:.0%}"
            elif b.percentage < policy.battery_low:
                active["battery_low"] = f"{b.percentage:.0%}"
        plan = w["plan"]
        if plan is not None and s is not None and s.valid & VehicleState.VALID_ORIGIN:
            home = GeoOrigin(s.origin.latitude, s.origin.longitude, s.origin.altitude)
            here = (s.position.x, s.position.y)
            fence = plan.geofence
            if fence.polygon:
                polygon = [home.to_enu(lat, lon, home.altitude)[:2] for lat, lon in fence.polygon]
                if not leg_inside(here, here, polygon):
                    active["geofence_breach"] = "outside the inclusion polygon"
            if fence.max_altitude > 0 and s.position.z > fence.max_altitude:
                active["geofence_breach"] = f"{s.position.z:.1f} m above the {fence.max_altitude:g} m ceiling"
            if fence.max_distance > 0 and math.hypot(*here) > fence.max_distance:
                active["geofence_breach"] = f"{math.hypot(*here):.0f} m from home"
        if link_topic and (w["link"] is None or t - w["link"] > 3.0):
            active["link_loss"] = f"no heartbeat on {link_topic} for 3 s"
        if w["overruns_new"]:
            active["executor_overrun"] = f"{w['overruns_new']} new overrun(s)"
        return active

    def request(action: Action) -> None:
        commands = {Action.HOLD: (6, 0), Action.RTL: (5, 0), Action.LAND: (4, 0), Action.TERMINATE: (7, 5)}
        if action not in commands:
            return
        command, mode = commands[action]
        client = mission_cmd if mission_cmd.service_is_ready() and "mission" not in w["dead"] else core_cmd
        if client is core_cmd and action == Action.RTL:
            command = 4  # RTL needs the mission node: land instead
        future = client.call_async(VehicleCommand.Request(command=command, mode=mode, force=True))

        def done(f) -> None:
            reply = f.result()
            if reply is None or reply.result != 0:
                node.get_logger().error(f"failsafe {action.name} refused: {reply.message if reply else 'no reply'}")
                if client is mission_cmd:  # fall back to the core directly
                    core_cmd.call_async(VehicleCommand.Request(command=4 if command == 5 else command, mode=mode,
                                                               force=True))
        future.add_done_callback(done)
        node.get_logger().warning(f"failsafe {action.name}: {arbiter.reason}")

    def tick() -> None:
        t = now()
        w["state"] = state_sampler.latest()
        st = w["status"]
        armed = st is not None and st.armed
        in_air = st is not None and st.landed_state in (VehicleStatus.LANDED_IN_AIR, VehicleStatus.LANDED_TAKEOFF,
                                                        VehicleStatus.LANDED_LANDING)
        if not armed and arbiter.action != Action.NONE:
            arbiter.reset()
            w["requested"] = Action.NONE
        w["dead"] = liveness.dead(t)
        active = events(t, w["dead"])
        action = arbiter.update(t, active, in_air)
        if action > w["requested"]:
            w["requested"] = action
            request(action)
        level = DiagnosticStatus.ERROR if action >= Action.HOLD else (DiagnosticStatus.WARN if active else DiagnosticStatus.OK)
        summary = DiagnosticStatus(level=level, name="c4d/health", hardware_id="vehicle",
                                   message=f"failsafe {action.name}: {arbiter.reason}" if action >= Action.HOLD else
                                   ("ok" if not active else "; ".join(f"{k}: {v}" for k, v in active.items())))
        summary.values = [KeyValue(key="failsafe", value=action.name), KeyValue(key="reason", value=arbiter.reason),
                          KeyValue(key="active", value=",".join(sorted(active))),
                          KeyValue(key="dead_nodes", value=active.get("node_dead", ""))]
        pub_summary.publish(summary)
        if t - w["last_diag"] >= 1.0:
            w["last_diag"] = t
            array = DiagnosticArray()
            array.header.stamp = node.get_clock().now().to_msg()
            for event in ("node_dead", "gps_loss", "estimator_invalid", "battery_low", "battery_critical",
                          "geofence_breach", "link_loss", "executor_overrun"):
                on = event in active
                array.status.append(DiagnosticStatus(level=DiagnosticStatus.ERROR if on else DiagnosticStatus.OK,
                                                     name=f"health/{event}", hardware_id="vehicle",
                                                     message=active.get(event, "ok")))
            pub_diag.publish(array)

    node.create_timer(TICK_S, tick)
    return node_runtime.spin_node(node, events_executor=False)


if __name__ == "__main__":
    sys.exit(main())
