"""The gateway's rules (c4d_offboard.gateway, ROS-free): each reason is decided from the values,
counted under its own key, and nothing refused is forwarded."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from c4d_common.geofence import LocalFence
from c4d_common.quat import yaw_of
from c4d_offboard.gateway import (
    NAN,
    Gateway,
    Level,
    Limits,
    RateLimiter,
    Reject,
    Setpoint,
    body_to_world,
    check_content,
    check_stamp,
    clamp_to_fence,
)

NOW = 1000.0


def position(x=1.0, y=2.0, z=3.0, **kw) -> Setpoint:
    return Setpoint(Level.POSITION, "map", NOW, (x, y, z), **kw)


def test_every_level_accepts_its_minimal_setpoint():
    good = [
        position(),
        Setpoint(Level.POSITION, "map", NOW, (NAN, NAN, 3.0), velocity=(1.0, 0.5, NAN)),  # velocity on x, y
        Setpoint(Level.VELOCITY, "map", NOW, velocity=(1.0, 0.0, 0.0)),
        Setpoint(Level.ACCELERATION, "map", NOW, acceleration=(0.0, 0.0, 0.5)),
        Setpoint(Level.ATTITUDE, "map", NOW, orientation=(2.0, 0.0, 0.0, 0.0), thrust=0.5),
        Setpoint(Level.RATE, "map", NOW, body_rate=(0.1, 0.0, 0.0), thrust=1.0),
    ]
    assert [check_content(sp) for sp in good] == [None] * len(good)


@pytest.mark.parametrize(("sp", "reason"), [
    (replace(position(), level=0), Reject.UNKNOWN_LEVEL),
    (replace(position(), level=9), Reject.UNKNOWN_LEVEL),
    (replace(position(), frame="odom"), Reject.FRAME),
    (replace(position(), frame="base_link"), Reject.FRAME),  # only the twist input takes base_link
    (position(x=NAN), Reject.MISSING),  # neither position nor velocity on x
    (position(z=math.inf), Reject.INFINITE),
    (position(yaw=-math.inf), Reject.INFINITE),  # inf in an optional field too
    (position(max_vertical_speed=math.inf), Reject.INFINITE),
    (Setpoint(Level.VELOCITY, "map", NOW, velocity=(1.0, NAN, 0.0)), Reject.MISSING),
    (Setpoint(Level.ACCELERATION, "map", NOW), Reject.MISSING),
    (Setpoint(Level.ATTITUDE, "map", NOW, orientation=(NAN, 0.0, 0.0, 0.0), thrust=0.5), Reject.MISSING),
    (Setpoint(Level.ATTITUDE, "map", NOW, orientation=(0.0, 0.0, 0.0, 0.0), thrust=0.5), Reject.QUATERNION),
    (Setpoint(Level.ATTITUDE, "map", NOW, thrust=NAN), Reject.MISSING),
    (Setpoint(Level.ATTITUDE, "map", NOW, thrust=1.2), Reject.THRUST),
    (Setpoint(Level.RATE, "map", NOW, body_rate=(0.0, 0.0, 0.0), thrust=-0.1), Reject.THRUST),
    (Setpoint(Level.RATE, "map", NOW, thrust=0.5), Reject.MISSING),  # body rates unset
])
def test_content_reasons(sp, reason):
    assert check_content(sp) is reason


def test_stamp_reasons():
    assert check_stamp(0.0, NOW, 0.5, 0.1) is Reject.UNSTAMPED
    assert check_stamp(NOW - 0.6, NOW, 0.5, 0.1) is Reject.STALE
    assert check_stamp(NOW + 0.2, NOW, 0.5, 0.1) is Reject.FUTURE
    assert check_stamp(NOW - 0.4, NOW, 0.5, 0.1) is None
    assert check_stamp(NOW + 0.05, NOW, 0.5, 0.1) is None


def test_gateway_counts_each_reason_and_forwards_nothing_refused():
    g = Gateway()
    bad = [replace(position(), level=7), replace(position(), frame="odom"), position(y=NAN), position(x=math.inf),
           replace(position(), stamp_s=NOW - 2.0), replace(position(), stamp_s=NOW + 1.0), replace(position(), stamp_s=0.0)]
    decisions = [g.offer(sp, NOW, float(i)) for i, sp in enumerate(bad)]
    assert all(d.setpoint is None for d in decisions)
    c = g.counters
    assert (c.received, c.accepted, c.rejected_total) == (7, 0, 7)
    assert {r.value: n for r, n in c.rejected.items() if n} == {
        "unknown_level": 1, "frame": 1, "nan_required": 1, "inf": 1, "stale": 1, "future": 1, "unstamped": 1}
    status = g.status(10.0)
    assert status["rejected_stale"] == "1" and status["rejected_bad_quaternion"] == "0" and status["stream_live"] == "false"


def test_claim_refuses_external_input_but_not_the_action():
    g = Gateway()
    g.owner = "goto"
    assert g.offer(position(), NOW, 0.0).reason is Reject.ACTION_ACTIVE
    assert g.offer_action(replace(position(), stamp_s=0.0)).setpoint is not None  # the action's stamp is not checked
    assert g.offer_action(position(x=NAN)).reason is Reject.MISSING  # its content is
    assert g.status(0.0)["action_owner"] == "goto"
    assert (g.counters.rejected[Reject.ACTION_ACTIVE], g.counters.action_setpoints) == (1, 1)


def test_attitude_quaternion_is_normalised():
    g = Gateway()
    out = g.offer(Setpoint(Level.ATTITUDE, "map", NOW, orientation=(0.0, 0.0, 0.0, 3.0), thrust=0.4), NOW, 0.0).setpoint
    assert out is not None and out.orientation == (0.0, 0.0, 0.0, 1.0)


def test_rate_limiter_holds_the_average_and_passes_a_jittery_stream_at_the_limit():
    flood = RateLimiter(100.0)
    passed = sum(flood.allow(i * 1e-4) for i in range(50_000))  # 10 kHz for 5 s
    assert 500 <= passed <= 502  # 100 Hz over 5 s + the burst
    at_limit = RateLimiter(100.0)
    jitter = [0.01 * i + (0.003 if i % 2 else -0.003) for i in range(1, 1001)]  # 100 Hz +-3 ms
    assert all(at_limit.allow(t) for t in jitter)


def test_gateway_rate_limits_valid_setpoints_and_says_the_stream_is_live():
    g = Gateway(Limits(max_rate_hz=50.0))
    decisions = [g.offer(position(), NOW, i * 1e-3) for i in range(1000)]  # 1 kHz for 1 s
    forwarded = sum(d.setpoint is not None for d in decisions)
    assert 50 <= forwarded <= 52 and g.counters.rate_limited == 1000 - forwarded
    assert g.live(1.2) and not g.live(1.6)


def test_position_targets_outside_the_fence_are_clamped_and_counted():
    g = Gateway()
    g.fence = LocalFence(((-50.0, -50.0), (50.0, -50.0), (50.0, 50.0), (-50.0, 50.0)), 30.0, 0.0)
    out = g.offer(position(x=500.0, y=0.0, z=100.0), NOW, 0.0)
    assert out.clamped and out.setpoint is not None
    assert out.setpoint.position == pytest.approx((49.9, 0.0, 29.9))
    inside = g.offer(position(), NOW, 1.0)
    assert not inside.clamped and inside.setpoint.position == (1.0, 2.0, 3.0)
    assert (g.counters.clamped, g.counters.accepted) == (1, 2)


def test_fence_clamp_leaves_unset_axes_unset_and_other_levels_alone():
    fence = LocalFence((), 30.0, 100.0)
    only_z = clamp_to_fence(Setpoint(Level.POSITION, "map", NOW, (NAN, NAN, 80.0), velocity=(1.0, 1.0, NAN)), fence)
    assert only_z is not None and math.isnan(only_z.position[0]) and only_z.position[2] == pytest.approx(29.9)
    assert clamp_to_fence(Setpoint(Level.POSITION, "map", NOW, (0.0, 500.0, NAN)), fence).position[1] == pytest.approx(99.9)
    assert clamp_to_fence(Setpoint(Level.VELOCITY, "map", NOW, velocity=(10.0, 0.0, 0.0)), fence) is None
    assert clamp_to_fence(position(), fence) is None


def test_body_twist_rotation_and_heading():
    assert body_to_world((1.0, 0.0, 0.5), math.pi / 2) == pytest.approx((0.0, 1.0, 0.5))  # facing north: forward = north
    assert body_to_world((0.0, 1.0, 0.0), math.pi / 2) == pytest.approx((-1.0, 0.0, 0.0))  # left = west
    half = math.pi / 8
    assert yaw_of((math.cos(half), 0.0, 0.0, math.sin(half))) == pytest.approx(math.pi / 4)
