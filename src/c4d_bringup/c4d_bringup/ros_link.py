"""The thin ROS side of the `c4d` CLI: one client node watching the graph and calling its services.

GraphLink subscribes to the low-rate topics a ground operator looks at (vehicle/status,
mission/state, health/summary, recorder/status latched; navigation/odometry 50 Hz,
sensors/battery, gnc/executor_stats, guidance/setpoint) and keeps the newest of each in
`latest`; navigation/state (500 Hz) is sampled, not spun (c4d_gnc.ros_drain.LatestSampler).
Callbacks registered in `listeners` see every message (the flight summary uses them).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable


class GraphLink:
    def __init__(self, name: str = "c4d_cli") -> None:
        from c4d_ros import node_runtime

        self.rclpy = node_runtime.init([])
        from diagnostic_msgs.msg import DiagnosticStatus
        from nav_msgs.msg import Odometry
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import BatteryState

        from c4d_interfaces.msg import ExecutorStats, GuidanceSetpoint, MissionState, VehicleState, VehicleStatus
        from c4d_interfaces.srv import MissionControl, UploadMission, VehicleCommand
        from c4d_ros.drain import LatestSampler

        self.node = self.rclpy.create_node(f"{name}_{os.getpid()}")
        self.side = self.rclpy.create_node(f"_{name}_samples_{os.getpid()}")
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        best = QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
        self.latest: dict[str, object] = {}
        self.listeners: dict[str, list[Callable]] = {}
        for key, msg_type, topic, qos in (
                ("status", VehicleStatus, "vehicle/status", latched),
                ("mission", MissionState, "mission/state", latched),
                ("health", DiagnosticStatus, "health/summary", latched),
                ("recorder", DiagnosticStatus, "recorder/status", latched),
                ("odometry", Odometry, "navigation/odometry", best),
                ("battery", BatteryState, "sensors/battery", best),
                ("stats", ExecutorStats, "gnc/executor_stats", 10),
                ("setpoint", GuidanceSetpoint, "guidance/setpoint", best)):
            self.node.create_subscription(msg_type, topic, self._store(key), qos)
        self.state = LatestSampler(self.side, VehicleState, "navigation/state",
                                   QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
        self.upload = self.node.create_client(UploadMission, "mission/upload")
        self.control = self.node.create_client(MissionControl, "mission/control")
        self.vehicle = self.node.create_client(VehicleCommand, "vehicle/command")

    def _store(self, key: str) -> Callable:
        def store(msg) -> None:
            self.latest[key] = msg
            for listener in self.listeners.get(key, ()):
                listener(msg)
        return store

    def listen(self, key: str, callback: Callable) -> None:
        self.listeners.setdefault(key, []).append(callback)

    def spin(self, seconds: float, until: Callable[[], bool] | None = None, watch: Callable[[], None] | None = None) -> bool:
        """Spin up to `seconds`; True as soon as `until()` holds (or after the whole time without it).
        `watch()` is called between spins and may raise to abort."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.05)
            if watch is not None:
                watch()
            if until is not None and until():
                return True
        return until is None

    def call(self, client, request, timeout: float = 15.0, watch: Callable[[], None] | None = None):
        """The service's response, or None if it is not available or does not answer in time."""
        if not self.spin(timeout, client.service_is_ready, watch):
            return None
        future = client.call_async(request)
        if not self.spin(timeout, future.done, watch):
            client.remove_pending_request(future)
            return None
        return future.result()

    def state_valid(self, mask: int) -> bool:
        s = self.state.latest()
        return s is not None and s.valid & mask == mask

    def node_names(self) -> set[str]:
        return {n for n, _ in self.node.get_node_names_and_namespaces()}

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.side.destroy_node()
        self.rclpy.try_shutdown()


def key_values(status) -> dict[str, str]:
    """The key/value pairs of a diagnostic_msgs/DiagnosticStatus."""
    return {kv.key: kv.value for kv in status.values} if status is not None else {}
