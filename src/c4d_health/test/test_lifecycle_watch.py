"""node_inactive without DDS: the lifecycle watcher's rule (unknown is not inactive, transition states
are not ACTIVE, mission only while armed) and the bundled policy's rule for it."""

from pathlib import Path

import pytest

from c4d_health.lifecycle_watch import ACTIVE, INACTIVE, UNCONFIGURED, UNKNOWN, LifecycleWatch, state_name
from c4d_health.policy import Action, Event, FailsafeArbiter, FailsafePolicy

POLICY = FailsafePolicy.from_yaml(Path(__file__).resolve().parents[1] / "config" / "failsafe.yaml")
WATCHED = ("core", "navigation", "perception", "mission", "sim")
ACTIVATING, DEACTIVATING, CLEANINGUP = 13, 14, 11


def test_state_ids_are_lifecycle_msgs_ones():
    state = pytest.importorskip("lifecycle_msgs.msg").State
    assert (UNKNOWN, UNCONFIGURED, INACTIVE, ACTIVE) == (state.PRIMARY_STATE_UNKNOWN, state.PRIMARY_STATE_UNCONFIGURED,
                                                         state.PRIMARY_STATE_INACTIVE, state.PRIMARY_STATE_ACTIVE)
    assert (ACTIVATING, DEACTIVATING, CLEANINGUP) == (state.TRANSITION_STATE_ACTIVATING,
                                                      state.TRANSITION_STATE_DEACTIVATING,
                                                      state.TRANSITION_STATE_CLEANINGUP)
    assert state_name(DEACTIVATING) == "deactivating" and state_name(99) == "state 99"


def test_never_heard_is_unknown_not_inactive():
    watch = LifecycleWatch(WATCHED)
    assert watch.not_active(armed=True) == () and watch.state("core") == UNKNOWN


def test_a_node_that_left_active_is_reported_until_it_is_back():
    watch = LifecycleWatch(WATCHED)
    for goal in (ACTIVATING, ACTIVE):  # heard coming up (health subscribed first)
        watch.on_transition("navigation", goal)
    assert watch.not_active(armed=True) == ()
    watch.on_transition("navigation", DEACTIVATING)
    assert watch.not_active(armed=True) == ("navigation (deactivating)",)
    watch.on_transition("navigation", INACTIVE)
    watch.on_transition("perception", CLEANINGUP)
    watch.on_transition("perception", UNCONFIGURED)
    assert watch.not_active(armed=False) == ("navigation (inactive)", "perception (unconfigured)")
    watch.on_transition("navigation", ACTIVATING)  # on its way back: still not active
    assert watch.not_active(armed=True)[0] == "navigation (activating)"
    watch.on_transition("navigation", ACTIVE)
    assert watch.not_active(armed=True) == ("perception (unconfigured)",)


def test_mission_counts_only_while_armed_and_unwatched_nodes_never():
    """maintenance deactivates mission on the ground on purpose; payload and offboard are not watched."""
    watch = LifecycleWatch(("core", "mission"))
    watch.on_transition("mission", INACTIVE)
    watch.on_transition("payload", INACTIVE)
    watch.on_transition("offboard", INACTIVE)
    assert watch.not_active(armed=False) == ()
    assert watch.not_active(armed=True) == ("mission (inactive)",)


def test_bundled_rule_lands_after_3_s_in_the_air_and_only_reports_on_the_ground():
    event = {Event.NODE_INACTIVE: "navigation (inactive)"}
    ground = FailsafeArbiter(POLICY)
    assert ground.update(0.0, event, in_air=False) == Action.NONE
    assert ground.update(60.0, event, in_air=False) == Action.NONE
    air = FailsafeArbiter(POLICY)
    assert air.update(0.0, event, in_air=True) == Action.NONE
    assert air.update(2.9, event, in_air=True) == Action.NONE  # the lifecycle manager re-activates within 2 s
    assert air.update(3.0, event, in_air=True) == Action.LAND
    back = FailsafeArbiter(POLICY)
    assert back.update(0.0, event, in_air=True) == Action.NONE
    assert back.update(2.5, {}, in_air=True) == Action.NONE  # re-activated in time: nothing
    assert back.update(5.0, event, in_air=True) == Action.NONE  # the delay starts again
