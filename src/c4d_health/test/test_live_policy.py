"""The health node's live failsafe thresholds (ROS-free): the table covers every threshold, timeout
and delay of the bundled policy, round-trips it, refuses bad values and broken cross rules with the
reason, and a changed threshold changes what the event evaluation reports."""

from __future__ import annotations

import math

from c4d_health.events import HealthSnapshot, evaluate
from c4d_health.health_node import default_policy
from c4d_health.live_policy import STALL, TOP, policy_table, policy_values, policy_with
from c4d_health.policy import FailsafePolicy

POLICY = FailsafePolicy.from_yaml(default_policy())


def test_table_covers_the_policy_and_round_trips():
    table = policy_table(POLICY)
    names = {t.name for t in table}
    assert set(TOP) | set(STALL) <= names
    assert {f"events.{e}.delay_s" for e in POLICY.rules} <= names
    assert {f"events.{e}.then_after_s" for e, r in POLICY.rules.items() if r.then is not None} \
        == {n for n in names if n.endswith(".then_after_s")}
    assert policy_with(POLICY, policy_values(POLICY)) == POLICY
    assert table.defaults()["battery_low_threshold"] == 0.30 and table.defaults()["node_timeout_s"] == 0.6
    tuned = policy_with(POLICY, {"battery_low_threshold": 0.4, "core_stall_skipped_ticks": 50.0,
                                 "events.link_loss.delay_s": 2.0, "events.offboard_loss.then_after_s": 9.0})
    assert tuned.battery_low == 0.4 and tuned.core_stall.skipped_ticks == 50
    assert isinstance(tuned.core_stall.skipped_ticks, int)
    assert tuned.rules["link_loss"].delay_s == 2.0 and tuned.rules["link_loss"].action == POLICY.rules["link_loss"].action
    assert tuned.rules["offboard_loss"].then_after_s == 9.0 and tuned.rules["gps_loss"] == POLICY.rules["gps_loss"]


def test_refusals_say_why():
    table = policy_table(POLICY)
    values = table.defaults()
    assert table.check({"battery_critical_threshold": 0.30}, values) == \
        "battery_critical_threshold (0.3) must be below battery_low_threshold (0.3)"
    assert "must be below battery_low_threshold" in table.check({"battery_low_threshold": 0.1}, values)
    assert "must be below obstacle_detection_range_m" in table.check({"obstacle_protection_radius_m": 3.0}, values)
    assert "not an integer" in table.check({"core_stall_repeat_count": 2.5}, values)
    assert "not finite" in table.check({"node_timeout_s": math.inf}, values)
    assert "outside" in table.check({"node_timeout_s": 0.0}, values)
    assert "outside" in table.check({"events.gps_loss.delay_s": -1.0}, values)
    assert "no such parameter" in table.check({"events.gps_loss.then_after_s": 1.0}, values)  # gps_loss has no 'then'
    assert table.check({"battery_low_threshold": 0.5, "battery_critical_threshold": 0.35}, values) == ""


def test_a_raised_battery_threshold_changes_the_evaluation():
    snapshot = HealthSnapshot(battery_soc=0.35)
    assert "battery_low" not in evaluate(snapshot, POLICY, 0.0)
    assert "battery_low" in evaluate(snapshot, policy_with(POLICY, {"battery_low_threshold": 0.4}), 0.0)
