"""Failsafe event evaluation without DDS: each event from a HealthSnapshot, and none from wording."""

from dataclasses import replace
from pathlib import Path

import pytest

from c4d_common.geodesy import GeoOrigin
from c4d_common.geofence import BreachKind, LocalFence
from c4d_common.plan import Geofence
from c4d_health.core_stall import CoreStallReport
from c4d_health.events import (
    GNSS_JAMMED,
    GNSS_SPOOFED,
    LINK_TIMEOUT_S,
    SOURCE_EXTERNAL,
    SOURCE_GNSS,
    SOURCE_NONE,
    Estimate,
    GnssReport,
    HealthSnapshot,
    LinkWatch,
    NavigationStatus,
    OffboardWatch,
    evaluate,
)
from c4d_health.liveness import LivenessMonitor
from c4d_health.policy import EVENTS, Event, FailsafePolicy

POLICY = FailsafePolicy.from_yaml(Path(__file__).resolve().parents[1] / "config" / "failsafe.yaml")
HOME = GeoOrigin(43.5630, 1.4816, 150.0)
GOOD = Estimate(attitude_valid=True, position_xy_valid=True, position=(0.0, 0.0, 10.0), home=HOME)
HEALTHY = HealthSnapshot(gnss=GnssReport(True, "ok"), estimate=GOOD, battery_soc=0.9, geofence=Geofence(),
                         link=LinkWatch("bridge/gcs_heartbeat", 99.0))
T = 100.0


def square(half_m: float) -> tuple[tuple[float, float], ...]:
    """A square inclusion polygon of ±half_m around HOME, as (lat, lon)."""
    corners = [(-half_m, -half_m), (half_m, -half_m), (half_m, half_m), (-half_m, half_m)]
    return tuple(HOME.to_geodetic(e, n, 0.0)[:2] for e, n in corners)


def events(**changes) -> dict[str, str]:
    return evaluate(replace(HEALTHY, **changes), POLICY, T)


def at(x: float, y: float, z: float = 10.0) -> Estimate:
    return replace(GOOD, position=(x, y, z))


def test_a_healthy_or_empty_snapshot_has_no_event():
    assert evaluate(HEALTHY, POLICY, T) == {}
    assert evaluate(HealthSnapshot(), POLICY, T) == {}  # nothing heard yet: nothing to judge


def test_event_names_are_the_policy_events():
    assert set(EVENTS) == {e.value for e in Event} and set(POLICY.rules) <= set(EVENTS)


def test_dead_nodes():
    assert events(dead_nodes=("mission", "sim")) == {"node_dead": "mission, sim"}


def test_stalled_nodes_are_their_own_event():
    assert events(stalled_nodes=("core",)) == {"node_stalled": "core"}
    assert events(dead_nodes=("mission",), stalled_nodes=("sim",)) == {"node_dead": "mission", "node_stalled": "sim"}


def test_inactive_nodes_are_their_own_event():
    assert events(inactive_nodes=("navigation (inactive)",)) == {"node_inactive": "navigation (inactive)"}
    assert events(dead_nodes=("sim",), inactive_nodes=("core (unconfigured)", "perception (inactive)")) == \
        {"node_dead": "sim", "node_inactive": "core (unconfigured), perception (inactive)"}


def test_core_stall_and_repeated_core_stalls():
    assert events(core_stall=CoreStallReport()) == {}
    assert events(core_stall=CoreStallReport("worst tick 25 ms, 12 skipped ticks")) == \
        {"core_stall": "worst tick 25 ms, 12 skipped ticks"}
    assert events(core_stall=CoreStallReport("", "3 stalls within 10 s")) == {"core_stall_repeated": "3 stalls within 10 s"}


def test_gnss_loss_is_decided_by_the_level_not_the_message():
    assert events(gnss=GnssReport(False, "stale")) == {"gps_loss": "GNSS stale"}
    assert events(gnss=GnssReport(False, "ok")) == {"gps_loss": "GNSS ok"}
    assert events(gnss=GnssReport(True, "stale, no fix, lost")) == {}


@pytest.mark.parametrize("attitude,position", [(False, True), (True, False), (False, False)])
def test_estimator_invalid(attitude, position):
    estimate = replace(GOOD, attitude_valid=attitude, position_xy_valid=position)
    assert events(estimate=estimate) == {"estimator_invalid": "position or attitude estimate not valid"}


def test_battery_low_then_critical_never_both():
    assert events(battery_soc=0.29) == {"battery_low": "29%"}
    assert events(battery_soc=0.14) == {"battery_critical": "14%"}
    assert events(battery_soc=POLICY.battery_low) == {}  # strictly below the threshold
    assert events(battery_soc=float("nan")) == {}  # unknown state of charge
    assert events(battery_soc=None) == {}


def test_geofence_polygon_ceiling_distance():
    fence = Geofence(polygon=square(20.0), max_altitude=30.0, max_distance=25.0)
    assert events(geofence=fence, estimate=at(10.0, -10.0)) == {}
    assert events(geofence=fence, estimate=at(21.0, 0.0)) == {"geofence_breach": "outside the inclusion polygon"}
    assert events(geofence=fence, estimate=at(0.0, 0.0, 31.0)) == {"geofence_breach": "31.0 m above the 30 m ceiling"}
    assert events(geofence=fence, estimate=at(18.0, 18.0)) == {"geofence_breach": "25 m from home (limit 25 m)"}


def test_geofence_is_the_shared_check():
    """The detail is LocalFence.breach's (the one check pre-flight validation uses)."""
    fence = Geofence(max_distance=15.0)
    breach = LocalFence.from_geofence(fence, HOME).breach((20.0, 0.0, 10.0))
    assert breach is not None and breach.kind == BreachKind.DISTANCE
    assert events(geofence=fence, estimate=at(20.0, 0.0)) == {"geofence_breach": breach.text}


def test_no_geofence_event_without_a_fence_or_a_home():
    assert events(geofence=None, estimate=at(1e4, 0.0)) == {}
    assert events(geofence=Geofence(max_distance=15.0), estimate=replace(at(20.0, 0.0), home=None)) == {}


def test_link_loss_after_the_timeout_or_never_heard():
    topic = "bridge/gcs_heartbeat"
    assert events(link=LinkWatch(topic, T - LINK_TIMEOUT_S)) == {}
    lost = {"link_loss": f"no heartbeat on {topic} for 3 s"}
    assert events(link=LinkWatch(topic, T - LINK_TIMEOUT_S - 0.1)) == lost
    assert events(link=LinkWatch(topic, None)) == lost
    assert events(link=None) == {}  # not watched


def test_executor_overrun():
    assert events(new_overruns=2) == {"executor_overrun": "2 new overrun(s)"}


def test_offboard_loss_only_in_offboard_after_the_timeout():
    assert POLICY.offboard_loss_timeout_s == 0.5
    assert events(offboard=OffboardWatch(True, T - 0.5)) == {}
    assert events(offboard=OffboardWatch(True, T - 0.6)) == {"offboard_loss": "no offboard setpoint for 0.6 s in OFFBOARD"}
    assert events(offboard=OffboardWatch(False, T - 60.0)) == {}  # no stream needed outside OFFBOARD
    assert events(offboard=None) == {}  # the core's mode not known yet
    slow = replace(POLICY, offboard_loss_timeout_s=2.0)
    assert evaluate(replace(HEALTHY, offboard=OffboardWatch(True, T - 1.9)), slow, T) == {}


def test_a_stalled_monitor_does_not_see_an_offboard_loss():
    """The stream's silence is counted in the monitor's running time (as node liveness): a 1 s
    stall of the health node itself is nobody's silence; a stream that stopped is still found."""
    stream = LivenessMonitor(("offboard",), POLICY.offboard_loss_timeout_s, 0.1, 0.0)
    for k in range(1, 11):
        stream.heard("offboard", k * 0.1)
        stream.silent(k * 0.1)
    stream.silent(2.0)  # the monitor did not run from 1.0 to 2.0 s; the queued samples are not taken yet
    assert evaluate(replace(HEALTHY, offboard=OffboardWatch(True, stream.last_seen["offboard"])), POLICY, 2.0) == {}
    for t in (2.1, 2.2, 2.3, 2.4, 2.5, 2.6):  # the stream really stopped
        stream.silent(t)
    lost = evaluate(replace(HEALTHY, offboard=OffboardWatch(True, stream.last_seen["offboard"])), POLICY, 2.6)
    assert list(lost) == ["offboard_loss"]


def test_events_come_in_event_order():
    everything = HealthSnapshot(("sim",), GnssReport(False, "lost"), replace(at(99.0, 0.0), attitude_valid=False), 0.1,
                                Geofence(max_distance=15.0), LinkWatch("link", None), 1, ("core",),
                                CoreStallReport("worst tick 30 ms, 14 skipped ticks", "3 stalls within 10 s"),
                                OffboardWatch(True, T - 1.0), True, ((99.3, 0.0, 0.0),),
                                NavigationStatus(SOURCE_GNSS, False, GNSS_SPOOFED), ("navigation (inactive)",))
    exclusive = (Event.BATTERY_LOW, Event.OBSTACLE_NEAR, Event.GNSS_JAMMED, Event.GNSS_SPOOFED_SWITCHED,
                 Event.GNSS_JAMMED_SWITCHED)  # each excluded by another one that is active
    assert list(evaluate(everything, POLICY, T)) == [e for e in Event if e not in exclusive]


def test_exclusion_zones_and_the_floor_of_the_fence_in_force():
    """geofence/active's exclusion polygon / circle is a breach inside it; the floor only while flying
    (take-off and landing pass through it)."""
    wall = tuple(HOME.to_geodetic(e, n, 0.0)[:2] for e, n in ((20, -10), (25, -10), (25, 10), (20, 10)))
    circle = (*HOME.to_geodetic(0.0, 30.0, 0.0)[:2], 4.0)
    fence = Geofence(exclusion_polygons=(wall,), exclusion_circles=(circle,), min_altitude=3.0)
    assert events(geofence=fence, estimate=at(22.0, 0.0)) == {"geofence_breach": "inside exclusion polygon 0"}
    assert events(geofence=fence, estimate=at(19.0, 0.0)) == {}
    assert events(geofence=fence, estimate=at(1.0, 28.0))["geofence_breach"].startswith("inside exclusion circle 0")
    assert events(geofence=fence, estimate=at(0.0, 0.0, 2.0)) == {}  # not flying: taking off or landing
    assert events(geofence=fence, estimate=at(0.0, 0.0, 2.0), flying=True) == {
        "geofence_breach": "2.0 m below the 3 m floor"}


def test_obstacle_near_and_collision_risk_from_the_perceived_obstacles():
    """Distance to the obstacle's surface (its bounding circle) from the estimated position: inside
    2 m obstacle_near (warn), inside 0.5 m obstacle_collision_risk (hold, then land)."""
    post = (5.0, 0.0, 1.0)  # surface at 4 m east
    assert events(obstacles=(post,), estimate=at(1.0, 0.0)) == {}  # 3 m away
    assert events(obstacles=(post,), estimate=at(2.5, 0.0)) == {"obstacle_near": "obstacle 1.5 m away"}
    assert events(obstacles=(post, (0.0, -1.0, 0.2)), estimate=at(3.7, 0.0)) == {
        "obstacle_collision_risk": "obstacle 0.30 m away (protection radius 0.5 m)"}
    assert events(obstacles=(), estimate=at(3.7, 0.0)) == {} and events(obstacles=None, estimate=at(3.7, 0.0)) == {}
    no_fix = replace(at(3.7, 0.0), position_xy_valid=False)  # the estimator's own event covers it
    assert "obstacle_collision_risk" not in events(obstacles=(post,), estimate=no_fix)
    wide = replace(POLICY, obstacle_detection_range_m=5.0)
    assert list(evaluate(replace(HEALTHY, obstacles=(post,), estimate=at(1.0, 0.0)), wide, T)) == ["obstacle_near"]


def test_navigation_constants_are_the_message_constants():
    from c4d_health import events as ev
    from c4d_interfaces.msg import GnssIntegrity, VehicleState
    assert (ev.SOURCE_NONE, ev.SOURCE_GNSS, ev.SOURCE_EXTERNAL) == \
        (VehicleState.SOURCE_NONE, VehicleState.SOURCE_GNSS, VehicleState.SOURCE_EXTERNAL)
    assert (ev.GNSS_SPOOFED, ev.GNSS_JAMMED) == (GnssIntegrity.STATE_SPOOFED, GnssIntegrity.STATE_JAMMED)


ON_GNSS = NavigationStatus(SOURCE_GNSS, external_healthy=False, gnss_state=1)
ON_EXTERNAL = NavigationStatus(SOURCE_EXTERNAL, external_healthy=True, gnss_state=1)


@pytest.mark.parametrize("state,event", [(GNSS_SPOOFED, "gnss_spoofed"), (GNSS_JAMMED, "gnss_jammed")])
def test_gnss_integrity_events_depend_on_a_healthy_other_source(state, event):
    alarm = replace(ON_GNSS, gnss_state=state, gnss_score=2.0, gnss_alarms="inertial")
    assert events(navigation=alarm) == {event: f"GNSS {event[5:]} (inertial, score 2.0); no other healthy horizontal "
                                               "source (on GNSS)"}
    # dead reckoning (the navigation stopped fusing GNSS, nothing else): the same event
    assert set(events(navigation=replace(alarm, horizontal_source=SOURCE_NONE))) == {event}
    # an external source configured but unhealthy is no alternative
    assert set(events(navigation=replace(alarm, horizontal_source=SOURCE_EXTERNAL, external_healthy=False))) == {event}
    switched = replace(alarm, horizontal_source=SOURCE_EXTERNAL, external_healthy=True)
    assert events(navigation=switched) == {f"{event}_switched": f"GNSS {event[5:]} (inertial, score 2.0); "
                                                                "navigation on the external source"}


def test_no_gnss_integrity_event_while_ok_suspect_or_unknown():
    for state in (0, 1, 2):
        assert events(navigation=replace(ON_GNSS, gnss_state=state)) == {}


def test_gps_loss_not_while_a_healthy_non_gnss_source_is_in_use():
    lost = GnssReport(False, "no fix")
    assert events(gnss=lost, navigation=ON_EXTERNAL) == {}  # GNSS disabled from boot + external pose: valid
    assert events(gnss=lost, navigation=ON_GNSS) == {"gps_loss": "GNSS no fix"}
    assert events(gnss=lost, navigation=replace(ON_EXTERNAL, external_healthy=False)) == {"gps_loss": "GNSS no fix"}
    assert events(gnss=lost, navigation=replace(ON_EXTERNAL, horizontal_source=SOURCE_NONE)) == {"gps_loss": "GNSS no fix"}
    assert events(gnss=lost) == {"gps_loss": "GNSS no fix"}  # navigation/status not heard: as before
