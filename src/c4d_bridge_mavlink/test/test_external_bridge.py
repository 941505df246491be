"""The real bridge process with MAVLink position inputs (issue 19): a pymavlink companion (system 1,
component 197) and a GCS (system 255) in a child process send VISION_POSITION_ESTIMATE, ODOMETRY,
ATT_POS_MOCAP and GPS_INPUT over UDP, then bad frames (NaN, an unsupported frame, another vehicle's
companion) and a 1 kHz flood for 1 s; this process checks the converted ROS messages on
navigation/external/{pose,odometry,gnss} (ENU / FLU, sample time = the UNIX-time stamp sent), the
drops counted per reason in bridge/link_stats, the flood limited to external_max_rate_hz, one warning
line per reason in the bridge's log, and ESTIMATOR_STATUS with GPS_GLITCH once navigation/status
says SPOOFED. No other node runs (the bridge alone is the unit)."""

from __future__ import annotations

import json
import math
import socket
import sys
import time

import pytest
from c4d_testing import installed_executable, spin_for

MAX_RATE_HZ = 250.0  # the bridge's default external_max_rate_hz
CLIENT = r"""
import json, math, os, sys, time
os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil
from pymavlink.dialects.v20 import common as M
port = int(sys.argv[1])
vio = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=1, source_component=197, dialect="common")
gcs = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255, source_component=190, dialect="common")
stranger = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=7, source_component=197, dialect="common")
def say(**kw):
    print(json.dumps(kw), flush=True)
end = time.monotonic() + 20  # until the bridge answers (its telemetry comes to known peers)
while time.monotonic() < end and vio.recv_match(blocking=True, timeout=0.2) is None:
    vio.mav.heartbeat_send(M.MAV_TYPE_ONBOARD_CONTROLLER, M.MAV_AUTOPILOT_INVALID, 0, 0, 0)
gcs.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, 0)
time.sleep(0.3)
unknown = [math.nan] + [0.0] * 20
cov = [0.0] * 21
for i, v in zip((0, 6, 11, 15, 18, 20), (0.01, 0.04, 0.09, 0.001, 0.002, 0.003)):
    cov[i] = v
usec = round((time.time() - 0.030) * 1e6)  # sampled 30 ms ago (UNIX time)
vio.mav.vision_position_estimate_send(usec, 1.0, 2.0, -3.0, 0.1, 0.2, 0.3, cov, 0)
say(sent="vpe", usec=usec)
time.sleep(0.05)
usec = round((time.time() - 0.020) * 1e6)
vio.mav.odometry_send(usec, M.MAV_FRAME_LOCAL_NED, M.MAV_FRAME_BODY_FRD, 4.0, 5.0, -6.0, [1.0, 0.0, 0.0, 0.0],
                      1.0, 2.0, 3.0, 0.1, 0.2, 0.3, unknown, unknown, 0, M.MAV_ESTIMATOR_TYPE_VIO, 100)
say(sent="odometry", usec=usec)
time.sleep(0.05)
vio.mav.att_pos_mocap_send(round(time.time() * 1e6), [1.0, 0.0, 0.0, 0.0], 7.0, 8.0, -9.0, unknown)
time.sleep(0.05)
gcs.mav.gps_input_send(round(time.time() * 1e6), 0, 0, 0, 0, 3, round(43.5 * 1e7), round(1.48 * 1e7), 146.0, 0.8, 1.2,
                       0.0, 0.0, 0.0, 0.0, 0.5, 0.9, 12)
time.sleep(0.05)
for _ in range(3):
    vio.mav.vision_position_estimate_send(round(time.time() * 1e6), math.nan, 2.0, -3.0, 0.0, 0.0, 0.0, unknown, 0)
vio.mav.odometry_send(round(time.time() * 1e6), M.MAV_FRAME_LOCAL_ENU, M.MAV_FRAME_BODY_FRD, 4.0, 5.0, -6.0,
                      [1.0, 0.0, 0.0, 0.0], 1.0, 2.0, 3.0, 0.1, 0.2, 0.3, unknown, unknown, 0, 0, 100)
stranger.mav.vision_position_estimate_send(round(time.time() * 1e6), 1.0, 1.0, 1.0, 0.0, 0.0, 0.0, unknown, 0)
vio.mav.vision_position_estimate_send(round((time.time() - 10.0) * 1e6), 1.0, 1.0, 1.0, 0.0, 0.0, 0.0, unknown, 0)
time.sleep(0.3)
say(sent="flood_start")
start, sent = time.monotonic(), 0
while (elapsed := time.monotonic() - start) < 1.0:  # 1 kHz for 1 s
    while sent < elapsed * 1000:
        vio.mav.vision_position_estimate_send(round(time.time() * 1e6), 0.5, 0.5, -0.5, 0.0, 0.0, 0.0, unknown, 0)
        sent += 1
    time.sleep(0.0005)
say(sent="flood_end", count=sent)
time.sleep(0.2)
vio.mav.vision_position_estimate_send(round(time.time() * 1e6), 11.0, 12.0, -13.0, 0.0, 0.0, 0.0, unknown, 0)
say(sent="after")
end = time.monotonic() + 10
while time.monotonic() < end:  # ESTIMATOR_STATUS as the test's navigation/status says
    m = gcs.recv_match(type="ESTIMATOR_STATUS", blocking=True, timeout=0.5)
    if m is not None:
        say(estimator_status=m.flags, ratio=m.pos_horiz_ratio)
        if m.flags & M.ESTIMATOR_GPS_GLITCH:
            break
say(done=True)
"""


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def lines_of(text: str) -> list[dict]:
    out = []
    for line in text.splitlines():
        if line.startswith("{"):
            out.append(json.loads(line))
    return out


@pytest.fixture(scope="module")
def session(module_processes, ros_node):
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import PoseWithCovarianceStamped
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import NavSatFix

    from c4d_interfaces.msg import EstimatorStatus, GnssIntegrity, VehicleState
    from c4d_ros import manifest as m

    node, executor = ros_node
    got: dict[str, list] = {"pose": [], "odometry": [], "gnss": [], "stats": []}
    for msg_type, topic, key in ((PoseWithCovarianceStamped, m.EXTERNAL_POSE, "pose"), (Odometry, m.EXTERNAL_ODOMETRY,
                                 "odometry"), (NavSatFix, m.EXTERNAL_GNSS, "gnss"), (DiagnosticArray, m.LINK_STATS, "stats")):
        node.create_subscription(msg_type, topic.name, lambda msg, k=key: got[k].append((time.time(), msg)),
                                 m.EXTERNAL_POSE.qos if key != "stats" else topic.qos)
    pub_state = node.create_publisher(VehicleState, m.NAV_STATE.name, m.NAV_STATE.qos)
    pub_status = node.create_publisher(EstimatorStatus, m.NAV_STATUS.name, m.NAV_STATUS.qos)
    port = free_udp_port()
    bridge = module_processes.spawn("bridge", [installed_executable("c4d_bridge_mavlink", "bridge"), "--ros-args",
                                               "-p", f"endpoints:=['udpin:127.0.0.1:{port}']"])
    status = EstimatorStatus(horizontal_source=VehicleState.SOURCE_EXTERNAL)
    status.gnss.state, status.gnss.score = GnssIntegrity.STATE_SPOOFED, 2.5
    pub_status.publish(status)
    state = VehicleState(valid=VehicleState.VALID_ATTITUDE | VehicleState.VALID_POSITION_XY | VehicleState.VALID_POSITION_Z)
    state.orientation.w = 1.0
    watch = (module_processes, {"bridge": bridge})
    # the bridge is up and its publishers matched ours once its link statistics arrive (about 1 s)
    assert spin_for(executor, 20, lambda: bool(got["stats"]), watch=watch), "no bridge/link_stats"
    spin_for(executor, 0.5)
    client = module_processes.spawn("client", [sys.executable, "-c", CLIENT, str(port)])
    deadline = time.monotonic() + 35
    while client.poll() is None and time.monotonic() < deadline:
        pub_state.publish(state)
        spin_for(executor, 0.1, watch=watch)
    assert client.poll() == 0, f"client: {module_processes.log_of(client)}"
    spin_for(executor, 1.5)  # the next link statistics
    return got, lines_of(module_processes.log_of(client)), module_processes.log_of(bridge)


def first(items, pred):
    return next(msg for _, msg in items if pred(msg))


def stamp_s(header) -> float:
    return header.stamp.sec + header.stamp.nanosec * 1e-9


def test_inputs_converted_to_enu_flu_at_their_sample_time(session):
    got, said, _ = session
    sent = {line["sent"]: line for line in said if "sent" in line}
    pose = first(got["pose"], lambda p: abs(p.pose.pose.position.x - 2.0) < 1e-4)
    assert pose.header.frame_id == "odom"
    p = pose.pose.pose.position
    assert (round(p.x, 4), round(p.y, 4), round(p.z, 4)) == (2.0, 1.0, 3.0)  # NED (1, 2, -3) → ENU
    assert abs(stamp_s(pose.header) - sent["vpe"]["usec"] * 1e-6) < 0.002  # the sample time, not the arrival
    cov = pose.pose.covariance
    c, s = math.cos(0.3) ** 2, math.sin(0.3) ** 2  # yaw 0.3 rad: roll / pitch errors about the world axes
    want = [0.04, 0.01, 0.09, s * 0.001 + c * 0.002, c * 0.001 + s * 0.002, 0.003]
    assert [round(cov[i * 7], 6) for i in range(6)] == [round(w, 6) for w in want]
    odom = first(got["odometry"], lambda o: True)
    assert (odom.pose.pose.position.x, odom.pose.pose.position.y, odom.pose.pose.position.z) == (5.0, 4.0, 6.0)
    v = odom.twist.twist.linear
    assert (v.x, v.y, v.z) == (1.0, -2.0, -3.0) and odom.child_frame_id == "base_link"  # body FRD → FLU
    assert abs(stamp_s(odom.header) - sent["odometry"]["usec"] * 1e-6) < 0.002
    o = odom.pose.pose.orientation  # level, facing north: ENU yaw 90°
    assert abs(o.w - math.sqrt(0.5)) < 1e-6 and abs(o.z - math.sqrt(0.5)) < 1e-6
    mocap = first(got["pose"], lambda p: abs(p.pose.pose.position.x - 8.0) < 1e-4)
    assert mocap.pose.pose.position.z == pytest.approx(9.0)
    fix = first(got["gnss"], lambda f: True)
    assert fix.latitude == pytest.approx(43.5, abs=1e-7) and fix.status.status == 0
    assert fix.position_covariance[0] == pytest.approx(0.25) and fix.position_covariance_type == 2
    after = [msg for _, msg in got["pose"] if abs(msg.pose.pose.position.x - 12.0) < 1e-4]
    assert after, "a sample after the flood still goes through"


def test_bad_frames_and_flood_counted_never_forwarded(session):
    got, said, log = session
    assert not [1 for _, p in got["pose"] if not math.isfinite(p.pose.pose.position.y)]
    assert not [1 for _, p in got["pose"] if abs(p.pose.pose.position.x - 1.0) < 1e-4]  # stranger's / stale
    stats = [s for _, array in got["stats"] for s in array.status if s.name == "bridge/external"]
    counts = {kv.key: kv.value for kv in stats[-1].values}
    assert int(counts["rejected_invalid"]) == 3 and int(counts["rejected_frame"]) == 1
    assert int(counts["rejected_source"]) == 1 and int(counts["rejected_stale"]) == 1
    flood = next(line["count"] for line in said if line.get("sent") == "flood_end")
    forwarded = int(counts["accepted_VISION_POSITION_ESTIMATE"]) - 2  # the first and the last
    assert forwarded <= MAX_RATE_HZ * 1.2 + 10, counts
    assert int(counts["rejected_rate"]) == flood - forwarded and int(counts["rejected_rate"]) >= flood - 320
    assert counts["clock_1_197"] == "epoch"
    for reason in ("invalid", "frame", "source", "stale", "rate"):
        assert log.count(f"external input dropped ({reason},") == 1, reason  # one line per reason (10 s period)


def test_estimator_status_reports_the_gnss_glitch(session):
    _, said, _ = session
    reports = [line for line in said if "estimator_status" in line]
    assert reports, "no ESTIMATOR_STATUS"
    import pymavlink.dialects.v20.common as M

    last = reports[-1]
    assert last["estimator_status"] & M.ESTIMATOR_GPS_GLITCH and last["estimator_status"] & M.ESTIMATOR_ATTITUDE
    assert last["ratio"] == pytest.approx(2.5)
