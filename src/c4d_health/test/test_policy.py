"""Failsafe policy: parsing, delays, most-severe-wins, escalation only, reset on disarm."""

from pathlib import Path

import pytest

from c4d_health.policy import Action, FailsafeArbiter, FailsafePolicy, PolicyError

POLICY = FailsafePolicy.from_yaml(Path(__file__).resolve().parents[1] / "config" / "failsafe.yaml")


def test_bundled_policy():
    assert POLICY.rules["gps_loss"].action == Action.LAND and POLICY.rules["battery_low"].action == Action.RTL
    assert POLICY.battery_critical < POLICY.battery_low and POLICY.node_timeout_s == 0.6


def test_delay_severity_and_no_oscillation():
    arbiter = FailsafeArbiter(POLICY)
    assert arbiter.update(0.0, {"battery_low": "29%"}, in_air=True) == Action.NONE  # 2 s delay not over
    assert arbiter.update(2.0, {"battery_low": "28%"}, in_air=True) == Action.RTL
    assert arbiter.reason == "battery_low: 28%"
    assert arbiter.update(2.5, {"battery_low": "27%", "battery_critical": "14%"}, True) == Action.RTL  # 1 s delay
    assert arbiter.update(3.5, {"battery_critical": "13%"}, True) == Action.LAND  # escalates
    assert arbiter.update(4.0, {"battery_low": "29%"}, True) == Action.LAND  # never back down to RTL
    assert arbiter.update(5.0, {}, True) == Action.LAND
    arbiter.reset()
    assert arbiter.update(6.0, {}, False) == Action.NONE


def test_ground_only_events_and_flicker():
    arbiter = FailsafeArbiter(POLICY)
    assert arbiter.update(0.0, {"gps_loss": "stale"}, in_air=False) == Action.NONE
    assert arbiter.update(10.0, {"gps_loss": "stale"}, in_air=False) == Action.NONE  # only_in_air
    assert arbiter.update(10.5, {"gps_loss": "stale"}, in_air=True) == Action.LAND  # held for 10 s already
    flicker = FailsafeArbiter(POLICY)
    flicker.update(0.0, {"gps_loss": "stale"}, True)
    assert flicker.update(2.0, {}, True) == Action.NONE  # cleared before its 3 s delay: the timer restarts
    assert flicker.update(3.0, {"gps_loss": "stale"}, True) == Action.NONE
    assert flicker.update(6.0, {"gps_loss": "stale"}, True) == Action.LAND


@pytest.mark.parametrize("doc,message", [
    ({"events": {"meteor": {"action": "land"}}}, "unknown event 'meteor'"),
    ({"events": {"gps_loss": {"action": "panic"}}}, "action must be one of"),
    ({"events": {"gps_loss": {"action": "land", "delay_s": -1}}}, "delay_s must be a number >= 0"),
    ({"events": {}, "battery_low_threshold": 0.1, "battery_critical_threshold": 0.2}, "battery_critical_threshold"),
    ({"rules": {}}, "needs an 'events' mapping"),
])
def test_bad_policy_names_the_field(doc, message):
    with pytest.raises(PolicyError, match=message):
        FailsafePolicy.from_dict(doc)
