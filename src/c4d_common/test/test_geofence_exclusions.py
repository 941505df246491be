"""Exclusion zones and the floor (issue 18): parsing from YAML plans and QGC .plan files, breach
checks, leg checks, clamping out of a zone, and pre-flight / go-to validation against them."""

from __future__ import annotations

import json
import math

import pytest

from c4d_common.geodesy import GeoOrigin
from c4d_common.geofence import BreachKind, LocalFence, leg_enters_polygon
from c4d_common.plan import Geofence, Item, PlanError, plan_from_yaml_text
from c4d_common.plan_files import plan_from_qgc_text
from c4d_common.plan_validation import IssueKind, check_goto, validate

HOME = GeoOrigin(43.5629, 1.4815, 146.0)
BOX = ((10.0, -5.0), (20.0, -5.0), (20.0, 5.0), (10.0, 5.0))  # east 10..20, north -5..5


def geo(east: float, north: float) -> tuple[float, float]:
    lat, lon, _ = HOME.to_geodetic(east, north, 0.0)
    return (lat, lon)


def test_breach_kinds_for_exclusions_and_the_floor():
    fence = LocalFence((), 0.0, 0.0, (BOX,), ((0.0, 30.0, 4.0),), 3.0)
    assert fence.breach((15.0, 0.0, 10.0)).kind is BreachKind.EXCLUSION_POLYGON
    assert fence.breach((1.0, 28.0, 10.0)).kind is BreachKind.EXCLUSION_CIRCLE
    assert fence.breach((0.0, 0.0, 2.0)) is None  # the floor only while flying
    floor = fence.breach((0.0, 0.0, 2.0), with_floor=True)
    assert floor.kind is BreachKind.FLOOR and "3 m floor" in floor.text
    for outside in ((9.9, 0.0, 10.0), (0.0, 25.9, 10.0), (30.0, 30.0, 3.0)):
        assert fence.breach(outside, with_floor=True) is None


def test_leg_through_an_exclusion_with_both_ends_outside():
    fence = LocalFence((), 0.0, 0.0, (BOX,), ((0.0, 30.0, 4.0),))
    assert fence.leg_exclusion((0.0, 0.0), (30.0, 0.0)) == "exclusion polygon 0"  # straight through the box
    assert fence.leg_exclusion((0.0, 0.0), (15.0, 0.0)) == "exclusion polygon 0"  # ends inside
    assert fence.leg_exclusion((0.0, 10.0), (30.0, 10.0)) == ""  # passes north of it
    assert fence.leg_exclusion((-10.0, 30.0), (10.0, 30.0)) == "exclusion circle 0"
    assert fence.leg_exclusion((-10.0, 35.0), (10.0, 35.0)) == ""  # 5 m from the centre, radius 4
    assert not leg_enters_polygon((0.0, -6.0), (30.0, -6.0), list(BOX))


def test_clamp_moves_a_target_out_of_an_exclusion_zone():
    fence = LocalFence((), 0.0, 0.0, (BOX,), ((0.0, 30.0, 4.0),))
    x, y, z = fence.clamp((11.0, 1.0, 5.0), margin=0.1)  # nearest edge: east = 10
    assert (x, y, z) == pytest.approx((9.9, 1.0, 5.0))
    x, y, _ = fence.clamp((0.0, 31.0, 5.0), margin=0.1)
    assert math.dist((x, y), (0.0, 30.0)) == pytest.approx(4.1)
    for p in ((11.0, 1.0, 5.0), (0.0, 31.0, 5.0), (0.0, 30.0, 5.0)):
        assert fence.breach(fence.clamp(p)) is None


def test_yaml_plan_fence_with_exclusions_and_floor():
    a, b, c, d = geo(10, -5), geo(20, -5), geo(20, 5), geo(10, 5)
    text = f"""
geofence:
  max_altitude: 30
  min_altitude: 3
  exclusion_polygons: [[{list(a)}, {list(b)}, {list(c)}, {list(d)}]]
  exclusion_circles: [{{lat: {geo(0, 30)[0]}, lon: {geo(0, 30)[1]}, radius: 4}}]
items:
  - {{type: takeoff, altitude: 5}}
  - {{type: waypoint, east: 0, north: 10, alt: 5}}
  - {{type: land}}
"""
    plan = plan_from_yaml_text(text)
    fence = plan.geofence
    assert fence.min_altitude == 3 and fence.max_altitude == 30 and len(fence.exclusion_polygons[0]) == 4
    assert fence.exclusion_circles[0][2] == 4 and not fence.empty
    local = LocalFence.from_geofence(fence, HOME)
    assert local.exclusion_polygons[0][0] == pytest.approx((10.0, -5.0), abs=1e-6)
    assert validate(plan, HOME, endurance_s=1000).ok
    through = text.replace("east: 0, north: 10", "east: 30, north: 0")
    result = validate(plan_from_yaml_text(through), HOME, endurance_s=1000)
    assert [(i.kind, i.item) for i in result.issues] == [(IssueKind.ENTERS_EXCLUSION, 1)]
    assert result.errors == ("item 2: leg enters the geofence's exclusion polygon 0",)
    low = validate(plan_from_yaml_text(text.replace("alt: 5}", "alt: 2}")), HOME, endurance_s=1000)
    assert [(i.kind, i.item) for i in low.issues] == [(IssueKind.BELOW_FLOOR, 1)]


@pytest.mark.parametrize("fence, message", [
    ("{min_altitude: 30, max_altitude: 20}", "floor 30 m is not below its ceiling 20 m"),
    ("{exclusion_polygons: [[[43.5, 1.4], [43.6, 1.4]]]}", "exclusion polygon 0 needs at least 3 vertices"),
    ("{exclusion_polygons: [[[43.5, 1.4], [43.6, 1.4], [43.6, .nan]]]}", "exclusion polygon 0 vertex 2: must be [lat, lon]"),
    ("{exclusion_circles: [{lat: 43.5, lon: 1.4, radius: 0}]}", "exclusion circle 0: radius must be > 0 m"),
    ("{exclusion_circles: [{lat: 43.5, lon: 1.4}]}", "exclusion circle 0: must be {lat, lon, radius}"),
    ("{exclusions: []}", "geofence: unknown field(s) exclusions"),
])
def test_yaml_fence_errors_name_the_part(fence, message):
    with pytest.raises(PlanError, match=message.replace("[", r"\[").replace("(", r"\(").replace(")", r"\)")):
        plan_from_yaml_text(f"geofence: {fence}\nitems: [{{type: land}}]")


def qgc(fence: dict) -> str:
    return json.dumps({"fileType": "Plan", "mission": {"items": []}, "geoFence": fence})


def test_qgc_plan_exclusion_polygons_and_circles():
    square = [[43.5628, 1.4814], [43.5628, 1.4818], [43.5632, 1.4818], [43.5632, 1.4814]]
    doc = {"version": 2, "polygons": [{"inclusion": True, "polygon": square, "version": 1},
                                      {"inclusion": False, "polygon": square[:3], "version": 1}],
           "circles": [{"circle": {"center": [43.563, 1.4816], "radius": 12.5}, "inclusion": False, "version": 1}]}
    fence = plan_from_qgc_text(qgc(doc)).geofence
    assert fence.polygon == tuple(map(tuple, square))
    assert fence.exclusion_polygons == (tuple(map(tuple, square[:3])),)
    assert fence.exclusion_circles == ((43.563, 1.4816, 12.5),)
    with pytest.raises(PlanError, match="inclusion circles are not supported"):
        plan_from_qgc_text(qgc({"circles": [{"circle": {"center": [43.563, 1.4816], "radius": 12.5}, "inclusion": True}]}))
    with pytest.raises(PlanError, match="second inclusion polygon"):
        plan_from_qgc_text(qgc({"polygons": [{"polygon": square}, {"polygon": square}]}))
    with pytest.raises(PlanError, match="radius > 0"):
        plan_from_qgc_text(qgc({"circles": [{"circle": {"center": [43.563, 1.4816], "radius": -1}, "inclusion": False}]}))


def test_goto_through_an_exclusion_or_below_the_floor_is_refused():
    fence = Geofence(exclusion_polygons=(tuple(geo(e, n) for e, n in BOX),), min_altitude=3.0)
    lat, lon = geo(30.0, 0.0)
    issues = check_goto(Item("loiter", "global", lat, lon, 5.0), (0.0, 0.0, 5.0), fence, HOME)
    assert [i.kind for i in issues] == [IssueKind.ENTERS_EXCLUSION]
    lat, lon = geo(0.0, 20.0)
    issues = check_goto(Item("loiter", "global", lat, lon, 2.0), (0.0, 0.0, 5.0), fence, HOME)
    assert [i.kind for i in issues] == [IssueKind.BELOW_FLOOR]
    assert check_goto(Item("loiter", "global", lat, lon, 5.0), (0.0, 0.0, 5.0), fence, HOME) == []
