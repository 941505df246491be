"""External pose input: every bad-input class of issue 19 rejected with its own counted reason,
never fused, no exception; the rate limit; frame alignment maths."""

import math

import numpy as np
import pytest

from c4d_common import quat
from c4d_gnc.ekf import NavigationEkf
from c4d_gnc.external_pose import ExternalConfig, ExternalSample, ExternalValidator, FrameAlignment, Rejection
from c4d_gnc.navigation_filter import NavigationConfig, NavigationFilter
from c4d_gnc.source_selection import EXTERNAL, NONE
from c4d_gnc.state_history import P, StateHistory

G, STILL, FIELD = (0.0, 0.0, 9.80665), (0.0, 0.0, 0.0), (0.0, 2.2e-5, -4.2e-5)
IDENTITY = (1.0, 0.0, 0.0, 0.0)


def sample(t, position=(0.0, 0.0, 0.0), frame="odom", child="base_link", cov=None, q=IDENTITY):
    return ExternalSample(t=t, position=np.array(position, dtype=float), quaternion=q,
                          covariance=np.zeros((6, 6)) if cov is None else np.asarray(cov, dtype=float),
                          frame_id=frame, child_frame_id=child)


def running_filter(seconds=2.0):
    """External-only filter, standing still, fed good samples at 100 Hz for `seconds` (aligned, fusing)."""
    f = NavigationFilter(NavigationEkf(), NavigationConfig(horizontal_primary=EXTERNAL, horizontal_secondary=NONE,
                                                           external_alignment="configured"))
    f.on_ground = True
    for k in range(int(seconds / 0.002)):
        t = k * 0.002
        if k % 10 == 0:
            f.magnetometer(FIELD)
        f.imu(t, STILL, G)
        if k % 5 == 0 and k > 100:
            assert f.external(sample(t - 0.02)) is None
    return f


BAD = [
    ("nan position", lambda t: sample(t, (math.nan, 0.0, 0.0)), Rejection.INVALID),
    ("inf covariance", lambda t: sample(t, cov=np.full((6, 6), math.inf)), Rejection.INVALID),
    ("non-unit quaternion", lambda t: sample(t, q=(2.0, 0.0, 0.0, 0.0)), Rejection.INVALID),
    ("wrong frame_id", lambda t: sample(t, frame="world"), Rejection.FRAME),
    ("wrong child_frame_id", lambda t: sample(t, child="camera"), Rejection.FRAME),
    ("future", lambda t: sample(t + 1.0), Rejection.FUTURE),
    ("10 s old", lambda t: sample(t - 10.0), Rejection.STALE),
    ("negative variance", lambda t: sample(t, cov=np.diag([-1.0, 1, 1, 1, 1, 1])), Rejection.COVARIANCE),
    ("asymmetric", lambda t: sample(t, cov=np.diag([1.0] * 6) + np.eye(6, k=1) * 0.5), Rejection.COVARIANCE),
    ("100 m away", lambda t: sample(t, (100.0, 0.0, 0.0)), Rejection.GATE),
]


@pytest.mark.parametrize(("name", "make", "reason"), BAD, ids=[b[0] for b in BAD])
def test_bad_sample_rejected_counted_never_fused(name, make, reason):
    f = running_filter()
    t = f.imu_t
    before, p = f.external_fused, f.ekf.p.copy()
    counts = dict(f.validator.counts)
    assert f.external(make(t - 0.01)) == reason
    assert f.validator.counts[reason] == counts[reason] + 1
    assert all(f.validator.counts[r] == counts[r] for r in Rejection if r != reason)
    assert f.external_fused == before and np.array_equal(f.ekf.p, p)


def test_all_zero_covariance_means_the_parameter_sigma():
    v = ExternalValidator(ExternalConfig(position_sigma_m=0.2, yaw_sigma_rad=0.1))
    ok = v.check(sample(1.0), 1.0, 0.0)
    assert not isinstance(ok, Rejection)
    assert np.allclose(ok.position_cov, np.eye(3) * 0.04) and math.isclose(ok.yaw_var, 0.01)


def test_a_1khz_flood_is_rate_limited_to_the_configured_rate():
    v = ExternalValidator(ExternalConfig(max_rate_hz=250.0))
    accepted = sum(not v.rate_limited(k * 0.001) and not isinstance(v.check(sample(k * 0.001), k * 0.001, 0.0), Rejection)
                   for k in range(1000))
    assert 249 <= accepted <= 251 and v.counts[Rejection.RATE] == 1000 - accepted


def test_alignment_estimate_recovers_yaw_and_origin():
    a = FrameAlignment(samples=10)
    yaw, origin = math.radians(-75.0), np.array([3.0, -1.0, 0.5])
    rot = np.array([[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0], [0, 0, 1]])
    for k in range(10):
        ext = np.array([0.1 * k, 0.2, 1.0])
        assert a.add(ext, 0.3, rot @ ext + origin, 0.3 + yaw) == (k == 9)
    assert math.isclose(a.yaw_offset, yaw, abs_tol=1e-9) and np.allclose(a.origin, origin)
    m, y = a.to_map(np.array([1.0, 0.0, 0.0]), 0.0)
    assert np.allclose(m, rot @ [1.0, 0.0, 0.0] + origin) and math.isclose(y, yaw)


def test_history_interpolates_and_shifts_and_rejects_outside():
    h = StateHistory(4)
    for k in range(6):
        h.push(k * 0.1, np.array([k, 0.0, 0.0]), np.zeros(3), quat.IDENTITY, np.zeros(3), np.zeros(3))
    assert h.count == 4 and math.isclose(h.oldest_t, 0.2) and h.at(0.1) is None and h.at(0.6) is None
    assert math.isclose(h.at(0.35)[P][0], 3.5)
    h.shift(np.array([1.0, 0.0, 0.0]), np.zeros(3))
    assert math.isclose(h.at(0.5)[P][0], 6.0)
