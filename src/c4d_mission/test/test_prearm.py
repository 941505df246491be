"""Pre-arm checks without ROS: each rule refuses with its kind and the operator's text."""

from pathlib import Path

from c4d_common.geodesy import GeoOrigin
from c4d_common.geofence import LocalFence
from c4d_common.plan_files import load_plan
from c4d_mission.prearm import PreArmChecks, PreArmInputs, RefusalKind

ROOT = Path(__file__).resolve().parents[3]
HOME = GeoOrigin(43.5629, 1.4815, 146.0)
FENCE = LocalFence.from_geofence(load_plan(ROOT / "missions" / "survey.yaml").geofence, HOME)


def refusal(**kw):
    inputs = dict(estimator_ready=True, position=(0.0, 0.0, 0.0), sensor_ok={"gps": True, "baro": True},
                  battery_fraction=0.9, fence=FENCE)
    inputs.update(kw)
    return PreArmChecks(min_battery=0.2).check(PreArmInputs(**inputs))


def test_a_ready_vehicle_inside_the_fence_may_arm():
    assert refusal() is None
    assert refusal(battery_fraction=None, fence=None) is None  # no battery report yet, no plan


def test_each_rule_refuses_with_its_kind_and_text():
    r = refusal(estimator_ready=False)
    assert r.kind == RefusalKind.ESTIMATOR_NOT_READY and str(r) == "estimator not ready (attitude, position and home needed)"
    r = refusal(sensor_ok={"mag": False, "gps": True, "baro": False})
    assert r.kind == RefusalKind.SENSORS_UNHEALTHY and str(r) == "sensors not healthy: baro, mag"
    r = refusal(battery_fraction=0.15)
    assert r.kind == RefusalKind.BATTERY_LOW and str(r) == "battery at 15%, below the 20% reserve"
    r = refusal(position=(500.0, 0.0, 0.0))
    assert r.kind == RefusalKind.OUTSIDE_GEOFENCE and str(r) == "outside the geofence"


def test_rules_are_checked_in_order():
    assert refusal(estimator_ready=False, battery_fraction=0.0).kind == RefusalKind.ESTIMATOR_NOT_READY
    assert refusal(sensor_ok={"gps": False}, battery_fraction=0.0).kind == RefusalKind.SENSORS_UNHEALTHY


def test_a_position_source_the_navigation_does_not_use_need_not_be_healthy():
    """GNSS off from boot, the navigation on an external pose: no fix is not a reason to refuse."""
    assert refusal(sensor_ok={"gps": False, "baro": True}, unused_sensors=frozenset({"gps"})) is None
    r = refusal(sensor_ok={"gps": False, "baro": False}, unused_sensors=frozenset({"gps"}))
    assert r.kind == RefusalKind.SENSORS_UNHEALTHY and str(r) == "sensors not healthy: baro"


def test_an_untrusted_gnss_the_estimate_depends_on_refuses_arming():
    r = refusal(gnss_untrusted="jammed")
    assert r.kind == RefusalKind.GNSS_UNTRUSTED and str(r).startswith("GNSS jammed (integrity monitor)")
    assert refusal(gnss_untrusted="jammed", estimator_ready=False).kind == RefusalKind.ESTIMATOR_NOT_READY
