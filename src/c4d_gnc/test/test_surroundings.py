"""Surroundings (ROS-free): clustering, circle fit, tracking with velocity, wind from the dynamics.

The scans are ray cast here against exact circles and wall segments (with seeded range noise), so
every figure is compared with a known truth.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scan_cast import ANGLE_MIN, BEAMS, INC, RANGE_MAX, RANGE_MIN, cast

from c4d_common import quat
from c4d_common.airframe import GRAVITY, default_airframe_path, load_airframe
from c4d_gnc.surroundings import (
    ClusterConfig,
    NavSample,
    Tracker,
    TrackerConfig,
    WindConfig,
    WindEstimator,
    detections,
    fit_circle,
    scan_points,
)

CFG = ClusterConfig()


def detect_at(ranges, x=0.0, y=0.0, yaw=0.0, cfg=CFG):
    return detections(ranges, ANGLE_MIN, INC, RANGE_MIN, RANGE_MAX, x, y, yaw, cfg)


def nearest(found, x, y):
    return min(found, key=lambda d: math.hypot(d.x - x, d.y - y))


def test_points_are_in_map_with_the_pose():
    ranges = np.full(BEAMS, np.inf, dtype=np.float32)
    ranges[BEAMS // 2] = 5.0  # angle 0: straight ahead
    ranges[3 * BEAMS // 4] = 2.0  # angle +90°: to the left
    pts = scan_points(ranges, ANGLE_MIN, INC, RANGE_MIN, RANGE_MAX, 10.0, -3.0, math.pi / 2)
    np.testing.assert_allclose(pts, [[10.0, 2.0], [8.0, -3.0]], atol=1e-9)


def test_two_cylinders_and_a_wall_from_a_rotated_pose():
    """Two posts and a wall, scanned with 2 cm noise from a yawed pose: each post is one
    detection at its centre with its radius within 10 % (the fit, not the arc's centroid), the
    wall a chain of pieces that covers its length and lies on it."""
    posts = [(6.0, 2.0, 0.5), (-3.0, 5.0, 0.3)]
    wall = ((-8.0, -6.0), (8.0, -6.0))
    x, y, yaw = 1.0, 0.5, 0.7
    found = detect_at(cast(x, y, yaw, posts, [wall], noise=0.02, seed=3), x, y, yaw)
    for cx, cy, r in posts:
        d = nearest(found, cx, cy)
        assert math.hypot(d.x - cx, d.y - cy) < 0.1, (d, cx, cy)
        assert abs(d.radius - r) <= 0.1 * r, (d.radius, r)
    pieces = [d for d in found if abs(d.y + 6.0) < 1.0]
    assert len(found) == 2 + len(pieces)
    assert 8 <= len(pieces) <= 17  # 16 m cut into 1 m cells once (the wall lies on a grid line: not twice)
    xs = sorted(d.x for d in pieces)
    assert xs[0] < -4.0 and xs[-1] > 4.0
    assert all(abs(d.y + 6.0) <= 0.1 and d.radius <= CFG.cell_m for d in pieces)


def test_circle_fit_beats_the_arc_centroid():
    """The visible arc's centroid is ~r·π/4 short of the centre; the fit gets centre and radius."""
    r, cx = 1.0, 5.0
    a = np.linspace(math.pi / 2, 3 * math.pi / 2, 40)  # the half facing the origin
    pts = np.column_stack((cx + r * np.cos(a), r * np.sin(a)))
    pts += np.random.default_rng(1).normal(0.0, 0.02, pts.shape)
    fx, fy, fr, rms = fit_circle(pts)
    assert abs(fx - cx) < 0.05 and abs(fy) < 0.05 and abs(fr - r) < 0.05 and rms < 0.03
    assert cx - pts[:, 0].mean() > 0.5  # what a centroid would have said


@pytest.mark.parametrize("distance", [3.0, 10.0, 20.0])
def test_small_post_radius_within_10_percent_at_range(distance):
    found = detect_at(cast(0.0, 0.0, 0.0, [(distance, 0.0, 0.4)], noise=0.01, seed=int(distance)))
    assert len(found) == 1
    d = found[0]
    assert abs(d.radius - 0.4) <= 0.04 and abs(d.x - distance) < 0.08, d


def test_noise_points_are_not_obstacles():
    ranges = np.full(BEAMS, np.inf, dtype=np.float32)
    ranges[[10, 200, 201, 500]] = [4.0, 7.0, 12.0, 3.0]  # isolated returns, a pair far apart
    assert detect_at(ranges) == []


def test_bad_inputs():
    """NaN / ±inf / negative / below-minimum / at-maximum ranges are no returns; an empty scan
    gives no obstacles; a post keeps its detection when NaNs are sprinkled over the rest."""
    assert detect_at(np.array([], dtype=np.float32)) == []
    junk = np.full(BEAMS, np.nan, dtype=np.float32)
    junk[::3] = -np.inf
    junk[1::7] = -1.0
    junk[2::11] = 0.05
    junk[5::13] = RANGE_MAX
    assert detect_at(junk) == []
    ranges = cast(0.0, 0.0, 0.0, [(5.0, 0.0, 0.5)])
    rng = np.random.default_rng(2)
    far = np.flatnonzero(~np.isfinite(ranges))
    ranges[rng.choice(far, 200, replace=False)] = np.nan
    found = detect_at(ranges)
    assert len(found) == 1 and abs(found[0].x - 5.0) < 0.05
    tracker = Tracker()
    assert tracker.update(0.0, []) == [] and tracker.update(0.1, []) == []


def test_wrap_around_joins_a_post_behind():
    """A post straight behind (beams at −180° and +180° see it) is one detection, not two."""
    found = detect_at(cast(0.0, 0.0, 0.0, [(-6.0, 0.0, 0.6)], noise=0.01, seed=4))
    assert len(found) == 1 and abs(found[0].x + 6.0) < 0.1 and abs(found[0].radius - 0.6) < 0.06


def run_tracker(seconds: float, rate_hz: float, world, vehicle=lambda t: (0.0, 0.0, 0.0), seed: int = 5):
    """Scan a moving world (t → circles) from a moving vehicle; return the tracker and the id
    history of the track nearest each circle."""
    tracker = Tracker(TrackerConfig())
    ids: list[list[int]] = []
    for k in range(int(seconds * rate_hz)):
        t = k / rate_hz
        circles = world(t)
        x, y, yaw = vehicle(t)
        reported = tracker.update(t, detect_at(cast(x, y, yaw, circles, noise=0.02, seed=seed + k), x, y, yaw))
        if reported and len(reported) >= len(circles):
            ids.append([min(reported, key=lambda tr: math.hypot(tr.x - c[0], tr.y - c[1])).id for c in circles])
    return tracker, ids


def test_moving_cylinder_velocity_and_stable_ids():
    """A 0.5 m post crossing at 2 m/s (diagonal) past a static one, scanned at 20 Hz while the
    vehicle itself moves and turns: after 2 s the mover's velocity is within 0.3 m/s, the static
    post's speed below 0.3 m/s, positions within 0.15 m, and neither track ever changed id."""
    v = (1.6, -1.2)

    def world(t):
        return [(2.0 + v[0] * t, 8.0 + v[1] * t, 0.5), (-4.0, -3.0, 0.4)]

    tracker, ids = run_tracker(3.0, 20.0, world, vehicle=lambda t: (0.5 * t, 0.2 * t, 0.3 * t))
    assert len(ids) >= 55
    assert all(row == ids[0] for row in ids) and ids[0][0] != ids[0][1]
    tracks = {tr.id: tr for tr in tracker.confirmed()}
    mover, post = tracks[ids[0][0]], tracks[ids[0][1]]
    truth = world(tracker.tracks[0].t)[0]
    assert math.hypot(mover.x - truth[0], mover.y - truth[1]) < 0.15
    assert math.hypot(mover.vx - v[0], mover.vy - v[1]) < 0.3, (mover.vx, mover.vy)
    assert math.hypot(post.vx, post.vy) < 0.3 and math.hypot(post.x + 4.0, post.y + 3.0) < 0.15
    assert mover.confidence > 0.9 and abs(mover.radius - 0.5) < 0.05
    assert len(tracker.tracks) == 2  # no spare tracks


def test_track_dropped_after_misses_and_new_id_after():
    cfg = TrackerConfig(max_misses=3)
    tracker = Tracker(cfg)
    seen = cast(0.0, 0.0, 0.0, [(5.0, 0.0, 0.5)])
    empty = cast(0.0, 0.0, 0.0, [])
    t = 0.0
    for _ in range(5):
        t += 0.05
        reported = tracker.update(t, detect_at(seen))
    first = reported[0].id
    confidences = []
    for _ in range(cfg.max_misses):
        t += 0.05
        confidences.append(tracker.update(t, detect_at(empty))[0].confidence)  # coasting, still reported
    assert confidences == sorted(confidences, reverse=True) and confidences[-1] < 0.5
    t += 0.05
    assert tracker.update(t, detect_at(empty)) == []  # dropped after the 4th miss
    for _ in range(2):
        t += 0.05
        reported = tracker.update(t, detect_at(seen))
    assert len(reported) == 1 and reported[0].id != first


AIRFRAME = load_airframe(default_airframe_path("quad_x"))


def steady_state(wind, velocity, accel=(0.0, 0.0, 0.0), yaw=0.4):
    """The attitude at which the plant's force balance holds (thrust along body z):
    T·z_b = m·(a + g ẑ) + C·(v − w)."""
    m, c = AIRFRAME.mass, AIRFRAME.drag_linear
    f = [m * accel[k] + c[k] * (velocity[k] - wind[k]) for k in range(3)]
    f[2] += m * GRAVITY
    n = math.sqrt(sum(v * v for v in f))
    zb = tuple(v / n for v in f)
    xc = (math.cos(yaw), math.sin(yaw), 0.0)
    yb = np.cross(zb, xc)
    yb /= np.linalg.norm(yb)
    xb = np.cross(yb, zb)
    return quat.from_axes(tuple(xb), tuple(yb), zb)


def test_wind_from_a_steady_hover_and_a_steady_cruise():
    """5 m/s wind: the attitude of a hover in it, then of a 4 m/s cruise across it, with 0.1 m/s²
    accelerometer-like noise on the acceleration (0.07 m/s 1-σ after the low-pass); the estimate converges within 0.3 m/s and is
    flagged valid only after converge_s airborne."""
    wind = (3.0, -4.0, 0.0)
    rng = np.random.default_rng(7)
    est = WindEstimator.for_airframe(AIRFRAME, WindConfig(time_constant_s=2.0, converge_s=5.0))
    for velocity in ((0.0, 0.0, 0.0), (4.0, 1.0, 0.0)):
        q = steady_state(wind, velocity)
        for k in range(200):  # 10 s at 20 Hz
            t = (est.last_t or 0.0) + 0.05
            accel = tuple(rng.normal(0.0, 0.1, 3))
            est.update(NavSample(t, 10.0, velocity, accel, q, True, tilt_std=0.002))
            if velocity == (0.0, 0.0, 0.0) and k == 80:
                assert not est.valid  # 4 s airborne
        assert est.valid
        assert math.hypot(est.wind[0] - wind[0], est.wind[1] - wind[1]) < 0.3, est.wind
        assert 0.0 < est.std < 0.5


def test_wind_with_acceleration_in_the_balance():
    """Accelerating at 2 m/s² in 2 m/s wind: the balance includes m·a, so the estimate is right
    although the tilt is mostly the acceleration's."""
    wind = (-2.0, 0.0, 0.0)
    est = WindEstimator.for_airframe(AIRFRAME)
    for k in range(100):
        t, v = k * 0.05, (1.0 + 0.1 * k, 0.0, 0.0)
        est.update(NavSample(t, 5.0, v, (2.0, 0.0, 0.0), steady_state(wind, v, (2.0, 0.0, 0.0)), True))
    assert math.hypot(est.wind[0] - wind[0], est.wind[1]) < 0.01


def test_wind_not_valid_on_the_ground_or_with_bad_samples():
    est = WindEstimator.for_airframe(AIRFRAME, WindConfig(converge_s=1.0))
    level = quat.from_euler(0.0, 0.0, 0.0)
    for k in range(100):
        est.update(NavSample(k * 0.05, 0.0, (0, 0, 0), (0, 0, 0), level, True))  # on the ground
    assert not est.valid and est.std == math.inf
    for k in range(100, 200):
        est.update(NavSample(k * 0.05, 5.0, (0, 0, 0), (0, 0, 0), level, True))
    assert est.valid
    est.update(NavSample(10.05, 5.0, (math.nan, 0, 0), (0, 0, 0), level, True))
    assert not est.valid  # a NaN restarts the convergence, it never enters the estimate
    assert all(math.isfinite(v) for v in est.wind)
    est.update(NavSample(10.1, 5.0, (0, 0, 0), (0, 0, 0), level, False))
    assert not est.valid
    with pytest.raises(ValueError, match="drag"):
        WindEstimator(1.5, (0.0, 0.25, 0.35))
