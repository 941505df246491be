"""The action servers' decisions without ROS: goal refusals, the motion profile, goal runs."""

from __future__ import annotations

import math

import pytest

from c4d_common.geodesy import GeoOrigin
from c4d_common.plan import Geofence
from c4d_common.vehicle import Landed, Mode, Nav
from c4d_offboard.action_logic import (
    OFFBOARD_AFTER_S,
    OFFBOARD_GIVE_UP_S,
    Brake,
    LandTracker,
    OffboardRun,
    PathPose,
    PathProfile,
    TakeoffTracker,
    VehicleView,
    goal_refusal,
    path_refusal,
)

HOME = GeoOrigin(43.5629, 1.4815, 146.0)
FLYING = VehicleView(Landed.IN_AIR, (0.0, 0.0, 5.0), HOME)


def square_fence(half: float) -> Geofence:
    corners = [(-half, -half), (half, -half), (half, half), (-half, half)]
    return Geofence(tuple(HOME.to_geodetic(e, n, 0.0)[:2] for e, n in corners), 0.0, 0.0)


def test_goto_refusals_name_the_reason():
    assert goal_refusal((10.0, 0.0, 5.0), FLYING, None) is None
    assert "not flying" in goal_refusal((10.0, 0.0, 5.0), VehicleView(Landed.ON_GROUND, (0, 0, 0), HOME), None)
    assert "finite" in goal_refusal((math.nan, 0.0, 5.0), FLYING, None)
    assert "no vehicle status" in goal_refusal((1.0, 0.0, 5.0), None, None)
    assert "home" in goal_refusal((1.0, 0.0, 5.0), VehicleView(Landed.IN_AIR, (0, 0, 5), None), None)
    assert "outside" in goal_refusal((10.0, 0.0, 150.0), FLYING, None)  # above the default 120 m ceiling
    assert "polygon" in goal_refusal((40.0, 0.0, 5.0), FLYING, square_fence(30.0))
    assert goal_refusal((20.0, 0.0, 5.0), FLYING, square_fence(30.0)) is None
    assert "exceeds" in goal_refusal((20.0, 0.0, 5.0), FLYING, Geofence((), 0.0, 15.0))


def test_path_refusals():
    ok = [PathPose("map", (5.0, 0.0, 5.0)), PathPose("", (5.0, 5.0, 5.0))]
    assert path_refusal("map", ok, FLYING, None) is None
    assert path_refusal("map", [], FLYING, None) == "the path is empty"
    assert "frame 'map'" in path_refusal("odom", ok, FLYING, None)
    assert "pose 1: frame" in path_refusal("map", [ok[0], PathPose("base_link", (1, 1, 5))], FLYING, None)
    assert "pose 0: position must be finite" == path_refusal("map", [PathPose("map", (math.inf, 0, 5))], FLYING, None)
    assert "not flying" in path_refusal("map", ok, VehicleView(Landed.ON_GROUND, (0, 0, 0), HOME), None)
    far = ok + [PathPose("map", (50.0, 0.0, 5.0))]
    assert path_refusal("map", far, FLYING, square_fence(30.0)).startswith("pose 2: ")


def test_profile_is_trapezoidal_and_ends_at_rest_on_the_target():
    p = PathProfile.build([(0.0, 0.0, 5.0), (20.0, 0.0, 5.0)], speed=4.0, accel=2.0, vertical_speed=1.5)
    assert p.length == 20.0 and p.peak_speed == 4.0
    assert p.duration == pytest.approx(2 * 2.0 + (20.0 - 8.0) / 4.0)  # 2 s ramps (4 m each), 3 s cruise
    assert p.at(0.0).velocity == (0.0, 0.0, 0.0)
    mid = p.at(p.duration / 2)
    assert mid.position == pytest.approx((10.0, 0.0, 5.0)) and mid.velocity == pytest.approx((4.0, 0.0, 0.0))
    end = p.at(p.duration + 1)
    assert end.done and end.position == (20.0, 0.0, 5.0) and end.velocity == (0.0, 0.0, 0.0)
    # never faster than cruise, never accelerating harder than the limit, monotonic along the path
    prev_s, prev_v = 0.0, 0.0
    for k in range(1, 600):
        s, v = p.arc(k * 0.02)
        assert s >= prev_s and v <= 4.0 + 1e-9 and abs(v - prev_v) <= 2.0 * 0.02 + 1e-9
        prev_s, prev_v = s, v


def test_short_leg_is_a_triangle_and_steep_leg_is_slowed():
    p = PathProfile.build([(0.0, 0.0, 5.0), (1.0, 0.0, 5.0)], speed=4.0, accel=1.0, vertical_speed=1.5)
    assert p.peak_speed == pytest.approx(1.0) and p.duration == pytest.approx(2.0)
    climb = PathProfile.build([(0.0, 0.0, 5.0), (0.0, 0.0, 15.0)], speed=4.0, accel=1.0, vertical_speed=1.5)
    assert climb.speed == pytest.approx(1.5)


def test_polyline_segments_and_passed_poses():
    p = PathProfile.build([(0, 0, 5), (10, 0, 5), (10, 10, 5)], speed=2.0, accel=1.0, vertical_speed=1.5)
    assert p.length == 20.0
    s_mid_second = p.at(p.duration - 3.0)
    assert s_mid_second.segment == 1 and s_mid_second.velocity[0] == 0.0 and s_mid_second.velocity[1] > 0
    assert p.passed(9.0) == 0 and p.passed(10.0) == 1 and p.passed(20.0) == 2


def run_goto(mode_after: float | None, refuse: tuple[str, bool] | None = None):
    p = PathProfile.build([(0.0, 0.0, 5.0), (4.0, 0.0, 5.0)], 2.0, 1.0, 1.5)
    run = OffboardRun(p, 0.3, start_time=0.0)
    requests, t = [], 0.0
    while t < 40:
        mode = Mode.OFFBOARD if mode_after is not None and t >= mode_after else Mode.AUTO
        sp = run.last.position if run.flying_since is not None else (0.0, 0.0, 5.0)
        step = run.step(t, mode, sp, 0.0)
        if step.request_offboard:
            requests.append(t)
            if refuse:
                out = run.refused(*refuse)
                if out:
                    return out, requests, t
        if step.outcome:
            return step.outcome, requests, t
        t = round(t + 0.02, 6)
    return None, requests, t


def test_run_streams_before_asking_for_offboard_then_flies_to_success():
    outcome, requests, t = run_goto(mode_after=1.2)
    assert outcome.success and outcome.message == "reached"
    assert requests and requests[0] >= OFFBOARD_AFTER_S  # never asked before 1.1 s of stream
    assert t >= 1.2 + 4.0  # the profile (4 m at 2 m/s, 1 m/s^2: 4 s) started only once OFFBOARD was in force


def test_run_retries_a_not_yet_and_gives_up():
    outcome, requests, t = run_goto(mode_after=None, refuse=("stream not live for 1 s yet", True))
    assert not outcome.success and "not entered" in outcome.message and "not live" in outcome.message
    assert len(requests) >= 5 and t > OFFBOARD_GIVE_UP_S
    outcome, requests, _ = run_goto(mode_after=None, refuse=("not armed", False))
    assert outcome == outcome.__class__(False, "OFFBOARD refused: not armed") and len(requests) == 1


def test_run_fails_when_someone_else_takes_the_vehicle_or_it_never_arrives():
    p = PathProfile.build([(0.0, 0.0, 5.0), (4.0, 0.0, 5.0)], 2.0, 1.0, 1.5)
    run = OffboardRun(p, 0.3, 0.0)
    run.step(0.0, Mode.OFFBOARD, (0, 0, 5), 0.0)
    out = run.step(1.0, Mode.AUTO, (1, 0, 5), 1.0).outcome
    assert out is not None and not out.success and "AUTO" in out.message
    run = OffboardRun(p, 0.3, 0.0)
    run.step(0.0, Mode.OFFBOARD, (0, 0, 5), 0.0)
    assert run.step(10.0, Mode.OFFBOARD, (4.0, 0, 5), 1.0).outcome is None  # at the end but still fast
    out = run.step(30.0, Mode.OFFBOARD, (2.0, 0, 5), 0.0).outcome
    assert out is not None and not out.success and "2.00 m away" in out.message
    assert run.distance_to_go((2.0, 0.0, 5.0)) == pytest.approx(2.0)


def test_takeoff_tracker():
    t = TakeoffTracker(5.0)
    assert t.update(True, Mode.AUTO, Nav.HOLD, 0.0) is None  # old status before the take-off shows up
    assert t.update(True, Mode.AUTO, Nav.TAKEOFF, 2.0) is None and t.distance_to_go(2.0) == 3.0
    assert t.update(True, Mode.AUTO, Nav.HOLD, 4.9) == t.update(True, Mode.AUTO, Nav.HOLD, 5.1)
    assert t.update(True, Mode.AUTO, Nav.HOLD, 4.9).success
    t = TakeoffTracker(0.0)
    assert math.isnan(t.distance_to_go(1.0))
    t.update(True, Mode.AUTO, Nav.TAKEOFF, 1.0)
    out = t.update(True, Mode.AUTO, Nav.LAND, 1.0)
    assert out is not None and not out.success and "LAND" in out.message


def test_land_tracker():
    t = LandTracker()
    assert t.update(True, Landed.IN_AIR, Mode.AUTO, Nav.HOLD) is None
    assert t.update(True, Landed.LANDING, Mode.AUTO, Nav.LAND) is None
    assert t.update(False, Landed.ON_GROUND, Mode.AUTO, Nav.NONE).success
    t = LandTracker()
    t.update(True, Landed.LANDING, Mode.AUTO, Nav.LAND)
    assert not t.update(True, Landed.IN_AIR, Mode.OFFBOARD, Nav.NONE).success


def test_brake_stops_along_the_velocity():
    b = Brake((0.0, 0.0, 5.0), (3.0, 4.0, 0.0), decel=2.5)
    assert b.duration == pytest.approx(2.0)
    assert b.at(0.0).velocity == pytest.approx((3.0, 4.0, 0.0)) and not b.at(0.0).done
    stop = b.at(5.0)
    assert stop.done and stop.velocity == pytest.approx((0.0, 0.0, 0.0))
    assert stop.position == pytest.approx((3.0, 4.0, 5.0))  # 5 m = v²/2a along (0.6, 0.8)
    assert Brake((1.0, 2.0, 3.0), (0.0, 0.0, 0.0), 2.0).at(0.5).position == (1.0, 2.0, 3.0)
