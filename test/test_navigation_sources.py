"""Navigation beyond GNSS over the whole graph (issue 19), judged against the simulator's ground truth.

Three graphs, each flown once with a bundled mission (waypoints in the local frame, the geofence in
latitude/longitude: without GNSS the configured origin must be right):
1. GNSS off from boot, external pose over ROS, missions/square.yaml (the sim's emulator: 100 Hz, 30 ms latency, 1 cm noise):
   hover 30 s (horizontal RMS estimate error < 0.10 m), then the square (completes, max error < 0.5 m).
2. The same with the pose arriving over MAVLink VISION_POSITION_ESTIMATE through the bridge (hover 15 s).
3. GNSS and external pose, external primary, missions/survey.yaml: the external source lost
   mid-mission → GNSS (no estimate step > 0.3 m), back to external once it returns (no step), then GNSS
   spoofed with a 1 m/s drift while the external source is healthy: flagged within 5 s, the estimate's
   true error stays < 1 m, the survey completes on the external source.
The spoofing with no other source (hold → land) is flown in test_failsafes_in_flight.py's graph.
"""

from __future__ import annotations

import functools
import math
import time
from pathlib import Path

import numpy as np
import pytest
from c4d_testing import call_service, installed_executable, spin_for, upload_plan

from c4d_common.geodesy import GeoOrigin

REPO = Path(__file__).resolve().parents[1]
SIM_HOME = GeoOrigin(43.5629, 1.4815, 146.0)  # the start of config/sim.yaml
ORIGIN = ["-p", f"origin_latitude_deg:={SIM_HOME.latitude}", "-p", f"origin_longitude_deg:={SIM_HOME.longitude}",
          "-p", f"origin_altitude_m:={SIM_HOME.altitude}"]
EXTERNAL_ONLY = ["-p", "horizontal_primary:=external", "-p", "horizontal_secondary:=none", *ORIGIN]


def graph_nodes(sim: list[str], navigation: list[str], bridge: bool = False) -> list[tuple[str, str, list[str]]]:
    nodes = [("c4d_sim", "sim", ["--ros-args", *sim]), ("c4d_gnc", "perception", []),
             ("c4d_gnc", "navigation", ["--ros-args", *navigation]),
             ("c4d_gnc", "core", ["--ros-args", "-p", "rt_priority:=50"]), ("c4d_mission", "mission", []),
             ("c4d_health", "health", [])]
    if bridge:
        nodes.append(("c4d_bridge_mavlink", "bridge", []))
    return nodes


class NavFlight:
    """The test's view of one graph: estimate vs ground truth, sources, failsafes, mission."""

    def __init__(self, node, executor, processes, nodes) -> None:
        from diagnostic_msgs.msg import DiagnosticStatus
        from nav_msgs.msg import Odometry
        from rcl_interfaces.srv import SetParameters
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        from c4d_interfaces.msg import EstimatorStatus, MissionState, VehicleStatus
        from c4d_interfaces.srv import MissionControl, UploadMission, VehicleCommand

        self.procs = {name: processes.spawn(name, [installed_executable(pkg, name), *args]) for pkg, name, args in nodes}
        self.group = processes
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        best = QoSProfile(depth=50, reliability=ReliabilityPolicy.BEST_EFFORT)
        self.truth: list[tuple[float, float, float, float]] = []  # (t, x, y, z)
        self.estimate: list[tuple[float, float, float, float]] = []
        self.nav_status = None
        self.status = None
        self.mission = None
        self.failsafes: set[str] = set()
        self.summary: dict[str, str] = {}
        node.create_subscription(Odometry, "sim/ground_truth", functools.partial(self._on_odometry, self.truth), best)
        node.create_subscription(Odometry, "navigation/odometry", functools.partial(self._on_odometry, self.estimate), best)
        self.status_changes: list[str] = []  # navigation/status transitions, for failure messages
        node.create_subscription(EstimatorStatus, "navigation/status", self._on_nav_status, latched)
        node.create_subscription(VehicleStatus, "vehicle/status", lambda m: setattr(self, "status", m), latched)
        node.create_subscription(MissionState, "mission/state", lambda m: setattr(self, "mission", m), latched)
        node.create_subscription(DiagnosticStatus, "health/summary", self._on_summary, latched)
        self.spin = functools.partial(spin_for, executor, watch=(processes, self.procs))
        self.vehicle = node.create_client(VehicleCommand, "vehicle/command")
        self.upload = node.create_client(UploadMission, "mission/upload")
        self.control = node.create_client(MissionControl, "mission/control")
        self.sim_params = node.create_client(SetParameters, "sim/set_parameters")

    @staticmethod
    def _on_odometry(into: list, msg) -> None:
        p = msg.pose.pose.position
        into.append((msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9, p.x, p.y, p.z))

    def _on_nav_status(self, msg) -> None:
        previous, self.nav_status = self.nav_status, msg
        key = lambda m: (m.horizontal_source, m.external_healthy, m.gnss.state, m.source_switches)  # noqa: E731
        if previous is None or key(previous) != key(msg):
            self.status_changes.append(
                f"{msg.header.stamp.sec % 1000 + msg.header.stamp.nanosec * 1e-9:.2f}: horizontal {msg.horizontal_source}, "
                f"external healthy {msg.external_healthy} (fused {msg.external_fused}, gate {msg.external_rejected_gate}), "
                f"gnss {msg.gnss.state} (alarms {msg.gnss.alarms}, score {msg.gnss.score:.2f}), switches {msg.source_switches}")

    def _on_summary(self, msg) -> None:
        self.summary = {kv.key: kv.value for kv in msg.values}
        self.failsafes.add(self.summary.get("failsafe", "NONE"))

    def logs(self, name: str) -> str:
        return self.group.log_of(self.procs[name])[-2500:]

    def call(self, client, request):
        return call_service(self.spin, client, request)

    def set_sim(self, name: str, value) -> None:
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter

        reply = self.call(self.sim_params, SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()]))
        assert reply.results[0].successful, reply.results[0].reason

    def horizontal_errors(self, since: float, until: float = math.inf) -> np.ndarray:
        """|estimate − truth| horizontally at each estimate sample in [since, until] (sample times),
        the truth interpolated at the estimate's stamp (both on the sim's clock)."""
        truth = np.array(self.truth)
        est = np.array([e for e in self.estimate if since <= e[0] <= until and truth[0, 0] <= e[0] <= truth[-1, 0]])
        assert len(est) > 10, (len(est), len(truth))
        tx = np.interp(est[:, 0], truth[:, 0], truth[:, 1])
        ty = np.interp(est[:, 0], truth[:, 0], truth[:, 2])
        return np.hypot(est[:, 1] - tx, est[:, 2] - ty)

    def estimate_steps(self, since: float, until: float) -> float:
        """Largest jump of the estimate between consecutive odometry samples beyond what the true motion
        explains [m]: a source switch that moves the estimate shows here, flying does not."""
        truth = np.array(self.truth)
        est = np.array([e for e in self.estimate if since <= e[0] <= until])
        assert len(est) > 10, len(est)
        true_xy = np.column_stack([np.interp(est[:, 0], truth[:, 0], truth[:, k]) for k in (1, 2)])
        error = est[:, 1:3] - true_xy
        return float(np.max(np.linalg.norm(np.diff(error, axis=0), axis=1)))

    def now(self) -> float:
        return self.estimate[-1][0] if self.estimate else 0.0

    def wait_ready(self) -> None:
        assert self.spin(60, lambda: self.nav_status is not None and len(self.estimate) > 50 and self.status is not None), \
            (self.nav_status, self.logs("navigation"))

    def take_off(self, altitude: float) -> None:
        from c4d_interfaces.msg import VehicleStatus
        from c4d_interfaces.srv import VehicleCommand

        for _ in range(40):
            reply = self.call(self.vehicle, VehicleCommand.Request(command=VehicleCommand.Request.CMD_TAKEOFF,
                                                                   altitude=altitude))
            if reply.result == VehicleCommand.Response.RESULT_ACCEPTED:
                break
            self.spin(1.0)
        assert reply.result == VehicleCommand.Response.RESULT_ACCEPTED, (reply.message, self.logs("navigation"))
        assert self.spin(30, lambda: self.status.landed_state == VehicleStatus.LANDED_IN_AIR
                         and self.status.nav_state == VehicleStatus.NAV_HOLD), (self.status, self.logs("core"))

    def fly_mission(self, name: str = "square", seconds: float = 150.0, during=None) -> None:
        """Upload missions/<name>.yaml, start it, run `during` (if any), wait until the mission completed
        and the vehicle disarmed."""
        from c4d_common.plan_files import load_plan
        from c4d_interfaces.msg import MissionState
        from c4d_interfaces.srv import MissionControl, UploadMission
        from c4d_ros.plan_msgs import plan_to_msg

        plan = load_plan(REPO / "missions" / f"{name}.yaml")
        reply = upload_plan(self.spin, self.upload, UploadMission.Request(plan=plan_to_msg(plan)))
        assert reply.accepted, reply.errors
        start = self.call(self.control, MissionControl.Request(action=MissionControl.Request.ACTION_START))
        assert start.result == MissionControl.Response.RESULT_ACCEPTED, start.message
        if during is not None:
            during()
        done = self.spin(seconds, lambda: self.mission is not None and self.mission.state == MissionState.STATE_COMPLETED
                         and not self.status.armed)
        if not done:
            print("\nnavigation/status changes:\n  " + "\n  ".join(self.status_changes))
        assert done, (self.mission, self.summary)

    def assert_no_failsafe_action(self) -> None:
        assert self.failsafes <= {"NONE", "WARN"}, (self.failsafes, self.summary, self.status_changes[-30:])


@pytest.fixture
def flight_of(processes, ros_node):
    node, executor = ros_node

    def start(nodes) -> NavFlight:
        return NavFlight(node, executor, processes, nodes)
    return start


def fly_denied(flight: NavFlight, hover_s: float) -> list[str]:
    """GNSS off from boot: hover `hover_s`, then the square; the figures for the report."""
    from c4d_interfaces.msg import VehicleState

    flight.wait_ready()
    flight.take_off(5.0)
    flight.spin(3.0)  # settle after the climb
    t0 = flight.now()
    flight.spin(hover_s)
    hover = flight.horizontal_errors(t0)
    rms = float(np.sqrt(np.mean(hover**2)))
    s = flight.nav_status
    assert s.horizontal_source == VehicleState.SOURCE_EXTERNAL, s
    assert rms < 0.10, (rms, float(hover.max()))
    t1 = flight.now()
    flight.fly_mission("square")
    square = flight.horizontal_errors(t1)
    assert square.max() < 0.5, (float(square.max()), float(np.sqrt(np.mean(square**2))))
    flight.assert_no_failsafe_action()  # no gps_loss failsafe: the external source is healthy
    return [f"hover {hover_s:.0f} s: RMS {rms:.3f} m, max {hover.max():.3f} m ({len(hover)} samples)",
            f"square: completed, max {square.max():.3f} m, RMS {np.sqrt(np.mean(square**2)):.3f} m",
            f"external: fused {s.external_fused}, rate {s.external_rate_hz:.0f} Hz, latency {s.external_latency_s * 1e3:.0f} ms, "
            f"yaw offset {s.external_yaw_offset_deg:.2f} deg"]


def test_gnss_denied_external_pose_over_ros(flight_of):
    flight = flight_of(graph_nodes(["-p", "fault.gps_loss:=true", "-p", "external_pose.enabled:=true"], EXTERNAL_ONLY))
    print("\nGNSS off, external pose over ROS:\n  " + "\n  ".join(fly_denied(flight, hover_s=30.0)))


def test_gnss_denied_external_pose_over_mavlink(flight_of):
    sim = ["-p", "fault.gps_loss:=true", "-p", "external_pose.enabled:=true", "-p", "external_pose.output:=mavlink"]
    flight = flight_of(graph_nodes(sim, EXTERNAL_ONLY, bridge=True))
    print("\nGNSS off, external pose over MAVLink VISION_POSITION_ESTIMATE:\n  "
          + "\n  ".join(fly_denied(flight, hover_s=15.0)))


def test_source_switches_and_spoofing_with_an_external_source(flight_of):
    from c4d_interfaces.msg import GnssIntegrity, VehicleState

    # back to the primary 2 s after it is healthy again (default 5 s): the survey is over in ~70 s
    navigation = ["-p", "horizontal_primary:=external", "-p", "horizontal_secondary:=gnss", "-p", "source_recovery_s:=2.0"]
    flight = flight_of(graph_nodes(["-p", "external_pose.enabled:=true"], navigation))
    flight.wait_ready()
    report: list[str] = []
    source = lambda: flight.nav_status.horizontal_source  # noqa: E731

    def disturbances() -> None:
        assert flight.spin(30, lambda: flight.status.armed and flight.now() > 0 and flight.mission.current_item >= 3), \
            flight.mission
        assert source() == VehicleState.SOURCE_EXTERNAL, flight.nav_status
        # 1. the external source is lost: GNSS takes over without a step
        t0 = flight.now()
        flight.set_sim("external_pose.enabled", False)
        assert flight.spin(5, lambda: source() == VehicleState.SOURCE_GNSS), flight.nav_status
        flight.spin(2.0)
        step = flight.estimate_steps(t0 - 1.0, flight.now())
        assert step < 0.3, step
        report.append(f"external lost -> GNSS: largest estimate step {step:.3f} m")
        # 2. it returns: back to the primary, without a step
        t1 = flight.now()
        flight.set_sim("external_pose.enabled", True)
        assert flight.spin(20, lambda: source() == VehicleState.SOURCE_EXTERNAL), flight.nav_status
        flight.spin(2.0)
        step = flight.estimate_steps(t1, flight.now())
        assert step < 0.3, step
        report.append(f"external back -> external after {flight.now() - t1:.1f} s: largest estimate step {step:.3f} m")
        # 3. GNSS spoofed (1 m/s drift east) while the external source is healthy
        t2, wall = flight.now(), time.monotonic()
        flight.set_sim("fault.gps_drift_m_s", [1.0, 0.0, 0.0])
        assert flight.spin(5, lambda: flight.nav_status.gnss.state == GnssIntegrity.STATE_SPOOFED), flight.nav_status.gnss
        report.append(f"1 m/s drift flagged SPOOFED after {time.monotonic() - wall:.1f} s (alarms "
                      f"{flight.nav_status.gnss.alarms}, score {flight.nav_status.gnss.score:.1f})")
        flight.spin(5.0)
        errors = flight.horizontal_errors(t2)
        assert errors.max() < 1.0, float(errors.max())
        assert source() == VehicleState.SOURCE_EXTERNAL, flight.nav_status
        report.append(f"while spoofed: estimate error max {errors.max():.3f} m, source external")

    flight.fly_mission("survey", during=disturbances)
    flight.assert_no_failsafe_action()  # spoofed with a healthy external source in use: a warning, no action
    s = flight.nav_status
    report.append(f"survey completed; switches {s.source_switches}, GNSS integrity state {s.gnss.state}")
    print("\nexternal primary, GNSS secondary:\n  " + "\n  ".join(report))
