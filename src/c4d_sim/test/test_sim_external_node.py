"""The sim node's external-pose and GNSS-fault glue, in-process on a private domain: the executive's own
tasks run tick by tick by hand (no real-time loop). Checks what only the glue can get wrong: the
external_pose task in the schedule at its rate, navigation/external/odometry's frame ids, pose in the
source frame, covariance and body twist, stamps on the 10 ms grid; the same samples as MAVLink datagrams
on the configured URL; fault.gps_loss as a start value (GNSS lost from boot: no fix published);
run-time parameters (disable = silence, frame change = reset) and refused ones; bad start values
end the process with one line, exit 2."""

from __future__ import annotations

import copy
import math
import socket
import subprocess

import pytest
from c4d_testing import installed_executable, spin_for
from nav_msgs.msg import Odometry
from pymavlink.dialects.v20 import common as mavlink
from sensor_msgs.msg import NavSatFix

from c4d_ros.manifest import EXTERNAL_ODOMETRY, GPS
from c4d_sim.sim_config import default_sim_config, load_sim_config
from c4d_sim.sim_node import SimNode


@pytest.fixture(scope="module")
def rig(ros_node):
    import rclpy
    from rclpy.parameter import Parameter

    node, executor = ros_node
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.setblocking(False)
    got: dict[str, list] = {"odom": [], "gps": []}
    qos = copy.copy(EXTERNAL_ODOMETRY.qos)
    qos.depth = 200  # the manifest's best effort, deep enough for a burst of ticks run by hand
    node.create_subscription(Odometry, EXTERNAL_ODOMETRY.name, got["odom"].append, qos)
    node.create_subscription(NavSatFix, GPS.name, got["gps"].append, GPS.qos)
    overrides = [Parameter(name, value=value) for name, value in {
        "external_pose.enabled": True, "external_pose.output": "both", "external_pose.noise_m": 0.0,
        "external_pose.yaw_noise_deg": 0.0, "external_pose.velocity_noise_m_s": 0.0,
        "external_pose.frame_offset_m": [1.0, 2.0, 3.0], "external_pose.frame_yaw_deg": 90.0,
        "external_pose.frame_id": "vio_odom", "external_pose.mavlink_sysid": 3,
        "external_pose.mavlink_url": f"udpout:127.0.0.1:{rx.getsockname()[1]}", "fault.gps_loss": True}.items()]
    sim_node = rclpy.create_node("sim", context=node.context, parameter_overrides=overrides)
    sim = SimNode(sim_node, load_sim_config(default_sim_config()))
    assert spin_for(executor, 5.0, until=lambda: node.count_publishers(EXTERNAL_ODOMETRY.name) > 0)
    yield node, executor, sim, got, rx
    sim.node.destroy_node()
    rx.close()


def run_ticks(sim: SimNode, executor, first: int, count: int) -> None:
    """The executive's tasks of ticks first .. first+count-1, in schedule order; the test node spins between."""
    for k in range(first, first + count):
        for task in sim.executive.due(k):
            sim.executive.functions[task.name](k)
        if k % 10 == 0:
            executor.spin_once(timeout_sec=0.0)


def datagrams(rx: socket.socket) -> list:
    parser, out = mavlink.MAVLink(None), []
    while True:
        try:
            out.append(parser.parse_char(rx.recv(512)))
        except BlockingIOError:
            return out


def test_odometry_and_mavlink_at_the_rate_in_the_source_frame_and_no_gnss_from_boot(rig):
    node, executor, sim, got, rx = rig
    assert {t.name: t.divider for t in sim.executive.due(0)}["external_pose"] == 10
    run_ticks(sim, executor, 0, 1000)  # 1 s: samples at 0.01 .. 1.0 s, the last 3 still in their 30 ms latency
    assert spin_for(executor, 5.0, until=lambda: len(got["odom"]) >= 97)
    odom = got["odom"]
    assert len(odom) == 97 and not got["gps"]  # GNSS lost from boot: the gps task ran 10 times, published nothing
    stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in odom]
    assert all(b - a == pytest.approx(0.01, abs=1e-6) for a, b in zip(stamps, stamps[1:], strict=False))
    m = odom[-1]
    assert (m.header.frame_id, m.child_frame_id) == ("vio_odom", "base_link")
    # on the ground at the world origin: in a source frame yawed 90° with its origin at (1, 2, 3): (-2, 1, -3)
    p = m.pose.pose.position
    assert (p.x, p.y, p.z) == pytest.approx((-2.0, 1.0, -3.0), abs=1e-6)
    q = m.pose.pose.orientation
    assert 2 * math.atan2(q.z, q.w) == pytest.approx(sim.sim.config.yaw - math.pi / 2, abs=1e-6)
    assert m.pose.covariance[0] == m.pose.covariance[7] == m.pose.covariance[14] == pytest.approx(1e-6)
    assert m.pose.covariance[21] > 0 and m.pose.covariance[1] == 0.0 and m.twist.covariance[0] == pytest.approx(1e-6)
    frames = [f for f in datagrams(rx) if f.get_type() == "VISION_POSITION_ESTIMATE"]
    assert len(frames) == 97 and (frames[-1].get_srcSystem(), frames[-1].get_srcComponent()) == (3, 197)
    assert frames[-1].usec == round(stamps[-1] * 1e6)
    assert (frames[-1].x, frames[-1].y, frames[-1].z) == pytest.approx((1.0, -2.0, 3.0), abs=1e-6)  # NED of (-2, 1, -3)


def test_run_time_parameters_disable_the_source_and_count_a_frame_reset(rig):
    from rclpy.parameter import Parameter

    node, executor, sim, got, rx = rig
    datagrams(rx)
    results = sim.node.set_parameters([Parameter("external_pose.frame_offset_m", value=[0.0, 0.0, 0.0])])
    assert results[0].successful and sim.external.reset_counter == 1
    run_ticks(sim, executor, 1000, 100)
    assert {f.reset_counter for f in datagrams(rx)} == {0, 1}  # 3 in flight from before the change, then the new frame
    assert not sim.node.set_parameters([Parameter("external_pose.rate_hz", value=50.0)])[0].successful  # read-only
    assert not sim.node.set_parameters([Parameter("external_pose.dropout_probability", value=2.0)])[0].successful
    assert sim.node.set_parameters([Parameter("fault.gps_jam_sigma_factor", value=3.0)])[0].successful
    assert sim.sim.faults.gps_jam_sigma_factor == 3.0
    assert sim.node.set_parameters([Parameter("external_pose.enabled", value=False)])[0].successful
    spin_for(executor, 0.5)
    before = len(got["odom"])
    run_ticks(sim, executor, 1100, 200)
    spin_for(executor, 0.5)
    assert len(got["odom"]) == before and datagrams(rx) == []  # the source is lost: nothing, not even what was in flight


@pytest.mark.parametrize("param, error", [
    ("external_pose.rate_hz:=30.0", "sim: error: parameter 'external_pose.rate_hz': 30 Hz does not divide the physics "
                                    "rate 1000 Hz (50, 100, 200 do)"),
    ("external_pose.output:=udp", "sim: error: parameter 'external_pose.output': 'udp' is not one of ros, mavlink, both"),
])
def test_bad_external_pose_parameters_exit_2_with_one_line(ros_env, param, error):
    done = subprocess.run([installed_executable("c4d_sim", "sim"), "--ros-args", "-p", param,
                           "-p", "external_pose.mavlink_url:=udpout:127.0.0.1"], env=ros_env,
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2, done.stderr
    assert [line for line in done.stderr.splitlines() if line.strip()] == [error]
