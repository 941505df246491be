"""NavigationFilter: the navigation node's sample handling without ROS."""

import math

import numpy as np

from c4d_gnc.ekf import NavigationEkf
from c4d_gnc.navigation_filter import HOME_GYRO_BIAS_SIGMA, HOME_SETTLE_MAX_S, ZUPT_EVERY, NavigationFilter

G = (0.0, 0.0, 9.80665)
STILL = (0.0, 0.0, 0.0)


def aligned_filter() -> NavigationFilter:
    """A filter after its static alignment (the EKF averages the first accelerometer samples); last sample at t = 0."""
    f = NavigationFilter(NavigationEkf())
    k = 0
    while not f.ekf.aligned:
        assert not f.imu(-1.0 + k * 0.002, STILL, G)  # nothing to publish before the estimate exists
        k += 1
    f.imu_t = 0.0
    return f


def test_aligns_first_then_predicts_but_never_across_a_gap():
    f = aligned_filter()
    assert f.imu(0.002, STILL, G) and f.imu_count == 1
    assert not f.imu(0.5, STILL, G)  # gap: no integration over an unknown interval
    assert f.imu(0.502, STILL, G) and f.imu_count == 2


def test_zero_velocity_updates_only_on_the_ground():
    calls = []
    f = aligned_filter()
    f.ekf.update_zero_velocity = lambda: calls.append(1) or True
    for k in range(1, ZUPT_EVERY + 1):
        f.imu(k * 0.002, STILL, G)
    assert calls == []
    f.on_ground = True
    for k in range(ZUPT_EVERY + 1, 2 * ZUPT_EVERY + 1):
        f.imu(k * 0.002, STILL, G)
    assert calls == [1]


def test_body_rate_is_bias_corrected_and_angular_acceleration_low_passed():
    f = aligned_filter()
    f.imu(0.002, (0.1, 0.0, 0.0), G)
    assert np.allclose(f.omega, np.array([0.1, 0.0, 0.0]) - f.ekf.bg)
    assert math.isclose(f.alpha[0], 0.2 * f.omega[0] / 0.002, rel_tol=1e-9)


def test_terrain_distance_needs_a_fresh_finite_reading():
    f = NavigationFilter(NavigationEkf())
    assert math.isnan(f.terrain_distance(1.0))
    f.range_down(-math.inf, 1.0)  # closer than the minimum range: on the ground
    assert f.terrain_distance(1.1) == 0.0
    assert math.isnan(f.terrain_distance(1.6))
    f.range_down(math.inf, 2.0)  # out of range
    assert math.isnan(f.terrain_distance(2.0))


def _stand_still(f: NavigationFilter, t0: float, seconds: float) -> float:
    """IMU at 500 Hz and GNSS at 10 Hz of a vehicle standing still; returns the last sample time."""
    t = t0
    for k in range(1, int(seconds * 500) + 1):
        t = t0 + k * 0.002
        f.imu(t, STILL, G)
        if k % 50 == 0:
            f.gnss(43.5629, 1.4815, 146.0, 0.25, 0.5, t)
    return t


def test_home_waits_for_the_vehicle_status_and_the_gyro_bias():
    """Until the vehicle's status is heard no zero-velocity update runs, so the gyro bias cannot converge: home
    (hence a valid position, hence arming) waits — CI's false SPOOFED at take-off had home set at once because
    the core's status reached navigation late. Heard disarmed: home once the bias σ converged; at most
    HOME_SETTLE_MAX_S after alignment whatever happens."""
    f = aligned_filter()
    t = _stand_still(f, 0.0, 5.0)
    assert not f.status_known and f.ekf.origin is None
    f.on_ground = True
    assert f.status_known
    while f.ekf.origin is None and t < 9.0:
        t = _stand_still(f, t, 0.1)
    assert f.ekf.origin is not None, "home never set on the ground"
    assert math.sqrt(max(f.ekf.P[9, 9], f.ekf.P[10, 10])) <= HOME_GYRO_BIAS_SIGMA
    never = aligned_filter()
    t = _stand_still(never, 0.0, HOME_SETTLE_MAX_S - 0.5)
    assert never.ekf.origin is None
    _stand_still(never, t, 3.0)  # the cap, then 20 fixes
    assert never.ekf.origin is not None and not never.status_known
