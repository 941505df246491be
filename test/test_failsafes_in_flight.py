"""Failsafes over the whole graph in real time, each fault injected through the sim (or, for
the geofence, by a fence set in flight with force around a vehicle already outside it, after a
forced go-to beyond the plan's fence that the core's barrier stops short of it, issue 18): GNSS
loss → land, geofence breach → RTL, GNSS spoofed with no other source → hold then land, low
battery → RTL then critical → land (never back), a dead node detected within 1 s. The action,
its reason and its timing are asserted from health/summary; the vehicle's reaction from
vehicle/status and the ground truth."""

from __future__ import annotations

import functools
import math
import os
import signal
import time

import pytest
from c4d_testing import call_service, installed_executable, spin_for, upload_plan

NODES = [("c4d_sim", "sim", []), ("c4d_gnc", "perception", []), ("c4d_gnc", "navigation", []),
         ("c4d_gnc", "core", ["--ros-args", "-p", "rt_priority:=50"]), ("c4d_mission", "mission", []),
         ("c4d_health", "health", [])]
# a small fence (15 m from home) and a low RTL altitude keep the geofence scenario short
FENCED_PLAN = """
name: fenced hop
rtl_altitude: 6
geofence: {max_altitude: 20, max_distance: 15}
items:
  - {type: takeoff, altitude: 5}
  - {type: waypoint, east: 5, north: 5, alt: 5}
  - {type: land}
"""


@pytest.fixture(scope="module")
def graph(module_processes, ros_node):
    procs = {name: module_processes.spawn(name, [installed_executable(pkg, name), *args]) for pkg, name, args in NODES}
    return (*ros_node, procs, module_processes)


class Flight:
    """The test's view of the vehicle and its ground station actions."""

    def __init__(self, node, executor, procs, group) -> None:
        from diagnostic_msgs.msg import DiagnosticStatus
        from nav_msgs.msg import Odometry
        from rcl_interfaces.srv import SetParameters
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        from c4d_interfaces.msg import VehicleStatus
        from c4d_interfaces.srv import UploadMission, VehicleCommand

        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.summaries: list[tuple[float, dict[str, str]]] = []
        self.status = None
        self.truth = (0.0, 0.0, 0.0)
        node.create_subscription(DiagnosticStatus, "health/summary", self._on_summary, latched)
        node.create_subscription(VehicleStatus, "vehicle/status", lambda m: setattr(self, "status", m), latched)
        node.create_subscription(Odometry, "sim/ground_truth", self._on_truth,
                                 QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
        self.vehicle = node.create_client(VehicleCommand, "vehicle/command")
        self.upload = node.create_client(UploadMission, "mission/upload")
        self.params = node.create_client(SetParameters, "sim/set_parameters")
        self.spin = functools.partial(spin_for, executor, watch=(group, procs))
        self.group, self.procs = group, procs

    def logs(self, name: str) -> str:
        return self.group.log_of(self.procs[name])[-3000:]

    def _on_summary(self, msg) -> None:
        self.summaries.append((time.monotonic(), {kv.key: kv.value for kv in msg.values}))

    def _on_truth(self, msg) -> None:
        p = msg.pose.pose.position
        self.truth = (p.x, p.y, p.z)

    @property
    def failsafe(self) -> str:
        return self.summaries[-1][1]["failsafe"] if self.summaries else "NONE"

    @property
    def summary(self) -> dict[str, str]:
        return self.summaries[-1][1] if self.summaries else {}

    def call(self, client, request):
        return call_service(self.spin, client, request)

    def fault(self, name: str, value) -> None:
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter

        reply = self.call(self.params, SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()]))
        assert reply.results[0].successful, reply.results[0].reason

    def command(self, command: int, **fields):
        from c4d_interfaces.srv import VehicleCommand

        return self.call(self.vehicle, VehicleCommand.Request(command=command, **fields))

    def take_off(self, altitude: float = 5.0) -> None:
        """Take off once the pre-arm checks pass (they refuse while the estimator aligns)."""
        from c4d_interfaces.msg import VehicleStatus
        from c4d_interfaces.srv import VehicleCommand

        for _ in range(40):
            reply = self.command(VehicleCommand.Request.CMD_TAKEOFF, altitude=altitude)
            if reply.result == VehicleCommand.Response.RESULT_ACCEPTED:
                break
            self.spin(1.0)
        assert reply.result == VehicleCommand.Response.RESULT_ACCEPTED, (reply.message, self.truth,
                                                                          self.logs("navigation")[-3000:])
        assert self.spin(25, lambda: self.status is not None and self.status.landed_state == VehicleStatus.LANDED_IN_AIR
                         and self.status.nav_state == VehicleStatus.NAV_HOLD), (self.status, self.truth, self.logs("core"))
        self.spin(1.0)
        assert self.failsafe in ("NONE", "WARN"), self.summary  # WARN: a platform-stall overrun, no action

    def wait_failsafe(self, action: str, seconds: float) -> float:
        """Seconds until health/summary reports `action`."""
        t0 = time.monotonic()
        assert self.spin(seconds, lambda: self.failsafe == action), (action, self.summary)
        return time.monotonic() - t0

    def wait_landed(self, seconds: float) -> None:
        assert self.spin(seconds, lambda: self.status is not None and not self.status.armed), ("not disarmed", self.status)
        assert self.spin(5, lambda: self.failsafe in ("NONE", "WARN")), self.summary  # reset on disarm


def test_failsafes_in_flight(graph):
    from c4d_common.plan import plan_from_yaml_text
    from c4d_interfaces.srv import UploadMission, VehicleCommand
    from c4d_ros.plan_msgs import plan_to_msg

    node, executor, procs, group = graph
    f = Flight(node, executor, procs, group)
    report = []

    # --- GNSS loss → LAND. Policy: gps_loss after 3 s; its consequence estimator_invalid (no
    # position update for 1 s) after 1 s more — whichever fires first, the action is LAND.
    f.take_off()
    f.fault("fault.gps_loss", True)
    waited = f.wait_failsafe("LAND", 8.0)
    assert 1.0 <= waited <= 3.0 + 1.0, waited  # never before the shortest delay, at most one monitor period late
    assert f.summary["reason"].startswith(("gps_loss", "estimator_invalid")), f.summary
    report.append(f"gps loss → LAND after {waited:.1f} s ({f.summary['reason']})")
    f.wait_landed(40)
    f.fault("fault.gps_loss", False)

    # --- geofence breach → RTL: a forced go-to 25 m out with a 15 m fence
    plan = plan_from_yaml_text(FENCED_PLAN)
    reply = upload_plan(f.spin, f.upload, UploadMission.Request(plan=plan_to_msg(plan)))
    assert reply.accepted, reply.errors
    f.spin(3.0)  # GNSS back: let the estimator converge before the pre-arm checks
    f.take_off()
    target = node_target(f, east=25.0)
    refused = f.command(VehicleCommand.Request.CMD_GOTO, target=target, yaw=math.nan)
    assert refused.result == VehicleCommand.Response.RESULT_DENIED and "exceeds the geofence" in refused.message
    forced = f.command(VehicleCommand.Request.CMD_GOTO, target=target, yaw=math.nan, force=True)
    assert forced.result == VehicleCommand.Response.RESULT_ACCEPTED, forced.message
    farthest = 0.0

    def track() -> bool:
        nonlocal farthest
        farthest = max(farthest, math.hypot(*f.truth[:2]))
        return False

    f.spin(10.0, track)  # the core's barrier stops the vehicle inside the 15 m fence (geofence/active)
    assert 10.0 < farthest < 15.0, farthest
    assert f.failsafe in ("NONE", "WARN"), f.summary
    # the last line of defence: a fence set with force that the vehicle is outside of
    from c4d_common.plan import Geofence
    from c4d_interfaces.srv import SetGeofence
    from c4d_ros.plan_msgs import geofence_to_msg

    set_fence = graph[0].create_client(SetGeofence, "geofence/set")
    t_set = time.monotonic()
    answer = f.call(set_fence, SetGeofence.Request(fence=geofence_to_msg(Geofence(max_altitude=20.0, max_distance=8.0)),
                                                   force=True))
    assert answer.result == SetGeofence.Response.RESULT_ACCEPTED, answer.message
    f.wait_failsafe("RTL", 6.0)
    waited = time.monotonic() - t_set
    assert waited <= 1.0 + 1.0, waited  # policy delay 1 s + one 10 Hz monitor period and the service call
    assert f.summary["reason"].startswith("geofence_breach"), f.summary
    report.append(f"forced go-to 25 m out stopped by the barrier at {farthest:.1f} m (fence 15 m); a fence of 8 m set "
                  f"with force → geofence_breach RTL {waited:.1f} s later")
    f.wait_landed(60)
    assert math.hypot(*f.truth[:2]) < 2.0, f.truth  # landed at home
    # the operator widens the fence again: the scenarios below must not depend on where the spoofed flight lands
    answer = f.call(set_fence, SetGeofence.Request(fence=geofence_to_msg(Geofence(max_altitude=20.0, max_distance=100.0)),
                                                   force=True))
    assert answer.result == SetGeofence.Response.RESULT_ACCEPTED, answer.message

    # --- GNSS spoofed (a 1 m/s drift east) with no other horizontal source (issue 19): flagged,
    # the fixes no longer fused (dead reckoning), HOLD, then LAND; the true excursion stays small
    f.take_off()
    start, t_spoof, farthest = f.truth, time.monotonic(), 0.0
    phases: dict[str, float] = {}  # the true distance from the start when each failsafe state was first seen

    def excursion() -> bool:
        nonlocal farthest
        distance = math.dist(f.truth[:2], start[:2])
        farthest = max(farthest, distance)
        phases.setdefault(f.failsafe, distance)
        return False

    f.fault("fault.gps_drift_m_s", [1.0, 0.0, 0.0])
    assert f.spin(10.0, lambda: excursion() or f.failsafe == "HOLD"), (f.summary, f.logs("navigation"))
    flagged = time.monotonic() - t_spoof
    assert f.summary["reason"].startswith("gnss_spoofed"), f.summary
    assert f.spin(10.0, lambda: excursion() or f.failsafe == "LAND"), f.summary
    assert f.spin(40, lambda: excursion() or (f.status is not None and not f.status.armed)), ("not disarmed", f.status)
    # without the cut-off the vehicle would follow the drift at 1 m/s for the ~14 s to touchdown (computed, not
    # flown). Issue 19 asks for < 5 m. Drag fusion keeps the horizontal velocity valid in the dead reckoning that
    # follows the undo, so the core brakes and holds still on it (before: a level blind descent, 5.8-8.1 m)
    touchdown = math.dist(f.truth[:2], start[:2])
    print(f"\nspoofing excursion {farthest:.2f} m, phases {phases}, touchdown {touchdown:.2f} m", flush=True)
    print("\n".join(line for line in f.logs("navigation").splitlines() if "SPOOFED" in line or "undone" in line))
    assert farthest < 5.0, farthest
    report.append(f"GNSS spoofed (1 m/s drift), no other source → HOLD {flagged:.1f} s later, then LAND; true "
                  f"horizontal excursion {farthest:.2f} m (at HOLD {phases.get('HOLD', math.nan):.2f} m, at LAND "
                  f"{phases.get('LAND', math.nan):.2f} m, touchdown {touchdown:.2f} m)")
    f.fault("fault.gps_drift_m_s", [0.0, 0.0, 0.0])  # the spoofer stops: the receiver reports the truth again
    assert f.spin(5, lambda: f.failsafe in ("NONE", "WARN")), f.summary  # reset on disarm
    f.spin(8.0)  # the integrity monitor re-admits GNSS after its recovery time

    # --- low battery → RTL, then critical → LAND; most severe wins, never back to RTL
    f.take_off()
    first = len(f.summaries)
    f.fault("fault.battery_drain_factor", 25.0)
    f.wait_failsafe("RTL", 60.0)
    assert "battery_low" in f.summary["reason"], f.summary
    t_rtl = time.monotonic()
    f.wait_failsafe("LAND", 40.0)
    assert "battery_critical" in f.summary["reason"], f.summary
    report.append(f"battery low → RTL, critical → LAND {time.monotonic() - t_rtl:.1f} s later")
    seen = [s[1]["failsafe"] for s in f.summaries[first:]]
    assert "RTL" not in seen[seen.index("LAND"):]  # no oscillation
    f.wait_landed(40)

    # --- a killed node is reported within 1 s (policy timeout 0.6 s + one 10 Hz monitor period)
    mission = procs.pop("mission")
    os.killpg(mission.pid, signal.SIGKILL)
    t0 = time.monotonic()
    # silent within 1 s; "stalled" until DDS drops the killed participant from the graph, then "dead"
    assert f.spin(5, lambda: "mission" in f.summary.get("stalled_nodes", "") + f.summary.get("dead_nodes", "")), f.summary
    detected = time.monotonic() - t0
    assert detected <= 1.0, detected
    report.append(f"killed node 'mission' reported silent after {detected:.2f} s")
    print("\n" + "\n".join(report))


def node_target(f: Flight, east: float):
    """A GeoPoint `east` metres east of home at 5 m (the sim's home = the estimator's origin)."""
    from c4d_common.geodesy import GeoOrigin
    from c4d_interfaces.msg import GeoPoint

    lat, lon, _ = GeoOrigin(43.5629, 1.4815, 146.0).to_geodetic(east, 0.0, 0.0)
    return GeoPoint(latitude=lat, longitude=lon, altitude=5.0)
