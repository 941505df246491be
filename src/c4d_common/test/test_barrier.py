"""The barrier's potential has the D3.3 §6.7 properties, and the shield keeps its promises on single steps.

Properties of U(d) = (D - d)^3 / ((D - r)(d - r)) (c4d_common.barrier), proved analytically (the
closed forms of U, U', U'' are checked against finite differences, and their limits at D and r) and
numerically on dense grids: exactly zero for d >= D; +inf as d -> r; strictly decreasing on (r, D);
U, U', U'' continuous at D (one-sided values and difference quotients -> 0); exactly C^2 (U''' jumps).
"""

from __future__ import annotations

import math

import pytest

from c4d_common.barrier import (
    Barrier,
    BarrierError,
    BarrierParams,
    FenceGeometry,
    Obstacle,
    obstacle_contact,
    potential,
    potential_second_derivative,
    repulsion,
)
from c4d_common.geodesy import GeoOrigin
from c4d_common.plan import Geofence

D, R = 2.0, 0.5


def u(d: float) -> float:
    return potential(d, D, R)


def du(d: float) -> float:
    return -repulsion(d, D, R)


def ddu(d: float) -> float:
    return potential_second_derivative(d, D, R)


def grid(a: float, b: float, n: int = 2000) -> list[float]:
    return [a + (b - a) * k / n for k in range(n + 1)]


def test_zero_at_and_beyond_the_detection_range():
    for d in [D, D + 1e-12, 2.5, 10.0, 1e6, math.inf]:
        assert u(d) == 0.0 and du(d) == 0.0 and ddu(d) == 0.0
    # and strictly positive inside it: the barrier is active exactly on (r, D)
    assert all(u(d) > 0 for d in grid(R + 1e-6, D - 1e-6))


def test_grows_without_bound_at_the_protection_radius():
    values = [u(R + 10.0 ** -k) for k in range(1, 10)]
    assert all(b > a for a, b in zip(values, values[1:], strict=False))
    assert values[-1] > 1e8
    # U(r + e) ~ (D - r)^2 / e: the 1/e pole (not a finite cap)
    for e in (1e-3, 1e-6, 1e-9):
        assert u(R + e) * e == pytest.approx((D - R) ** 2, rel=1e-2)
    assert u(R) == math.inf and u(R - 0.1) == math.inf and repulsion(R, D, R) == math.inf


def test_strictly_decreasing_and_convex_inside_the_range():
    ds = grid(R + 1e-4, D - 1e-4)
    values = [u(d) for d in ds]
    assert all(b < a for a, b in zip(values, values[1:], strict=False))
    assert all(du(d) < 0 and ddu(d) > 0 for d in ds)


@pytest.mark.parametrize("d", [0.51, 0.6, 0.9, 1.25, 1.7, 1.99])
def test_closed_form_derivatives_match_finite_differences(d):
    h = min(1e-5, (d - R) * 1e-4)
    assert du(d) == pytest.approx((u(d + h) - u(d - h)) / (2 * h), rel=1e-6, abs=1e-9)
    assert ddu(d) == pytest.approx((du(d + h) - du(d - h)) / (2 * h), rel=1e-6, abs=1e-9)
    assert ddu(d) == pytest.approx((u(d + h) - 2 * u(d) + u(d - h)) / (h * h), rel=1e-4, abs=1e-5)


def test_value_first_and_second_derivative_continuous_at_the_detection_range():
    # analytically: with e = D - d, U = e^3/(c(c - e)), U' = -(3e^2(c - e) + e^3)/(c(c - e)^2), U'' = O(e):
    # all three -> 0 = the outside branch's values as e -> 0+
    for e in (1e-2, 1e-4, 1e-6):
        assert u(D - e) <= e ** 3 / (D - R - e) / (D - R) * 1.0001
        assert abs(du(D - e)) <= 3.1 * e ** 2 / (D - R) ** 2 + 1e-300
        assert abs(ddu(D - e)) <= 6.1 * e / (D - R) ** 2
    # numerically: one-sided difference quotients of U and U' across D agree (both -> 0)
    for h in (1e-3, 1e-4, 1e-5):
        left1, right1 = (u(D) - u(D - h)) / h, (u(D + h) - u(D)) / h
        left2, right2 = (du(D) - du(D - h)) / h, (du(D + h) - du(D)) / h
        assert abs(left1 - right1) < 10 * h and abs(left2 - right2) < 10 * h
    # exactly C^2: the third derivative jumps from -6/(D - r)^2 to 0 at D (a cubic factor is the least that works)
    h = 1e-6
    third_left = (ddu(D - h) - ddu(D - 2 * h)) / h
    assert third_left == pytest.approx(-6.0 / (D - R) ** 2, rel=1e-3)


def test_second_derivative_continuous_everywhere_on_the_open_interval():
    # on (r, D) U is rational with a non-vanishing denominator and beyond D it is 0 (both C-infinity), so D is the
    # only place to check; numerically over the whole range: halving the grid step halves the largest jump
    # between neighbours of U'' (a discontinuity would keep it), including grids with D as a node
    def largest_jump(n: int) -> float:
        second = [ddu(d) for d in grid(R + 0.05, D + 1.0, n)]
        return max(abs(b - a) for a, b in zip(second, second[1:], strict=False))

    for n in (1000, 2000, 4000):
        assert largest_jump(2 * n) < 0.55 * largest_jump(n)
    near = [ddu(d) for d in grid(D - 1e-3, D + 1e-3, 2000)]
    assert max(abs(b - a) for a, b in zip(near, near[1:], strict=False)) < 1e-5


def test_bad_parameters_are_refused_with_one_line():
    with pytest.raises(BarrierError, match="must exceed the protection radius"):
        BarrierParams(detection_range=0.5, protection_radius=0.5)
    with pytest.raises(BarrierError, match="brake_decel"):
        BarrierParams(brake_decel=0.0)
    with pytest.raises(BarrierError, match="protection radius"):
        BarrierParams(protection_radius=math.nan)


def test_stop_speed_stops_within_the_room():
    p = BarrierParams()
    for room in (0.1, 1.0, 5.0, 20.0):
        v = p.stop_speed(room)
        assert v * p.response_time + v * v / (2 * p.brake_decel) == pytest.approx(room)
    assert p.stop_speed(0.0) == 0.0 and p.stop_speed(-0.3) < 0.0 and p.stop_speed(-100.0) == -p.max_repulsion


# ----------------------------------------------------------------------------- the shield on single steps
def test_far_from_everything_the_setpoint_passes_unchanged():
    barrier = Barrier()
    v = (3.0, 1.0, 0.5)
    out = barrier.shield(0.0, 0.01, (0.0, 0.0, 5.0), (0.0, 0.0, 0.0), v, None, [Obstacle(1, 30.0, 0.0, 1.0)], None)
    assert out.velocity == v and not out.limited


def test_approach_towards_an_obstacle_is_capped_to_what_stops_outside_the_protection_radius():
    p = BarrierParams()
    barrier = Barrier(p)
    obstacle = Obstacle(1, 5.0, 0.0, 1.0)
    for x in (-8.0, -2.0, 0.0, 2.5, 3.3):
        d = 5.0 - 1.0 - x
        out = barrier.shield(0.0, 0.01, (x, 0.0, 5.0), (0.0, 0.0, 0.0), (8.0, 0.0, 0.0), None, [obstacle], None)
        assert out.velocity[0] <= p.stop_speed(d - p.protection_radius - p.margin) + 1e-9
    # moving away or along is never slowed by the cap
    out = barrier.shield(0.0, 0.01, (-8.0, 0.0, 5.0), (0.0, 0.0, 0.0), (-5.0, 0.0, 0.0), None, [obstacle], None)
    assert out.velocity == (-5.0, 0.0, 0.0)


def test_a_closing_mover_makes_the_vehicle_back_off():
    barrier = Barrier()
    mover = Obstacle(7, 2.7, 0.0, 0.5, vx=-4.0)  # 4 m/s towards a hovering vehicle, surface 2.2 m away
    out = barrier.shield(0.0, 0.01, (0.0, 0.0, 5.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), None, [mover], None)
    assert out.velocity[0] < -0.5
    # the same obstacle at rest does not push at this distance (outside D)
    still = Obstacle(7, 2.7, 0.0, 0.5)
    out = barrier.shield(0.0, 0.01, (0.0, 0.0, 5.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), None, [still], None)
    assert out.velocity == (0.0, 0.0, 0.0)


def test_cylinder_contact_over_the_top():
    c = obstacle_contact(Obstacle(1, 0.0, 0.0, 1.0, top=4.0), (2.0, 0.0, 6.0), 0.0)
    assert c.distance == pytest.approx(math.hypot(1.0, 2.0))
    assert c.normal == pytest.approx((1 / math.sqrt(5), 0.0, 2 / math.sqrt(5)))
    c = obstacle_contact(Obstacle(1, 0.0, 0.0, 1.0), (2.0, 0.0, 60.0), 0.0)
    assert c.distance == pytest.approx(1.0) and c.normal == pytest.approx((1.0, 0.0, 0.0))


HOME = GeoOrigin(43.5629, 1.4815, 146.0)


def fence_of(**local):
    """A Geofence from local (east, north) geometry, through the geodetic conversion the core uses."""
    def geo(e, n):
        lat, lon, _ = HOME.to_geodetic(e, n, 0.0)
        return (lat, lon)
    return Geofence(polygon=tuple(geo(*p) for p in local.get("polygon", ())), max_altitude=local.get("ceiling", 0.0),
                    max_distance=local.get("max_distance", 0.0),
                    exclusion_circles=tuple((*geo(e, n), r) for e, n, r in local.get("circles", ())),
                    exclusion_polygons=tuple(tuple(geo(*p) for p in poly) for poly in local.get("exclusions", ())),
                    min_altitude=local.get("floor", 0.0))


def test_fence_geometry_converts_once_to_local_and_gives_inward_normals():
    fence = FenceGeometry.from_geofence(fence_of(polygon=[(-20, -20), (20, -20), (20, 20), (-20, 20)], ceiling=30.0,
                                                 circles=[(10.0, 0.0, 3.0)], max_distance=25.0, floor=2.0), HOME)
    assert fence.inclusion[1] == pytest.approx((20.0, -20.0), abs=1e-3)
    contacts = fence.contacts((15.0, 0.0, 10.0))
    east = min(contacts[:4], key=lambda c: c.distance)
    assert east.distance == pytest.approx(5.0, abs=1e-3) and east.normal == pytest.approx((-1.0, 0.0, 0.0), abs=1e-6)
    circle = contacts[4]
    assert circle.distance == pytest.approx(2.0, abs=1e-3) and circle.normal == pytest.approx((1.0, 0.0, 0.0), abs=1e-6)
    assert contacts[5].distance == pytest.approx(10.0, abs=1e-3)  # max distance 25 m
    assert contacts[6].distance == pytest.approx(20.0) and contacts[6].normal == (0.0, 0.0, -1.0)  # ceiling
    assert contacts[7].distance == pytest.approx(8.0) and contacts[7].normal == (0.0, 0.0, 1.0)  # floor
    assert len(fence.contacts((15.0, 0.0, 10.0), with_floor=False)) == 7


def test_outside_the_inclusion_polygon_the_barrier_pushes_back_in():
    fence = FenceGeometry(inclusion=((0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)))
    out = Barrier().shield(0.0, 0.01, (11.0, 5.0, 5.0), (0.0, 0.0, 0.0), (2.0, 0.0, 0.0), None, [], fence)
    assert out.velocity[0] < 0.0
    inside = fence.contacts((9.0, 5.0, 5.0))
    assert min(c.distance for c in inside) == pytest.approx(1.0)


def test_corner_push_is_capped_on_both_walls():
    p = BarrierParams()
    fence = FenceGeometry(inclusion=((0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)))
    out = Barrier(p).shield(0.0, 0.01, (9.0, 9.0, 5.0), (0.0, 0.0, 0.0), (8.0, 8.0, 0.0), None, [], fence)
    limit = p.stop_speed(1.0 - p.protection_radius - p.margin)
    assert out.velocity[0] <= limit + 1e-9 and out.velocity[1] <= limit + 1e-9


def test_blocked_head_on_starts_a_deterministic_detour_after_the_stall_time():
    p = BarrierParams()
    barrier = Barrier(p)
    obstacle = Obstacle(3, 3.0, 0.0, 1.0)
    position, target = (0.9, 0.0, 5.0), (10.0, 0.0, 5.0)  # 1.1 m from the surface, held there, target behind it
    t, detour_at = 0.0, None
    while t < 3.0:
        out = barrier.shield(t, 0.01, position, (0.0, 0.0, 0.0), (3.0, 0.0, 0.0), target, [obstacle], None)
        if out.detour and detour_at is None:
            detour_at = t
        t += 0.01
    assert detour_at is not None and p.detour_after - 0.02 <= detour_at < p.detour_after + 0.35
    # head-on tie: counter-clockwise around the obstacle (from its west side: south first)
    assert out.detour == 1 and out.velocity[1] < -1.0
    # the side closer to the target wins: target north of the line -> clockwise (north first)
    other = Barrier(p)
    for k in range(300):
        out = other.shield(k * 0.01, 0.01, position, (0.0, 0.0, 0.0), (3.0, 0.0, 0.0), (10.0, 3.0, 5.0), [obstacle],
                           None)
    assert out.detour == -1 and out.velocity[1] > 1.0


def test_detour_ends_when_the_line_to_the_target_clears():
    barrier = Barrier()
    obstacle = Obstacle(3, 3.0, 0.0, 1.0)
    for k in range(200):
        out = barrier.shield(k * 0.01, 0.01, (0.9, 0.0, 5.0), (0.0, 0.0, 0.0), (3.0, 0.0, 0.0), (10.0, 0.0, 5.0),
                             [obstacle], None)
    assert out.detour == 1
    out = barrier.shield(2.0, 0.01, (3.0, -2.4, 5.0), (0.0, 0.0, 0.0), (3.0, 0.0, 0.0), (10.0, -2.4, 5.0), [obstacle],
                         None)
    assert out.detour == 0
