"""Issue 20 (items 1-3) over one real-time SITL graph (sim, perception, navigation, core, bridge):

- a QGroundControl-like client downloads every MAVLink parameter (PARAM_REQUEST_LIST): count and
  indices complete, MC_ROLLRATE_P shows the core's value;
- the core's SetParameters service refuses an out-of-range gain and a set that breaks a
  cross-field rule, each with its reason; a valid change is logged with the executive tick it
  took effect at;
- hovering, a scripted roll step (OFFBOARD, attitude level, +-15 deg) is flown with the bundled
  rate P gain, a MAVLink PARAM_SET doubles MC_ROLLRATE_P (PARAM_VALUE echoes 44), the same step
  is flown again: the roll response changes as the linear model of the roll loop predicts
  (c4d_gnc.rate_loop_model, numbers in docs/parameters.md): less overshoot and a shorter 10-50 % rise;
- the core restarted with the same vehicle name starts with the doubled gain (restored from its
  per-vehicle store under XDG_DATA_HOME, here a temporary directory).
"""

from __future__ import annotations

import functools
import math
import re
import socket
import statistics
import time

import pytest
from c4d_testing import call_service, installed_executable, spin_for

from c4d_common import quat
from c4d_gnc.rate_loop_model import step_metrics, step_response

VEHICLE = "live_params_test"
STEP = math.radians(15.0)
PLATEAU_S = 0.7
HOVER = 1.5 * 9.80665 / (4 * 9.0)  # quad_x: weight / total max thrust


def roll_step_model(kp: float) -> tuple[float, float]:
    """(overshoot, 10-50 % rise [s]) the linear model (c4d_gnc.rate_loop_model) predicts for a STEP roll step."""
    return step_metrics(step_response(kp, step=STEP), 0.0, STEP)


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def graph(module_processes, ros_node, tmp_path_factory):
    xdg = tmp_path_factory.mktemp("xdg")
    port = free_udp_port()
    core_argv = [installed_executable("c4d_gnc", "core"), "--ros-args", "-p", "rt_priority:=50", "-p", f"vehicle:={VEHICLE}"]
    procs = {name: module_processes.spawn(name, argv, XDG_DATA_HOME=str(xdg)) for name, argv in (
        ("sim", [installed_executable("c4d_sim", "sim")]),
        ("perception", [installed_executable("c4d_gnc", "perception")]),
        ("navigation", [installed_executable("c4d_gnc", "navigation")]),
        ("core", core_argv),
        ("bridge", [installed_executable("c4d_bridge_mavlink", "bridge"), "--ros-args", "-p",
                    f"endpoints:=['udpin:127.0.0.1:{port}']", "-p", f"param_file:={xdg / 'bridge.yaml'}"]))}
    return (*ros_node, procs, module_processes, port, xdg, core_argv)


class Gcs:
    def __init__(self, port: int) -> None:
        from pymavlink import mavutil

        self.conn = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255, source_component=190,
                                               dialect="common")
        self.M = mavutil.mavlink

    def heartbeat(self) -> None:
        self.conn.mav.heartbeat_send(self.M.MAV_TYPE_GCS, self.M.MAV_AUTOPILOT_INVALID, 0, 0, 0)

    def recv(self, kind: str, timeout: float, where=lambda m: True):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            m = self.conn.recv_match(type=kind, blocking=True, timeout=0.2)
            if m is not None and where(m):
                return m
        return None


def _set(spin, client, name: str, value):
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter

    reply = call_service(spin, client, SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()]))
    return reply.results[0]


def _get(spin, client, name: str):
    from rcl_interfaces.srv import GetParameters
    from rclpy.parameter import parameter_value_to_python

    return parameter_value_to_python(call_service(spin, client, GetParameters.Request(names=[name])).values[0])


def test_live_gains_mavlink_and_persistence(graph):
    from nav_msgs.msg import Odometry
    from rcl_interfaces.srv import GetParameters, SetParameters
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    from c4d_interfaces.msg import GuidanceSetpoint
    from c4d_interfaces.srv import VehicleCommand

    node, executor, procs, group, port, xdg, core_argv = graph
    spin = functools.partial(spin_for, executor, watch=(group, procs))
    set_client = node.create_client(SetParameters, "core/set_parameters")
    get_client = node.create_client(GetParameters, "core/get_parameters")
    command = node.create_client(VehicleCommand, "gnc/command")
    truth: list[tuple[float, float, float, tuple]] = []  # stamp, roll, z, orientation

    def on_truth(m) -> None:
        q = m.pose.pose.orientation
        o = (q.w, q.x, q.y, q.z)
        truth.append((m.header.stamp.sec + m.header.stamp.nanosec * 1e-9, quat.to_euler(o)[0], m.pose.pose.position.z, o))

    best = QoSProfile(depth=50, reliability=ReliabilityPolicy.BEST_EFFORT)
    node.create_subscription(Odometry, "sim/ground_truth", on_truth, best)

    # --- ROS: refusals with the reason, a valid change applied at a tick boundary
    assert set_client.wait_for_service(timeout_sec=30.0)
    too_big = _set(spin, set_client, "gains.rate.roll.p", 1000.0)
    assert not too_big.successful and "out of range" in too_big.reason and "200" in too_big.reason, too_big.reason
    crossed = _set(spin, set_client, "limits.min_thrust_ratio", 0.97)
    assert not crossed.successful and "must be below limits.max_thrust_ratio" in crossed.reason, crossed.reason
    wrong = _set(spin, set_client, "gains.rate.roll.p", "fast")
    assert not wrong.successful and "type" in wrong.reason.lower()
    ok = _set(spin, set_client, "gains.rate.yaw.i", 4.5)
    assert ok.successful, ok.reason
    assert spin(5.0, lambda: "parameters applied at tick" in group.log_of(procs["core"]))
    applied = re.search(r"parameters applied at tick (\d+): gains.rate.yaw.i=4.5", group.log_of(procs["core"]))
    assert applied, group.log_of(procs["core"])[-2000:]
    assert _get(spin, get_client, "gains.rate.yaw.i") == 4.5

    # --- MAVLink: full parameter download (count, every index once), the core's value shown
    gcs = Gcs(port)
    gcs.heartbeat()
    spin(1.0)
    gcs.heartbeat()
    gcs.conn.mav.param_request_list_send(1, 1)
    values: dict[str, object] = {}
    indices: set[int] = set()
    while (m := gcs.recv("PARAM_VALUE", 5.0)) is not None:
        values[m.param_id], count = m, m.param_count
        indices.add(m.param_index)
        if len(values) == count:
            break
    assert values and len(values) == count and indices == set(range(count)), (len(values), sorted(indices))
    assert values["MC_ROLLRATE_P"].param_value == 22.0 and values["MC_YAWRATE_I"].param_value == 4.5

    # --- hover, then the roll step with the bundled gain
    vehicle = VehicleCommand.Request
    deadline = time.monotonic() + 40.0
    while (reply := call_service(spin, command, vehicle(command=vehicle.CMD_TAKEOFF, altitude=3.0))).result != 0:
        assert time.monotonic() < deadline, f"take-off refused: {reply.message}"
        spin(1.0)
    assert spin(30.0, lambda: truth and truth[-1][2] > 2.7), "no climb to 3 m"
    spin(3.0)
    offboard = node.create_publisher(GuidanceSetpoint, "guidance/offboard", best)
    yaw = quat.yaw_of(truth[-1][3])

    def stream(roll: float, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            sp = GuidanceSetpoint(control_level=GuidanceSetpoint.LEVEL_ATTITUDE, thrust=HOVER / math.cos(roll))
            sp.header.stamp = node.get_clock().now().to_msg()
            w, x, y, z = quat.from_euler(roll, 0.0, yaw)
            sp.orientation.w, sp.orientation.x, sp.orientation.y, sp.orientation.z = w, x, y, z
            sp.yaw = sp.yaw_rate = sp.max_horizontal_speed = sp.max_vertical_speed = math.nan
            for field in (sp.velocity, sp.acceleration):
                field.x = field.y = field.z = math.nan
            offboard.publish(sp)
            spin(0.02)

    def fly_steps() -> list[tuple[float, float]]:
        """0 → +STEP → 0 → −STEP → 0 in OFFBOARD attitude; returns (overshoot, rise) of the four steps."""
        stream(0.0, 1.5)  # the stream must be live >= 1 s before OFFBOARD is accepted
        reply = call_service(spin, command, vehicle(command=vehicle.CMD_SET_MODE, mode=6))
        assert reply.result == 0, reply.message
        stream(0.0, 0.5)
        marks, targets = [], [STEP, 0.0, -STEP, 0.0]
        previous = 0.0
        for target in targets:
            marks.append((node.get_clock().now().nanoseconds * 1e-9, previous, target))
            stream(target, PLATEAU_S)
            previous = target
        end = node.get_clock().now().nanoseconds * 1e-9
        reply = call_service(spin, command, vehicle(command=vehicle.CMD_SET_MODE, mode=3))  # POSITION: hold here
        assert reply.result == 0, reply.message
        results = []
        for k, (t0, start, target) in enumerate(marks):
            t1 = marks[k + 1][0] if k + 1 < len(marks) else end
            segment = [(t, roll) for t, roll, _, _ in truth if t0 <= t < t1]
            assert len(segment) > 0.5 * PLATEAU_S * 100, f"ground truth missing: {len(segment)} samples"
            results.append(step_metrics(segment, start, target))
        return results

    before = fly_steps()
    spin(3.0)

    # --- MAVLink PARAM_SET doubles MC_ROLLRATE_P; PARAM_VALUE echoes what the core applied
    gcs.conn.mav.param_set_send(1, 1, b"MC_ROLLRATE_P", 44.0, gcs.M.MAV_PARAM_TYPE_REAL32)
    echo = gcs.recv("PARAM_VALUE", 5.0, lambda m: m.param_id == "MC_ROLLRATE_P")
    assert echo is not None and echo.param_value == 44.0
    assert _get(spin, get_client, "gains.rate.roll.p") == 44.0
    gcs.conn.mav.param_set_send(1, 1, b"MC_ROLLRATE_P", math.nan, gcs.M.MAV_PARAM_TYPE_REAL32)
    error = gcs.recv("PARAM_ERROR", 5.0)
    assert error is not None and error.error == gcs.M.MAV_PARAM_ERROR_VALUE_OUT_OF_RANGE
    after = fly_steps()

    # --- the response against the linear model
    (over_22, rise_22), (over_44, rise_44) = roll_step_model(22.0), roll_step_model(44.0)
    m_over_22, m_rise_22 = statistics.median(o for o, _ in before), statistics.median(r for _, r in before)
    m_over_44, m_rise_44 = statistics.median(o for o, _ in after), statistics.median(r for _, r in after)
    report = (f"roll step {math.degrees(STEP):.0f} deg: model overshoot {over_22:.1%} -> {over_44:.1%}, 10-50 % rise "
              f"{rise_22 * 1e3:.0f} -> {rise_44 * 1e3:.0f} ms (ratio {rise_44 / rise_22:.2f}); measured overshoot "
              f"{m_over_22:.1%} -> {m_over_44:.1%}, rise {m_rise_22 * 1e3:.0f} -> {m_rise_44 * 1e3:.0f} ms "
              f"(ratio {m_rise_44 / m_rise_22:.2f}); steps {before} / {after}")
    print(report)
    assert m_over_44 < m_over_22, report  # direction: the doubled P damps the attitude loop's overshoot
    assert m_over_22 - m_over_44 > 0.5 * (over_22 - over_44), report  # and by roughly the predicted amount
    assert m_rise_44 < m_rise_22, report  # the faster rate loop: a shorter rise
    assert abs(m_rise_44 / m_rise_22 - rise_44 / rise_22) < 0.25, report

    # --- restart the core: the doubled gain is restored from the vehicle's store
    store = xdg / "c4d" / "vehicles" / VEHICLE / "core.yaml"
    assert spin(5.0, lambda: store.exists() and "gains.rate.roll.p: 44.0" in store.read_text()), "not persisted"
    core = procs.pop("core")
    core.send_signal(2)
    assert core.wait(15) == 0
    procs["core"] = group.spawn("core2", core_argv, XDG_DATA_HOME=str(xdg))
    assert spin(20.0, lambda: "restored" in group.log_of(procs["core"])), group.log_of(procs["core"])[-2000:]
    assert "gains.rate.roll.p=44" in group.log_of(procs["core"]) and "gains.rate.yaw.i=4.5" in group.log_of(procs["core"])
    assert _get(spin, get_client, "gains.rate.roll.p") == 44.0
