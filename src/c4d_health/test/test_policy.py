"""Failsafe policy: parsing, delays, most-severe-wins, escalation only, reset on disarm."""

from pathlib import Path

import pytest

from c4d_health.policy import EVENTS, Action, CoreStallLimits, FailsafeArbiter, FailsafePolicy, PolicyError, Rule

POLICY = FailsafePolicy.from_yaml(Path(__file__).resolve().parents[1] / "config" / "failsafe.yaml")


def test_bundled_policy():
    assert POLICY.rules["gps_loss"].action == Action.LAND and POLICY.rules["battery_low"].action == Action.RTL
    assert POLICY.battery_critical < POLICY.battery_low and POLICY.node_timeout_s == 0.6
    assert set(POLICY.rules) == set(EVENTS)  # every event has its rule in the bundled policy
    assert POLICY.core_stall == CoreStallLimits(20.0, 25, 1.5, 3, 10.0)
    assert POLICY.offboard_loss_timeout_s == 0.5
    assert POLICY.rules["offboard_loss"] == Rule(Action.HOLD, 0.0, True, Action.LAND, 5.0)


def test_offboard_loss_holds_then_lands_after_the_condition_cleared():
    """HOLD takes the vehicle out of OFFBOARD (the condition clears at once); LAND still follows 5 s after the HOLD."""
    arbiter = FailsafeArbiter(POLICY)
    loss = {"offboard_loss": "no offboard setpoint for 0.6 s in OFFBOARD"}
    assert arbiter.update(10.0, loss, in_air=True) == Action.HOLD
    assert arbiter.update(10.1, {}, in_air=True) == Action.HOLD  # out of OFFBOARD: no condition, escalation pending
    assert arbiter.update(14.9, {}, in_air=True) == Action.HOLD
    assert arbiter.update(15.0, {}, in_air=True) == Action.LAND
    assert arbiter.reason.startswith("offboard_loss: no offboard setpoint") and "then land" in arbiter.reason
    assert arbiter.update(30.0, {}, in_air=True) == Action.LAND and arbiter.pending is None
    ground = FailsafeArbiter(POLICY)
    assert ground.update(0.0, loss, in_air=False) == Action.NONE  # only in the air
    assert ground.update(60.0, {}, in_air=False) == Action.NONE


def test_what_cancels_a_pending_escalation():
    loss = {"offboard_loss": "x"}
    disarmed = FailsafeArbiter(POLICY)
    disarmed.update(0.0, loss, True)
    disarmed.reset()  # disarm
    assert disarmed.update(6.0, {}, False) == Action.NONE
    taken_over = FailsafeArbiter(POLICY)
    taken_over.update(0.0, loss, True)
    assert not taken_over.clear("battery_low") and taken_over.action == Action.HOLD  # another cause: stays
    assert taken_over.clear("offboard_loss")  # OFFBOARD re-entered with a live stream
    assert taken_over.update(6.0, {}, True) == Action.NONE
    assert taken_over.update(7.0, loss, True) == Action.HOLD  # a second loss is handled again
    assert taken_over.update(12.0, {}, True) == Action.LAND
    severe = FailsafeArbiter(POLICY)
    severe.update(0.0, loss, True)
    assert severe.update(1.0, {"core_stall_repeated": "3 stalls"}, True) == Action.LAND
    assert severe.reason == "core_stall_repeated: 3 stalls" and severe.pending is None
    assert not severe.clear("offboard_loss") and severe.update(9.0, {}, True) == Action.LAND


def test_escalation_to_rtl_is_configurable():
    policy = FailsafePolicy.from_dict({"events": {"offboard_loss": {"action": "hold", "then": "rtl", "then_after_s": 2}},
                                       "offboard_loss_timeout_s": 1.5})
    assert policy.offboard_loss_timeout_s == 1.5
    arbiter = FailsafeArbiter(policy)
    assert arbiter.update(0.0, {"offboard_loss": "x"}, True) == Action.HOLD
    assert arbiter.update(2.0, {}, True) == Action.RTL
    direct = FailsafeArbiter(FailsafePolicy.from_dict({"events": {"offboard_loss": {"action": "rtl"}}}))
    assert direct.update(0.0, {"offboard_loss": "x"}, True) == Action.RTL and direct.pending is None


def test_a_dead_node_waits_for_its_restart_and_a_stalled_one_only_warns():
    """node_dead lands only after 8 s (restart back-off + start-up); a node back before then clears it."""
    arbiter = FailsafeArbiter(POLICY)
    assert arbiter.update(0.0, {"node_dead": "mission"}, in_air=True) == Action.NONE
    assert arbiter.update(5.0, {"node_dead": "mission"}, in_air=True) == Action.NONE  # restarting
    assert arbiter.update(5.1, {}, in_air=True) == Action.NONE  # back: cleared
    assert arbiter.update(6.0, {"node_dead": "mission"}, in_air=True) == Action.NONE  # the delay starts again
    assert arbiter.update(13.9, {"node_dead": "mission"}, in_air=True) == Action.NONE
    assert arbiter.update(14.0, {"node_dead": "mission"}, in_air=True) == Action.LAND
    stalled = FailsafeArbiter(POLICY)
    assert stalled.update(0.0, {"node_stalled": "mission"}, in_air=False) == Action.WARN  # reported on the ground too
    assert stalled.update(60.0, {"node_stalled": "mission"}, in_air=True) == Action.WARN  # never more than a warning


def test_one_core_stall_warns_repeated_stalls_land_in_the_air():
    arbiter = FailsafeArbiter(POLICY)
    assert arbiter.update(0.0, {"core_stall": "worst tick 25 ms, 3 skipped ticks"}, in_air=True) == Action.WARN
    assert arbiter.update(1.0, {}, in_air=True) == Action.WARN  # latched warning, no landing
    ground = FailsafeArbiter(POLICY)
    assert ground.update(0.0, {"core_stall": "x", "core_stall_repeated": "3 stalls within 10 s"}, in_air=False) == Action.WARN
    assert ground.update(0.1, {"core_stall_repeated": "3 stalls within 10 s"}, in_air=True) == Action.LAND
    assert ground.reason == "core_stall_repeated: 3 stalls within 10 s"


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
    ({"events": {}, "core_stall_ms": 0}, "core_stall_ms must be a number > 0"),
    ({"events": {}, "core_stall_skipped_ticks": 2.5}, "core_stall_skipped_ticks must be an integer > 0"),
    ({"events": {}, "core_stall_repeat_count": True}, "core_stall_repeat_count must be an integer > 0"),
    ({"events": {}, "core_stats_timeout_s": "soon"}, "core_stats_timeout_s must be a number > 0"),
    ({"events": {}, "offboard_loss_timeout_s": 0}, "offboard_loss_timeout_s must be a number > 0"),
    ({"events": {}, "offboard_loss_timeout_s": "0.5"}, "offboard_loss_timeout_s must be a number > 0"),
    ({"events": {"offboard_loss": {"action": "hold", "then": "fly"}}}, r"events.offboard_loss.then must be one of"),
    ({"events": {"offboard_loss": {"action": "land", "then": "hold"}}}, "then must be more severe than its action"),
    ({"events": {"offboard_loss": {"action": "hold", "then": "land", "then_after_s": -1}}}, "then_after_s must be"),
    ({"events": {"offboard_loss": {"action": "hold", "then_after_s": 3}}}, "with a 'then' action"),
    ({"events": {"offboard_loss": {"action": "hold", "thne": "land"}}}, r"events.offboard_loss: unknown field\(s\) thne"),
    ({"events": {"offboard_loss": "hold"}}, "events.offboard_loss must be a mapping"),
])
def test_bad_policy_names_the_field(doc, message):
    with pytest.raises(PolicyError, match=message):
        FailsafePolicy.from_dict(doc)


def test_core_stall_limits_default_and_partial():
    assert FailsafePolicy.from_dict({"events": {}}).core_stall == CoreStallLimits()
    limits = FailsafePolicy.from_dict({"events": {}, "core_stall_ms": 50, "core_stall_repeat_count": 5}).core_stall
    assert (limits.worst_tick_ms, limits.repeat_count, limits.skipped_ticks) == (50.0, 5, 25)
    assert isinstance(limits.worst_tick_ms, float)


def test_obstacle_rules_and_thresholds():
    assert (POLICY.obstacle_detection_range_m, POLICY.obstacle_protection_radius_m) == (2.0, 0.5)
    assert POLICY.rules["obstacle_near"] == Rule(Action.WARN, 0.0, True)
    assert POLICY.rules["obstacle_collision_risk"] == Rule(Action.HOLD, 0.0, True, Action.LAND, 5.0)
    arbiter = FailsafeArbiter(POLICY)
    assert arbiter.update(0.0, {"obstacle_collision_risk": "0.3 m"}, in_air=True) == Action.HOLD
    assert arbiter.update(1.0, {}, in_air=True) == Action.HOLD  # the vehicle stopped: still lands
    assert arbiter.update(5.0, {}, in_air=True) == Action.LAND
    for bad in ({"obstacle_protection_radius_m": 2.0}, {"obstacle_detection_range_m": 0.4},
                {"obstacle_protection_radius_m": 0}, {"obstacle_detection_range_m": True}):
        with pytest.raises(PolicyError, match="0 < obstacle_protection_radius_m < obstacle_detection_range_m"):
            FailsafePolicy.from_dict({"events": {}, **bad})


def test_gnss_integrity_rules_hold_then_land_without_an_alternative_and_warn_with_one():
    assert POLICY.rules["gnss_spoofed"] == Rule(Action.HOLD, 1.0, True, Action.LAND, 1.0)
    assert POLICY.rules["gnss_jammed"] == Rule(Action.HOLD, 2.0, True, Action.LAND, 10.0)
    assert POLICY.rules["gnss_spoofed_switched"].action == POLICY.rules["gnss_jammed_switched"].action == Action.WARN
    arbiter = FailsafeArbiter(POLICY)
    spoofed = {"gnss_spoofed": "GNSS spoofed (inertial, score 1.3); no other healthy horizontal source (on GNSS)"}
    assert arbiter.update(10.0, spoofed, in_air=True) == Action.NONE  # the status may precede the switch
    assert arbiter.update(10.9, spoofed, in_air=True) == Action.NONE
    assert arbiter.update(11.0, spoofed, in_air=True) == Action.HOLD
    assert arbiter.update(11.9, spoofed, in_air=True) == Action.HOLD
    assert arbiter.update(12.0, {}, in_air=True) == Action.LAND  # lands even if the verdict cleared meanwhile
    switched = FailsafeArbiter(POLICY)
    # the verdict comes first, the switch 0.5 s later: only a warning is latched
    assert switched.update(0.0, spoofed, in_air=True) == Action.NONE
    assert switched.update(0.5, {"gnss_spoofed_switched": "x"}, in_air=True) == Action.WARN
    assert switched.update(60.0, {"gnss_spoofed_switched": "x"}, in_air=True) == Action.WARN
