"""The external-pose emulator without DDS: rate (executive divider), latency (release vs stamp), seeded noise
statistics, dropouts, the source frame (a known offset round-trips), run-time settings, and the MAVLink
VISION_POSITION_ESTIMATE bytes decoded by pymavlink (NED/FRD conversion, covariance, ids)."""

from __future__ import annotations

import math
import socket
import statistics

import pytest
from pymavlink.dialects.v20 import common as mavlink

from c4d_common import quat
from c4d_sim.external_pose import (
    ExternalPoseEmulator,
    ExternalPoseSettings,
    mavlink_vision_position,
    parse_udpout,
    source_to_world,
    world_to_source,
)
from c4d_sim.mavlink_out import VisionSender
from c4d_sim.plant import PlantState
from c4d_sim.sim_config import default_sim_config, load_sim_config
from c4d_sim.simulation import task_specs


def run(emulator: ExternalPoseEmulator, seconds: float, physics_hz: int = 1000, divider: int = 10,
        state: PlantState | None = None):
    """Step a moving truth (1 m/s east, 0.5 m/s north, 2 m up) at the physics rate, sampling every `divider`
    steps as the executive does; returns [(release time, sample)]."""
    state = state or PlantState()
    out = []
    for k in range(round(seconds * physics_hz)):
        t = k / physics_hz
        state.t, state.position = t, (1.0 * t, 0.5 * t, 2.0)
        state.velocity = (1.0, 0.5, 0.0)
        if k % divider == 0:
            emulator.sample(state)
            out += [(t, s) for s in emulator.due(t)]
    return out


def test_rate_is_an_executive_task_dividing_the_physics_rate():
    config = load_sim_config(default_sim_config())
    specs = {s.name: s for s in task_specs(config, {"external_pose": 100.0})}
    assert specs["external_pose"].divider == 10 and specs["external_pose"].budget_us == 400
    emulator = ExternalPoseEmulator(ExternalPoseSettings(enabled=True, latency_s=0.0))
    stamps = [s.stamp for _, s in run(emulator, 2.0)]
    assert len(stamps) == 200 and all(b - a == pytest.approx(0.01) for a, b in zip(stamps, stamps[1:], strict=False))


def test_released_latency_after_the_sample_time_and_stamped_with_it():
    emulator = ExternalPoseEmulator(ExternalPoseSettings(enabled=True, latency_s=0.03, noise_m=0.0))
    out = run(emulator, 1.0)
    assert [round(released - s.stamp, 9) for released, s in out] == [0.03] * len(out)
    assert len(out) == 97 and len(emulator.pending) == 3  # the last three are in flight
    released, s = out[10]
    assert s.position == pytest.approx((s.stamp, 0.5 * s.stamp, 2.0))  # the pose at its stamp, not at release


def test_noise_statistics_and_reported_covariance_match_the_settings():
    emulator = ExternalPoseEmulator(ExternalPoseSettings(enabled=True, latency_s=0.0, noise_m=0.05, yaw_noise_deg=2.0),
                                    seed=7)
    out = [s for _, s in run(emulator, 40.0)]
    ex = [s.position[0] - s.stamp for s in out]
    ey = [s.position[1] - 0.5 * s.stamp for s in out]
    ez = [s.position[2] - 2.0 for s in out]
    yaw = [math.degrees(quat.yaw_of(s.orientation)) for s in out]
    assert len(out) == 4000
    for e in (ex, ey, ez):  # 4000 samples: the σ estimate is within ~2.5 % (1σ 1.1 %)
        assert abs(statistics.fmean(e)) < 0.004 and statistics.stdev(e) == pytest.approx(0.05, rel=0.05)
    assert statistics.stdev(yaw) == pytest.approx(2.0, rel=0.05)
    assert out[0].sigma_position == 0.05 and out[0].sigma_orientation == pytest.approx(math.radians(2.0))
    again = [s for _, s in run(ExternalPoseEmulator(emulator.settings, seed=7), 1.0)]
    assert [s.position for s in again] == [s.position for s in out[:len(again)]]  # seeded: the same stream


def test_a_noise_free_source_still_reports_a_positive_covariance():
    emulator = ExternalPoseEmulator(ExternalPoseSettings(enabled=True, latency_s=0.0, noise_m=0.0, yaw_noise_deg=0.0,
                                                         velocity_noise_m_s=0.0))
    s = run(emulator, 0.02)[0][1]
    assert s.position == (0.0, 0.0, 2.0) and 0 < s.sigma_position <= 1e-3 and 0 < s.sigma_orientation < 0.002


def test_dropouts_follow_the_probability_and_are_counted():
    emulator = ExternalPoseEmulator(ExternalPoseSettings(enabled=True, latency_s=0.0, dropout_probability=0.3), seed=3)
    out = run(emulator, 20.0)
    assert emulator.sampled == 2000 and emulator.dropped + len(out) == 2000
    assert emulator.dropped / 2000 == pytest.approx(0.3, abs=0.03)


def test_disabling_loses_the_source_at_once_and_enabling_resumes():
    emulator = ExternalPoseEmulator(ExternalPoseSettings(enabled=True, latency_s=0.03))
    state = PlantState()
    for k in range(5):
        state.t = 0.01 * k
        emulator.sample(state)
    assert emulator.set("enabled", False) is None and not emulator.pending
    state.t = 1.0
    emulator.sample(state)
    assert emulator.due(2.0) == [] and emulator.sampled == 5
    emulator.set("enabled", True)
    emulator.sample(state)
    assert [s.stamp for s in emulator.due(1.03)] == [1.0]


def test_frame_offset_and_yaw_round_trip_and_apply_to_the_pose():
    yaw, offset = math.radians(30.0), (10.0, -5.0, 1.0)
    for p in ((0.0, 0.0, 0.0), (3.0, 4.0, 5.0), (-7.5, 2.0, -1.0)):
        assert source_to_world(world_to_source(p, yaw, offset), yaw, offset) == pytest.approx(p)
    assert world_to_source((10.0, -5.0, 1.0), yaw, offset) == pytest.approx((0.0, 0.0, 0.0))  # its origin
    assert world_to_source((0.0, 1.0, 0.0), math.pi / 2, (0.0, 0.0, 0.0)) == pytest.approx((1.0, 0.0, 0.0))  # north = its x
    emulator = ExternalPoseEmulator(ExternalPoseSettings(enabled=True, latency_s=0.0, noise_m=0.0, yaw_noise_deg=0.0,
                                                         velocity_noise_m_s=0.0))
    assert emulator.set("frame_yaw_deg", 90.0) is None and emulator.set("frame_offset_m", [1.0, 2.0, 3.0]) is None
    assert emulator.reset_counter == 2 and emulator.set("frame_offset_m", [1.0]) is not None
    assert emulator.set("rate_hz", 50.0) == "'rate_hz' cannot change at run time"
    state = PlantState(t=0.0, position=(4.0, 2.0, 5.0), velocity=(0.0, 2.0, 0.0),
                       orientation=quat.from_euler(0.0, 0.0, math.pi / 2))  # heading north, flying forward at 2 m/s
    emulator.sample(state)
    s = emulator.due(0.0)[0]
    assert s.position == pytest.approx((0.0, -3.0, 2.0))  # 3 m east of the source origin = its −y
    assert quat.yaw_of(s.orientation) == pytest.approx(0.0, abs=1e-12)  # heading along the source's x
    assert s.velocity_body == pytest.approx((2.0, 0.0, 0.0)) and s.reset_counter == 2
    assert source_to_world(s.position, math.pi / 2, (1.0, 2.0, 3.0)) == pytest.approx(state.position)


def test_vision_position_estimate_bytes_decode_to_ned_frd():
    """ENU/FLU in the source frame → NED/FRD, checked against the rotation composed independently:
    q_FRD→NED = q_ENU→NED ⊗ q_FLU→ENU ⊗ q_FRD→FLU."""
    emulator = ExternalPoseEmulator(ExternalPoseSettings(enabled=True, latency_s=0.0, noise_m=0.02, yaw_noise_deg=0.0))
    state = PlantState(t=12.5, position=(3.0, 4.0, 5.0), orientation=quat.from_euler(0.1, -0.2, 0.3))
    emulator.set("frame_yaw_deg", 0.0)  # one reset
    emulator.sample(state)
    sample = emulator.due(12.5)[0]
    fields = mavlink_vision_position(sample, epoch=1_700_000_000.0)
    sender = VisionSender("udpout:127.0.0.1:9", sysid=7)
    try:
        frame = sender.encode(fields)
    finally:
        sender.close()
    parser = mavlink.MAVLink(None)
    msg = parser.parse_char(frame)
    assert frame[0] == 0xFD and msg.get_type() == "VISION_POSITION_ESTIMATE"  # MAVLink 2 (reset_counter is an extension)
    assert (msg.get_srcSystem(), msg.get_srcComponent()) == (7, mavlink.MAV_COMP_ID_VISUAL_INERTIAL_ODOMETRY)
    assert msg.usec == 1_700_000_012_500_000
    e, n, u = sample.position
    assert (msg.x, msg.y, msg.z) == pytest.approx((n, e, -u), abs=1e-5)
    s2 = math.sqrt(0.5)
    q = quat.mul(quat.mul((0.0, s2, s2, 0.0), sample.orientation), (0.0, 1.0, 0.0, 0.0))
    roll, pitch, yaw = quat.to_euler(q)
    assert (msg.roll, msg.pitch, msg.yaw) == pytest.approx((roll, pitch, yaw), abs=1e-6)
    assert (msg.roll, msg.pitch, msg.yaw) == pytest.approx((0.1, 0.2, math.pi / 2 - 0.3), abs=1e-6)
    diagonal = [msg.covariance[i] for i in (0, 6, 11, 15, 18, 20)]
    assert diagonal == pytest.approx([0.02 ** 2] * 3 + [math.radians(0.1) ** 2] * 3, rel=1e-6)
    assert sum(msg.covariance) == pytest.approx(sum(diagonal)) and msg.reset_counter == 1


def test_vision_sender_delivers_datagrams_and_counts_a_missing_listener():
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(2.0)
    port = rx.getsockname()[1]
    emulator = ExternalPoseEmulator(ExternalPoseSettings(enabled=True, latency_s=0.0))
    emulator.sample(PlantState())
    sender = VisionSender(f"udpout:127.0.0.1:{port}", sysid=1)
    try:
        sender.send(mavlink_vision_position(emulator.due(0.0)[0], 0.0))
        msg = mavlink.MAVLink(None).parse_char(rx.recv(512))
        assert msg.get_type() == "VISION_POSITION_ESTIMATE" and sender.sent == 1 and sender.errors == 0
    finally:
        rx.close()
        sender.close()


@pytest.mark.parametrize("url", ["udpin:127.0.0.1:14550", "udpout:127.0.0.1", "udpout::14550", "udpout:h:99999", "x"])
def test_bad_mavlink_urls_are_refused_with_one_line(url):
    with pytest.raises(ValueError, match="expected udpout:HOST:PORT"):
        parse_udpout(url)
    assert parse_udpout("udpout:127.0.0.1:14550") == ("127.0.0.1", 14550)
