"""The thin ROS side of the `c4d` CLI: one client node watching the graph and calling its services.

GraphLink subscribes to the low-rate topics a ground operator looks at (vehicle/status,
mission/state, health/summary, recorder/status latched; navigation/odometry 50 Hz,
sensors/battery, gnc/executor_stats, guidance/setpoint) and keeps the newest of each in
`latest`; navigation/state (500 Hz) is sampled, not spun (c4d_ros.drain.LatestSampler). Names and
QoS come from the interface manifest (c4d_ros.manifest). Callbacks registered in `listeners`
see every message (the flight summary uses them).
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
        from sensor_msgs.msg import BatteryState

        from c4d_interfaces.msg import ExecutorStats, GuidanceSetpoint, MissionState, VehicleState, VehicleStatus
        from c4d_interfaces.srv import MissionControl, UploadMission, VehicleCommand
        from c4d_ros import manifest as topics
        from c4d_ros.drain import LatestSampler

        self.node = self.rclpy.create_node(f"{name}_{os.getpid()}")
        self.side = self.rclpy.create_node(f"{topics.side_node_name(name)}_{os.getpid()}")
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.latest: dict[str, object] = {}
        self.listeners: dict[str, list[Callable]] = {}
        for key, msg_type, topic in (
                ("status", VehicleStatus, topics.STATUS),
                ("mission", MissionState, topics.MISSION_STATE),
                ("health", DiagnosticStatus, topics.HEALTH_SUMMARY),
                ("recorder", DiagnosticStatus, topics.RECORDER_STATUS),
                ("odometry", Odometry, topics.NAV_ODOMETRY),
                ("battery", BatteryState, topics.BATTERY),
                ("stats", ExecutorStats, topics.EXECUTOR_STATS),
                ("setpoint", GuidanceSetpoint, topics.SETPOINT)):
            self.node.create_subscription(msg_type, topic.name, self._store(key), topic.qos)
        self.state = LatestSampler(self.side, VehicleState, topics.NAV_STATE.name, topics.NAV_STATE.qos)
        self.upload = self.node.create_client(UploadMission, topics.MISSION_UPLOAD.name)
        self.control = self.node.create_client(MissionControl, topics.MISSION_CONTROL.name)
        self.vehicle = self.node.create_client(VehicleCommand, topics.VEHICLE_COMMAND.name)

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
