"""LocalFence.clamp: a point outside the fence moves to the nearest point inside it (and passes
`breach`); a point inside is returned as is."""

from __future__ import annotations

import math

import pytest

from c4d_common.geofence import LocalFence, pull_inside

SQUARE = ((-50.0, -50.0), (50.0, -50.0), (50.0, 50.0), (-50.0, 50.0))


def test_inside_points_are_unchanged():
    fence = LocalFence(SQUARE, 30.0, 60.0)
    for p in ((0.0, 0.0, 5.0), (40.0, -40.0, 29.9), (-10.0, 49.0, 0.0)):
        assert fence.clamp(p) == p
        assert fence.breach(p) is None


def test_outside_an_edge_goes_to_the_edge_margin_inside():
    fence = LocalFence(SQUARE, 0.0, 0.0)
    x, y, z = fence.clamp((80.0, 10.0, 7.0), margin=0.1)
    assert (x, y, z) == pytest.approx((49.9, 10.0, 7.0))
    assert fence.breach((x, y, z)) is None


def test_outside_a_corner_goes_to_the_corner():
    fence = LocalFence(SQUARE, 0.0, 0.0)
    x, y, _ = fence.clamp((70.0, 90.0, 3.0), margin=0.1)
    assert math.dist((x, y), (50.0, 50.0)) < 0.11
    assert fence.breach((x, y, 3.0)) is None


def test_acute_vertex_still_ends_inside():
    """Beyond the tip of a thin triangle the direction point → tip leaves the polygon; the nudge
    towards the centroid keeps the result inside."""
    triangle = [(0.0, -1.0), (100.0, 0.0), (0.0, 1.0)]
    outside = (110.0, 30.0)  # nearest boundary point: the tip (100, 0)
    x, y = pull_inside(outside, triangle, 0.1)
    assert math.dist((x, y), (100.0, 0.0)) < 0.11
    assert LocalFence(tuple(triangle), 0.0, 0.0).breach((x, y, 0.0)) is None


def test_ceiling_and_distance():
    fence = LocalFence((), 20.0, 100.0)
    assert fence.clamp((0.0, 0.0, 35.0), margin=0.5) == (0.0, 0.0, 19.5)
    x, y, z = fence.clamp((300.0, 400.0, 10.0), margin=0.5)  # 500 m out along (0.6, 0.8)
    assert (x, y, z) == pytest.approx((59.7, 79.6, 10.0))
    assert fence.breach((x, y, z)) is None


def test_non_convex_polygon_projects_onto_the_nearest_edge():
    """An L shape: a point in the notch goes to the nearer of the notch's two edges."""
    ell = ((0.0, 0.0), (100.0, 0.0), (100.0, 40.0), (40.0, 40.0), (40.0, 100.0), (0.0, 100.0))
    fence = LocalFence(ell, 0.0, 0.0)
    x, y, _ = fence.clamp((70.0, 45.0, 0.0), margin=0.1)  # 5 m above the edge y = 40, 30 m right of x = 40
    assert (x, y) == pytest.approx((70.0, 39.9))
    assert fence.breach((x, y, 0.0)) is None
