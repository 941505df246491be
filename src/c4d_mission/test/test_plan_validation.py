"""Plan files and validation: YAML and QGroundControl formats, item-by-item rejections."""

import json
from pathlib import Path

import pytest

from c4d_common.geodesy import GeoOrigin
from c4d_common.plan import Geofence, Item, Plan, PlanError, plan_from_yaml_text
from c4d_common.plan_files import load_plan, plan_from_qgc_text
from c4d_common.plan_validation import VehicleLimits, validate

ROOT = Path(__file__).resolve().parents[3]
HOME = GeoOrigin(43.5629, 1.4815, 146.0)


def test_example_survey_is_valid():
    plan = load_plan(ROOT / "missions" / "survey.yaml")
    result = validate(plan, HOME, endurance_s=1200)
    assert result.ok, result.errors
    assert [i.type for i in plan.items].count("waypoint") == 6
    assert result.path_length > 100 and 30 < result.duration < 200


def test_outside_geofence_too_high_and_too_far_are_rejected_item_by_item():
    plan = load_plan(ROOT / "missions" / "survey.yaml")
    text = (ROOT / "missions" / "survey.yaml").read_text()
    bad = text.replace("{type: waypoint, east: 20, north: 20, alt: 8", "{type: waypoint, east: 200, north: 20, alt: 8")
    bad = bad.replace("{type: waypoint, east: 0, north: 30, alt: 8", "{type: waypoint, east: 0, north: 30, alt: 50")
    result = validate(plan_from_yaml_text(bad), HOME)
    assert any(e.startswith("item 5: outside the geofence polygon") for e in result.errors)
    assert any(e.startswith("item 5:") and "exceeds the geofence's 120 m" in e for e in result.errors)
    assert any(e.startswith("item 7: altitude 50 m above the maximum 30 m") for e in result.errors)
    assert validate(plan, HOME).ok  # the original is untouched


def test_a_point_outside_the_fence_is_one_error_per_fact_numbered_from_1():
    # waypoint 5 (1-based, as in the file) at 300 m east: outside the polygon and too far; the leg back
    # from it (item 6) is a consequence, not a second error
    text = (ROOT / "missions" / "survey.yaml").read_text().replace("east: 20, north: 20", "east: 300, north: 20")
    errors = validate(plan_from_yaml_text(text), HOME).errors
    assert errors == ("item 5: 301 m from home exceeds the geofence's 120 m", "item 5: outside the geofence polygon")
    # two points outside in a row: each named once; a leg between two inside points that cuts the
    # polygon's corner is named by the item it leads to
    two = text.replace("east: 0, north: 20", "east: 100, north: 20")
    assert [e for e in validate(plan_from_yaml_text(two), HOME).errors if "polygon" in e] == [
        "item 5: outside the geofence polygon", "item 6: outside the geofence polygon"]
    square = [(0.0, 0.0), (50.0, 0.0), (50.0, 50.0), (25.0, 25.0), (0.0, 50.0)]  # a notch from the north
    corner = Plan((Item("takeoff", z=5.0), Item("waypoint", x=0.0, y=30.0, z=5.0), Item("waypoint", x=30.0, y=30.0, z=5.0)),
                  Geofence(tuple(HOME.to_geodetic(e - 10.0, n - 5.0, 0.0)[:2] for e, n in square)))
    assert list(validate(corner, HOME).errors) == ["item 3: leg leaves the geofence polygon"]


def test_endurance_and_limits():
    plan = load_plan(ROOT / "missions" / "survey.yaml")
    assert any("exceeds 80 %" in e for e in validate(plan, HOME, endurance_s=60).errors)
    fast = plan_from_yaml_text("items:\n  - {type: takeoff, altitude: 5}\n  - {type: change_speed, speed: 20}\n"
                               "  - {type: land}\n")
    assert any("speed 20 m/s above" in e for e in validate(fast, HOME, VehicleLimits(max_speed=8)).errors)


def test_a_plan_without_take_off_is_flown_from_the_ground_with_an_implicit_climb():
    """Issue 14 (PX4 semantics): a waypoint before any take-off item was refused ("before any
    take-off"); it is valid, and the estimate counts the climb to its altitude, at least the
    vehicle's take-off altitude (MIS_TAKEOFF_ALT)."""
    early = plan_from_yaml_text("items:\n  - {type: waypoint, east: 3, north: 4, alt: 5}\n  - {type: land}\n")
    result = validate(early, HOME)
    assert result.ok and not result.warnings, result.errors
    assert result.path_length == pytest.approx(5.0 + 5.0 + 5.0)  # climb 5, 5 m across, descend 5
    higher = validate(early, HOME, VehicleLimits(takeoff_altitude=8.0))
    assert higher.ok and higher.path_length == pytest.approx(8.0 + 3.0 + 5.0 + 5.0)  # climb 8, down 3, across, land
    capped = plan_from_yaml_text("geofence: {max_altitude: 6}\nitems:\n  - {type: waypoint, east: 3, north: 4, alt: 5}\n")
    assert validate(capped, HOME, VehicleLimits(takeoff_altitude=8.0)).errors == (
        "item 1: take-off altitude 8 m above the maximum 6 m",)


@pytest.mark.parametrize("text,message", [
    ("items: [", "malformed YAML"),
    ("name: x\n", "needs an 'items' list"),
    ("items:\n  - {type: teleport}\n", "unknown item type 'teleport'"),
    ("items:\n  - {type: waypoint, alt: 5}\n", "needs lat/lon or east/north"),
    ("items:\n  - {type: waypoint, east: 1, north: 2, alt: .nan}\n", "must be a finite number"),
    ("items:\n  - {type: takeoff, altitude: 5, colour: red}\n", "unknown field(s) colour"),
    ("geofence: {polygon: [[1, 2], [3, 4]]}\nitems: []\n", "at least 3 vertices"),
])
def test_malformed_plans_say_why(text, message):
    with pytest.raises(PlanError) as err:
        plan_from_yaml_text(text)
    assert message in str(err.value)


def test_qgroundcontrol_plan_import():
    doc = {"fileType": "Plan", "version": 1, "groundStation": "QGroundControl",
           "geoFence": {"polygons": [{"inclusion": True, "polygon": [[43.5625, 1.481], [43.5625, 1.4823],
                                                                       [43.56345, 1.4823], [43.56345, 1.481]]}]},
           "mission": {"cruiseSpeed": 4, "items": [
               {"type": "SimpleItem", "command": 22, "frame": 3, "params": [0, 0, 0, None, 43.5629, 1.4815, 10]},
               {"type": "SimpleItem", "command": 16, "frame": 3, "params": [2, 1.5, 0, None, 43.5630, 1.4816, 10]},
               {"type": "SimpleItem", "command": 206, "frame": 2, "params": [5, 0, 1, 0, 0, 0, 0]},
               {"type": "SimpleItem", "command": 20, "frame": 2, "params": [0, 0, 0, 0, 0, 0, 0]}]}}
    plan = plan_from_qgc_text(json.dumps(doc))
    assert [i.type for i in plan.items] == ["takeoff", "waypoint", "camera_distance", "rtl"]
    assert plan.items[1].hold == 2 and plan.items[1].acceptance_radius == 1.5 and plan.cruise_speed == 4
    assert len(plan.geofence.polygon) == 4 and validate(plan, HOME).ok
    doc["mission"]["items"].append({"type": "ComplexItem", "complexItemType": "survey"})
    with pytest.raises(PlanError, match="item 5: only SimpleItem"):
        plan_from_qgc_text(json.dumps(doc))
    with pytest.raises(PlanError, match="not a QGroundControl"):
        plan_from_qgc_text("{}")


def test_goto_targets_follow_the_plan_rules():
    from c4d_common.plan import GLOBAL, Item
    from c4d_common.plan_validation import check_goto

    fence = load_plan(ROOT / "missions" / "survey.yaml").geofence

    def check(target):
        return [str(issue) for issue in check_goto(target, (0.0, 0.0, 5.0), fence, HOME)]

    def goto(east, north, alt):
        lat, lon, _ = HOME.to_geodetic(east, north, 0.0)
        return Item("loiter", frame=GLOBAL, x=lat, y=lon, z=alt)

    assert check(goto(10, 10, 8)) == []
    assert any("exceeds the geofence's 120 m" in e for e in check(goto(200, 0, 8)))
    assert any("leaves the geofence polygon" in e for e in check(goto(200, 0, 8)))
    assert check(goto(10, 10, 50)) == ["go-to altitude 50 m outside [1, 30] m"]
    assert check(Item("loiter", frame=GLOBAL, x=float("nan"), y=1.0, z=5.0)) == \
        ["go-to target needs a finite position and altitude"]
    assert check(Item("loiter", frame=GLOBAL, x=95.0, y=1.0, z=5.0)) == \
        ["go-to target latitude/longitude out of range"]


def test_issues_are_typed_with_the_item_and_the_same_text():
    from c4d_common.plan import GLOBAL, Item
    from c4d_common.plan_validation import IssueKind, check_goto

    text = (ROOT / "missions" / "survey.yaml").read_text()
    bad = text.replace("{type: waypoint, east: 20, north: 20, alt: 8", "{type: waypoint, east: 200, north: 20, alt: 8")
    result = validate(plan_from_yaml_text(bad), HOME)
    kinds = {(i.kind, i.item) for i in result.issues}
    assert {(IssueKind.LEAVES_POLYGON, 4), (IssueKind.TOO_FAR, 4)} <= kinds
    assert result.errors == tuple(str(i) for i in result.issues)
    airborne = validate(plan_from_yaml_text("items:\n  - {type: takeoff, altitude: 5}\n"), HOME)
    assert [i.kind for i in airborne.notices] == [IssueKind.ENDS_IN_AIR]
    assert airborne.warnings == ("plan: ends in the air (no land or RTL item)",)
    fence = load_plan(ROOT / "missions" / "survey.yaml").geofence
    malformed = check_goto(Item("loiter", frame=GLOBAL, x=95.0, y=1.0, z=5.0), (0.0, 0.0, 5.0), fence, HOME)
    assert [i.kind.malformed for i in malformed] == [True]
    lat, lon, _ = HOME.to_geodetic(200.0, 0.0, 0.0)
    outside = check_goto(Item("loiter", frame=GLOBAL, x=lat, y=lon, z=8.0), (0.0, 0.0, 5.0), fence, HOME)
    assert {i.kind for i in outside} == {IssueKind.TOO_FAR, IssueKind.LEAVES_POLYGON}
    assert not any(i.kind.malformed for i in outside)


def test_flight_time_left_keeps_the_reserve():
    from c4d_common.plan_validation import flight_time_left

    assert flight_time_left(5.0, 20.0) == 5.0 * 0.8 / 20.0 * 3600.0
    assert flight_time_left(float("nan"), 20.0) is None and flight_time_left(0.0, 20.0) == 0.0
