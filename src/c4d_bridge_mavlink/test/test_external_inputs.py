"""MAVLink position inputs (issue 19): VISION_POSITION_ESTIMATE / ATT_POS_MOCAP / ODOMETRY / GPS_INPUT
→ c4d's ENU / FLU samples, covariances, sample times, rejections; ESTIMATOR_STATUS flags. Every input
is a pymavlink-encoded frame decoded as the vehicle decodes it (float32 fields, source ids)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from c4d_bridge_mavlink import estimator_status as es
from c4d_bridge_mavlink.external_inputs import (
    COV_APPROXIMATED,
    COV_DIAGONAL_KNOWN,
    NO_FIX,
    RATE_BURST,
    Clocks,
    ExternalInputs,
    GnssSample,
    OdometrySample,
    PoseSample,
    SampleClock,
    pose_covariance_to_enu,
    upper_to_full,
)
from c4d_bridge_mavlink.offboard import Rejected
from c4d_bridge_mavlink.signing import mavlink as M
from c4d_common import quat

VIO = M.MAVLink(None, 1, 197)  # a companion of vehicle 1 (MAV_COMP_ID_VISUAL_INERTIAL_ODOMETRY)
STRANGER = M.MAVLink(None, 7, 197)  # another vehicle's companion
WALL, ROS = 1.7e9, 1.7e9 + 0.25  # a real-time graph: the ROS clock is system time (a quarter second apart here)
NOW = Clocks(100.0, WALL, ROS)
UNKNOWN = [math.nan] + [0.0] * 20


def rx(msg, sender=VIO):
    return M.MAVLink(None, 1, 1).decode(bytearray(msg.pack(sender)))


def upper(matrix) -> list[float]:
    m = np.asarray(matrix, dtype=float)
    return [float(v) for v in m[np.triu_indices(6)]]


def vpe(x=1.0, y=2.0, z=-3.0, roll=0.1, pitch=0.2, yaw=0.3, usec=0, cov=UNKNOWN):
    return rx(M.MAVLink_vision_position_estimate_message(usec, x, y, z, roll, pitch, yaw, cov, 0))


def odometry(frame=M.MAV_FRAME_LOCAL_NED, child=M.MAV_FRAME_BODY_FRD, q=(1.0, 0.0, 0.0, 0.0), v=(1.0, 2.0, 3.0),
             rates=(0.1, 0.2, 0.3), usec=0, pose_cov=UNKNOWN, vel_cov=UNKNOWN):
    return rx(M.MAVLink_odometry_message(usec, frame, child, 1.0, 2.0, -3.0, list(q), *v, *rates, pose_cov, vel_cov, 0,
                                         M.MAV_ESTIMATOR_TYPE_VIO, 100))


def gps_input(fix=3, lat=43.5, lon=1.48, alt=146.0, hdop=0.8, vdop=1.2, h_acc=0.5, v_acc=0.9, ignore=0, usec=0):
    return rx(M.MAVLink_gps_input_message(usec, 0, ignore, 0, 0, fix, round(lat * 1e7), round(lon * 1e7), alt, hdop, vdop,
                                          0.0, 0.0, 0.0, 0.0, h_acc, v_acc, 12))


def inputs(**kwargs) -> ExternalInputs:
    return ExternalInputs(1, **kwargs)


def close(a, b, tol=1e-5) -> bool:
    return all(abs(x - y) < tol for x, y in zip(a, b, strict=True))


def test_vision_position_ned_frd_to_enu_flu():
    sample = inputs().handle(vpe(), NOW)
    assert isinstance(sample, PoseSample) and sample.source == "VISION_POSITION_ESTIMATE"
    assert close(sample.position, (2.0, 1.0, 3.0))  # 1 m north, 2 m east, 3 m up
    roll, pitch, yaw = quat.to_euler(sample.orientation)
    assert close((roll, pitch, yaw), (0.1, -0.2, math.pi / 2 - 0.3))  # FLU: pitch nose-up is negative, yaw from east
    assert sample.covariance == (0.0,) * 36  # NaN first element: unknown → the navigation's parameter
    assert sample.stamp == ROS  # usec 0: no stamp, the arrival time


def test_attitude_quaternions_frd_ned_to_flu_enu():
    """ATT_POS_MOCAP's quaternion and VISION_POSITION_ESTIMATE's Euler angles give the same attitude;
    a nose pointing east (NED yaw 90°) is ENU yaw 0, and the body's left (FLU y) points north."""
    q_ned = quat.from_euler(0.1, 0.2, 0.3)
    mocap = inputs().handle(rx(M.MAVLink_att_pos_mocap_message(0, list(q_ned), 1.0, 2.0, -3.0, UNKNOWN)), NOW)
    assert isinstance(mocap, PoseSample)
    vision = inputs().handle(vpe(), NOW)
    assert quat.angle_between(mocap.orientation, vision.orientation) < 1e-5
    east = inputs().handle(vpe(roll=0.0, pitch=0.0, yaw=math.pi / 2), NOW)
    assert close(quat.rotate(east.orientation, (1.0, 0.0, 0.0)), (1.0, 0.0, 0.0))
    assert close(quat.rotate(east.orientation, (0.0, 1.0, 0.0)), (0.0, 1.0, 0.0))
    bad = rx(M.MAVLink_att_pos_mocap_message(0, [0.5, 0.0, 0.0, 0.0], 1.0, 2.0, -3.0, UNKNOWN))
    ext = inputs()
    assert ext.handle(bad, NOW) is None and ext.rejected["quaternion"] == 1


def test_pose_covariance_ned_to_enu():
    c = np.diag([1.0, 4.0, 9.0, 0.01, 0.02, 0.03])
    c[0, 1] = c[1, 0] = 0.5  # north-east
    c[0, 2] = c[2, 0] = 0.2  # north-down
    full = np.array(pose_covariance_to_enu(upper(c), 0.0)).reshape(6, 6)
    assert close(np.diag(full), (4.0, 1.0, 9.0, 0.02, 0.01, 0.03))  # facing north: roll is about north = ENU y
    assert math.isclose(full[0, 1], 0.5, rel_tol=1e-6)  # east-north
    assert math.isclose(full[1, 2], -0.2, rel_tol=1e-6)  # north-up = −(north-down)
    assert np.allclose(full, full.T)
    east = np.array(pose_covariance_to_enu(upper(c), math.pi / 2)).reshape(6, 6)
    assert close(np.diag(east)[3:], (0.01, 0.02, 0.03))  # facing east: roll is about east = ENU x
    assert pose_covariance_to_enu(UNKNOWN, 0.0) == (0.0,) * 36
    assert np.allclose(upper_to_full(upper(c)), c)
    # through the message (float32 on the wire): same mapping
    sample = inputs().handle(vpe(yaw=0.0, cov=upper(c)), NOW)
    assert close(np.diag(np.array(sample.covariance).reshape(6, 6)), (4.0, 1.0, 9.0, 0.02, 0.01, 0.03))
    for bad, why in ((np.diag([1.0, 1.0, 0.0, 0.1, 0.1, 0.1]), "zero variance"),
                     (np.array([[1.0, 2.0] + [0.0] * 4, [2.0, 1.0] + [0.0] * 4] + [[0.0] * i + [1.0] + [0.0] * (5 - i)
                                                                                  for i in range(2, 6)]), "not PSD")):
        ext = inputs()
        assert ext.handle(vpe(cov=upper(bad)), NOW) is None, why
        assert ext.rejected["covariance"] == 1
    ext = inputs()
    assert ext.handle(vpe(cov=[1.0, math.nan] + [0.0] * 19), NOW) is None and ext.rejected["covariance"] == 1


def test_odometry_frames_velocity_and_twist_covariance():
    sample = inputs().handle(odometry(vel_cov=upper(np.diag([0.1, 0.2, 0.3, 0.01, 0.02, 0.03]))), NOW)
    assert isinstance(sample, OdometrySample)
    assert close(sample.pose.position, (2.0, 1.0, 3.0))
    assert close(sample.velocity, (1.0, -2.0, -3.0)) and close(sample.angular_velocity, (0.1, -0.2, -0.3))
    assert close(np.diag(np.array(sample.twist_covariance).reshape(6, 6)), (0.1, 0.2, 0.3, 0.01, 0.02, 0.03))
    # velocity in the local NED frame, vehicle facing east: 1 m/s north is 1 m/s to its left (FLU +y)
    q_east = quat.from_euler(0.0, 0.0, math.pi / 2)
    local = inputs().handle(odometry(child=M.MAV_FRAME_LOCAL_NED, q=q_east, v=(1.0, 0.0, 0.0)), NOW)
    assert close(local.velocity, (0.0, 1.0, 0.0))
    frd = inputs().handle(odometry(frame=M.MAV_FRAME_LOCAL_FRD), NOW)
    assert isinstance(frd, OdometrySample)  # accepted as PX4 does (yaw offset: the navigation's alignment)
    unknown = inputs().handle(odometry(v=(math.nan,) * 3, rates=(math.nan,) * 3), NOW)
    assert all(math.isnan(v) for v in unknown.velocity + unknown.angular_velocity)  # NaN = not sent
    ext = inputs()
    for frame, child in ((M.MAV_FRAME_LOCAL_ENU, M.MAV_FRAME_BODY_FRD), (M.MAV_FRAME_GLOBAL, M.MAV_FRAME_BODY_FRD),
                         (M.MAV_FRAME_LOCAL_NED, M.MAV_FRAME_BODY_NED)):
        assert ext.handle(odometry(frame=frame, child=child), NOW) is None
    assert ext.rejected["frame"] == 3
    assert ext.handle(odometry(v=(1.0, math.nan, 0.0)), NOW) is None and ext.rejected["invalid"] == 1


def test_gps_input_fix_covariance_and_ignore_flags():
    fix = inputs().handle(gps_input(), NOW)
    assert isinstance(fix, GnssSample) and fix.status == 0
    assert math.isclose(fix.latitude, 43.5, abs_tol=1e-7) and math.isclose(fix.longitude, 1.48, abs_tol=1e-7)
    assert math.isclose(fix.altitude, 146.0, rel_tol=1e-6) and fix.covariance_type == COV_DIAGONAL_KNOWN
    assert close((fix.covariance[0], fix.covariance[4], fix.covariance[8]), (0.25, 0.25, 0.81))
    dop = inputs().handle(gps_input(ignore=M.GPS_INPUT_IGNORE_FLAG_HORIZONTAL_ACCURACY
                                    | M.GPS_INPUT_IGNORE_FLAG_VERTICAL_ACCURACY | M.GPS_INPUT_IGNORE_FLAG_ALT), NOW)
    assert dop.covariance_type == COV_APPROXIMATED and close((dop.covariance[0], dop.covariance[8]), (0.64, 1.44))
    assert math.isnan(dop.altitude)
    assert inputs().handle(gps_input(fix=6), NOW).status == 2  # RTK fixed: GBAS
    none = inputs().handle(gps_input(fix=1, lat=0.0, lon=0.0), NOW)
    assert none.status == NO_FIX and math.isnan(none.latitude)  # a lost fix is published (jamming evidence)
    ext = inputs()
    assert ext.handle(gps_input(lat=95.0), NOW) is None and ext.handle(gps_input(h_acc=-1.0), NOW) is None
    assert ext.handle(gps_input(alt=math.inf), NOW) is None
    assert ext.rejected["range"] == 3


def test_sample_time_bases():
    clock = SampleClock(max_age_s=0.5)
    vio = (1, 197)
    # UNIX epoch µs: exact age
    assert math.isclose(clock.age(vio, round((WALL - 0.03) * 1e6), 5.0, WALL, ROS), 0.03, abs_tol=1e-6)
    assert clock.describe() == {"clock_1_197": "epoch"}
    with pytest.raises(Rejected, match="ahead") as future:
        clock.age(vio, round((WALL + 1.0) * 1e6), 5.0, WALL, ROS)
    assert future.value.reason == "future"
    with pytest.raises(Rejected) as stale:
        clock.age(vio, round((WALL - 10.0) * 1e6), 5.0, WALL, ROS)
    assert stale.value.reason == "stale"
    # time since the sender's boot: the fastest sample of the window defines age 0
    other = (1, 198)
    latencies = [0.012, 0.004, 0.020, 0.009]
    boot = 1000.0  # our monotonic clock when the sender booted
    ages = [clock.age(other, round((k * 0.1) * 1e6), boot + k * 0.1 + lat, WALL, ROS) for k, lat in enumerate(latencies)]
    assert ages[0] == 0.0 and ages[1] == 0.0  # first sample; faster one: new minimum
    assert math.isclose(ages[2], 0.016, abs_tol=1e-6) and math.isclose(ages[3], 0.005, abs_tol=1e-6)  # latency − 4 ms
    # TIMESYNC: the offset from the round trip makes the age exact
    clock.timesync(other, -boot)  # sender clock − our monotonic clock
    assert math.isclose(clock.age(other, round(3.0e6), boot + 3.0 + 0.030, WALL, ROS), 0.030, abs_tol=1e-6)
    # the sender restarted (its clock jumps back): a new estimate, counted
    assert clock.age(other, round(0.2e6), boot + 100.0, WALL, ROS) == 0.0 and clock.resets == 1
    # a simulated graph: the ROS clock is sim time, a stamp near it is that clock
    sim = SampleClock(max_age_s=0.5)
    assert math.isclose(sim.age((1, 197), round(41.97e6), 7.0, WALL, 42.0), 0.03, abs_tol=1e-6)
    assert "clock_1_197" in sim.describe() and sim.describe()["clock_1_197"] == "ros"


def test_timesync_round_trip_and_requests():
    ext = inputs()
    assert ext.timesync_request(10.0) is None  # no boot-time sender yet
    reply = ext.on_timesync(rx(M.MAVLink_timesync_message(0, 123)), 10.0)
    assert reply.tc1 == int(10.0 * 1e9) and reply.ts1 == 123  # a companion's request answered with our clock
    ext.handle(vpe(usec=5_000_000), Clocks(20.0, WALL, ROS))  # boot-time stamps: requests start
    request = ext.timesync_request(20.5)
    assert request is not None and request.tc1 == 0
    # the companion answers 4 ms later with its clock (its boot was at our 15.0)
    assert ext.on_timesync(rx(M.MAVLink_timesync_message(int((20.502 - 15.0) * 1e9), request.ts1)), 20.504) is None
    sample = ext.handle(vpe(usec=round((21.0 - 15.0) * 1e6)), Clocks(21.025, WALL, ROS))
    assert math.isclose(ROS - sample.stamp, 0.025, abs_tol=1e-4)


def test_flood_rate_limited_sources_refused_warnings_once():
    ext = inputs(max_rate_hz=250.0)
    for k in range(1000):  # 1 kHz for 1 s
        ext.handle(vpe(), Clocks(100.0 + k * 1e-3, WALL, ROS))
    assert 250 <= ext.accepted["VISION_POSITION_ESTIMATE"] <= 250 + RATE_BURST + 1
    assert ext.rejected["rate"] == 1000 - ext.accepted["VISION_POSITION_ESTIMATE"]
    assert ext.handle(vpe(), Clocks(200.0, WALL, ROS)) is not None  # the source is not banned
    assert ext.handle(vpe(x=math.nan), Clocks(201.0, WALL, ROS)) is None and ext.rejected["invalid"] == 1
    assert ext.handle(vpe(x=1e6), Clocks(202.0, WALL, ROS)) is None and ext.rejected["range"] == 1
    assert ext.handle(rx(vpe_msg := M.MAVLink_vision_position_estimate_message(0, 1, 2, 3, 0, 0, 0, UNKNOWN, 0),
                         STRANGER), NOW) is None
    assert ext.rejected["source"] == 1
    ext.note_gcs(7)  # a system that sent a GCS HEARTBEAT: taken
    assert ext.handle(rx(vpe_msg, STRANGER), NOW) is not None  # its own rate bucket
    own = M.MAVLink(None, 1, 1)  # our own autopilot's id: a loop or an impostor
    assert ext.handle(rx(vpe_msg, own), NOW) is None and ext.rejected["source"] == 2
    lines = ext.take_warnings(300.0)
    assert sorted(line.split("(")[1].split(",")[0] for line in lines) == ["invalid", "range", "rate", "source"]
    assert ext.take_warnings(301.0) == []  # nothing new
    ext.handle(vpe(x=math.nan), Clocks(302.0, WALL, ROS))
    assert ext.take_warnings(303.0) == []  # new drops, but the reason was warned < 10 s ago
    assert len(ext.take_warnings(311.0)) == 1
    stats = ext.stats()
    assert stats["rejected_rate"] == str(ext.rejected["rate"]) and stats["accepted_VISION_POSITION_ESTIMATE"]


def test_estimator_status_flags_and_glitch():
    from c4d_interfaces.msg import GnssIntegrity, VehicleState

    assert (es.VALID_POSITION_XY, es.VALID_POSITION_Z, es.VALID_VELOCITY_XY, es.VALID_VELOCITY_Z, es.VALID_ATTITUDE,
            es.VALID_GLOBAL, es.VALID_TERRAIN_DISTANCE, es.SOURCE_NONE, es.STATE_SPOOFED) == (
        VehicleState.VALID_POSITION_XY, VehicleState.VALID_POSITION_Z, VehicleState.VALID_VELOCITY_XY,
        VehicleState.VALID_VELOCITY_Z, VehicleState.VALID_ATTITUDE, VehicleState.VALID_GLOBAL,
        VehicleState.VALID_TERRAIN_DISTANCE, VehicleState.SOURCE_NONE, GnssIntegrity.STATE_SPOOFED)
    view = es.NavigationView()
    assert es.estimator_status(view, 1) is None  # nothing heard: nothing claimed
    view.state_heard, view.valid, view.sigma_h, view.sigma_v = True, 1 | 2 | 4 | 8 | 32 | 512, 0.4, 0.9
    msg = es.estimator_status(view, 5)
    want = (M.ESTIMATOR_ATTITUDE | M.ESTIMATOR_VELOCITY_HORIZ | M.ESTIMATOR_VELOCITY_VERT | M.ESTIMATOR_POS_HORIZ_REL
            | M.ESTIMATOR_POS_HORIZ_ABS | M.ESTIMATOR_POS_VERT_ABS | M.ESTIMATOR_PRED_POS_HORIZ_REL
            | M.ESTIMATOR_PRED_POS_HORIZ_ABS)
    assert msg.flags == want and math.isclose(msg.pos_horiz_accuracy, 0.4) and msg.pos_horiz_ratio == 0.0
    view.status_heard, view.horizontal_source, view.gnss_state, view.gnss_score = True, 2, 3, 1.7
    msg = rx(es.estimator_status(view, 5))  # through the wire
    assert msg.flags & M.ESTIMATOR_GPS_GLITCH and math.isclose(msg.pos_horiz_ratio, 1.7, rel_tol=1e-6)
    view.horizontal_source, view.gnss_state = es.SOURCE_NONE, 1
    msg = es.estimator_status(view, 5)
    assert msg.flags & M.ESTIMATOR_CONST_POS_MODE and not msg.flags & M.ESTIMATOR_GPS_GLITCH
