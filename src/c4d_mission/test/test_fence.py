"""The fence in force without ROS: which fence is active after plans and geofence/set, the
refusals, the leg a new fence blocks (mission paused + HOLD), go-to checks against the active
fence, and the journal round trip that lets a restarted node republish it."""

from __future__ import annotations

import math

from c4d_common.geodesy import GeoOrigin
from c4d_common.plan import Geofence, Item, Plan
from c4d_common.plan_validation import IssueKind
from c4d_common.vehicle import Command, CommandResult, Landed, MissionAction, MissionStatus, Nav, VehicleCommandId
from c4d_mission.arbitration import CommandArbiter, VehicleView, goto_target
from c4d_mission.executor import Checkpoint, Vehicle
from c4d_mission.fence import ActiveFence, FenceSource, leg_blocked, refusal
from c4d_mission.mission_journal import JournalEntry, MissionJournal

HOME = GeoOrigin(43.5629, 1.4815, 146.0)


def geo(east: float, north: float) -> tuple[float, float]:
    lat, lon, _ = HOME.to_geodetic(east, north, 0.0)
    return (lat, lon)


def box(e0: float, e1: float, n0: float, n1: float) -> tuple[tuple[float, float], ...]:
    return tuple(geo(e, n) for e, n in ((e0, n0), (e1, n0), (e1, n1), (e0, n1)))


WALL = Geofence(exclusion_polygons=(box(20.0, 25.0, -10.0, 10.0),))  # across the east leg at 20..25 m
PLAN_FENCE = Geofence(box(-60.0, 60.0, -60.0, 60.0), 30.0)
EAST = Plan((Item("takeoff", z=5.0), Item("waypoint", x=40.0, y=0.0, z=5.0), Item("land")))


def flying(position=(0.0, 0.0, 5.0)) -> VehicleView:
    return VehicleView(HOME, True, Landed.IN_AIR, position)


def test_which_fence_is_in_force():
    active = ActiveFence()
    assert active.source is FenceSource.NONE and active.fence.empty
    with_fence = Plan(EAST.items, PLAN_FENCE)
    assert active.for_plan(with_fence) is with_fence
    active.plan_accepted(with_fence)
    assert (active.fence, active.source, active.revision) == (PLAN_FENCE, FenceSource.PLAN, 1)
    active.set(WALL)
    assert (active.fence, active.source) == (WALL, FenceSource.SET)
    inherited = active.for_plan(EAST)  # no fence of its own: flies under the set one
    assert inherited.geofence == WALL
    active.plan_accepted(inherited)
    assert active.source is FenceSource.SET and active.revision == 2  # unchanged
    active.plan_accepted(with_fence)  # a plan with its own fence replaces the set one
    assert (active.fence, active.source) == (PLAN_FENCE, FenceSource.PLAN)
    active.plan_accepted(EAST)  # a plan without a fence after a plan's fence: no fence
    assert active.fence.empty and active.for_plan(EAST) is EAST
    active.set(Geofence())  # a cleared fence is a set one: plans without a fence keep none
    assert active.fence.empty and active.source is FenceSource.SET


def test_refused_when_the_vehicle_is_outside_unless_forced():
    around_me = Geofence(exclusion_circles=((*geo(0.0, 0.0), 5.0),))
    text = refusal(around_me, False, HOME, (1.0, 0.0, 5.0), True)
    assert text.startswith("the vehicle is outside the new fence (inside exclusion circle 0") and "force" in text
    assert refusal(around_me, True, HOME, (1.0, 0.0, 5.0), True) == ""
    assert refusal(around_me, False, HOME, (10.0, 0.0, 5.0), True) == ""
    assert refusal(around_me, False, None, (1.0, 0.0, 5.0), False) == ""  # no home: nothing to judge
    floor = Geofence(min_altitude=3.0)
    assert refusal(floor, False, HOME, (0.0, 0.0, 0.0), False) == ""  # on the ground: the floor does not apply
    assert "floor" in refusal(floor, False, HOME, (0.0, 0.0, 2.0), True)
    assert refusal(Geofence(), False, HOME, (1.0, 0.0, 5.0), True) == ""  # clearing is always allowed


def test_leg_blocked_reasons():
    assert leg_blocked(WALL, HOME, (0.0, 0.0, 5.0), (40.0, 0.0, 5.0)) == "enters the geofence's exclusion polygon 0"
    assert leg_blocked(WALL, HOME, (0.0, 0.0, 5.0), (0.0, 40.0, 5.0)) == ""
    assert leg_blocked(PLAN_FENCE, HOME, (0.0, 0.0, 5.0), (80.0, 0.0, 5.0)) == "leaves the geofence polygon"
    assert "beyond" in leg_blocked(Geofence(max_distance=30.0), HOME, (0.0, 0.0, 5.0), (40.0, 0.0, 5.0))
    assert leg_blocked(Geofence(), HOME, (0.0, 0.0, 5.0), (400.0, 0.0, 5.0)) == ""


def started(arbiter: CommandArbiter, plan: Plan = EAST) -> Vehicle:
    assert arbiter.accept(plan, HOME, 3600.0).plan is not None
    assert arbiter.control(MissionAction.START).result == CommandResult.ACCEPTED
    vehicle = Vehicle((0.0, 0.0, 5.0), True, True, int(Nav.GOTO))
    out = arbiter.step(0.0, 0.02, vehicle)[0][1]  # take-off item: already flying, next; the east leg starts
    out = arbiter.step(0.02, 0.02, vehicle)[0][1]
    assert out.requests == [(Command.GOTO, 0.0)] and arbiter.mission.leg is not None
    return vehicle


def test_a_fence_set_across_the_leg_being_flown_pauses_the_mission_and_holds():
    arbiter = CommandArbiter()
    vehicle = started(arbiter)
    decision = arbiter.set_geofence(WALL, False, flying())
    assert decision.result == CommandResult.ACCEPTED and decision.core == (Command.HOLD,)
    assert decision.message == "fence in force; mission paused: the leg to item 2 enters the geofence's exclusion polygon 0"
    assert arbiter.mission.status == MissionStatus.PAUSED and arbiter.fence.fence == WALL
    assert arbiter.notices == ["mission paused: the leg to item 2 enters the geofence's exclusion polygon 0"]
    (_, out), _ = arbiter.step(0.04, 0.02, vehicle)
    assert out.setpoint is None  # nothing streamed: the core holds
    # resuming flies a fresh leg to the same item: blocked again, paused again before a setpoint goes out
    assert arbiter.control(MissionAction.RESUME).result == CommandResult.ACCEPTED
    (_, out), _ = arbiter.step(0.06, 0.02, vehicle)
    assert out.requests == [(Command.GOTO, 0.0), (Command.HOLD, 0.0)] and out.setpoint is None
    assert arbiter.mission.status == MissionStatus.PAUSED
    # clearing the fence lets the mission go on
    assert arbiter.set_geofence(Geofence(), False, flying()).message == "fence cleared"
    arbiter.control(MissionAction.RESUME)
    (_, out), _ = arbiter.step(0.08, 0.02, vehicle)
    assert out.requests == [(Command.GOTO, 0.0)] and out.setpoint is not None


def test_a_fence_off_the_leg_changes_nothing_and_a_later_blocked_leg_stops_there():
    arbiter = CommandArbiter()
    north_then_east = Plan((Item("takeoff", z=5.0), Item("waypoint", x=0.0, y=30.0, z=5.0),
                            Item("waypoint", x=40.0, y=30.0, z=5.0), Item("land")))
    vehicle = started(arbiter, north_then_east)
    wall = Geofence(exclusion_polygons=(box(20.0, 25.0, 20.0, 40.0),))  # across the second leg only
    decision = arbiter.set_geofence(wall, False, flying())
    assert decision.result == CommandResult.ACCEPTED and decision.core == () and decision.message == "fence in force"
    vehicle.position = (0.0, 30.0, 5.0)
    t, outs = 0.04, []
    while arbiter.mission.status == MissionStatus.ACTIVE and t < 60.0:
        outs.append(arbiter.step(t, 0.02, vehicle)[0][1])
        t += 0.02
    assert arbiter.mission.status == MissionStatus.PAUSED and arbiter.mission.current == 2
    assert outs[-1].requests == [(Command.GOTO, 0.0), (Command.HOLD, 0.0)]
    assert arbiter.notices[-1] == "mission paused: the leg to item 3 enters the geofence's exclusion polygon 0"


def test_set_refusals_change_nothing():
    arbiter = CommandArbiter()
    started(arbiter)
    around_me = Geofence(exclusion_circles=((*geo(0.0, 0.0), 5.0),))
    decision = arbiter.set_geofence(around_me, False, flying())
    assert decision.result == CommandResult.DENIED and "outside the new fence" in decision.message
    assert arbiter.fence.fence.empty and arbiter.mission.status == MissionStatus.ACTIVE
    assert arbiter.set_geofence(around_me, True, flying()).result == CommandResult.ACCEPTED  # forced


def test_goto_and_plans_are_checked_against_the_active_fence():
    arbiter = CommandArbiter()
    assert arbiter.set_geofence(WALL, False, VehicleView(HOME, False, Landed.ON_GROUND, (0.0, 0.0, 0.0))).result == 0
    refused = arbiter.accept(EAST, HOME, 3600.0)  # no fence of its own: validated against the set one
    assert refused.plan is None and [i.kind for i in refused.errors] == [IssueKind.ENTERS_EXCLUSION]
    north = Plan((Item("takeoff", z=5.0), Item("waypoint", x=0.0, y=40.0, z=5.0), Item("land")))
    accepted = arbiter.accept(north, HOME, 3600.0)
    assert accepted.plan is not None and accepted.plan.geofence == WALL  # carries the fence it flies under
    lat, lon = geo(40.0, 0.0)
    goto = arbiter.command(VehicleCommandId.GOTO, flying(), False, goto_target(lat, lon, 5.0, math.nan))
    assert goto.result == CommandResult.DENIED and "exclusion polygon 0" in goto.message


def test_the_journal_keeps_the_fence_in_force(tmp_path):
    journal = MissionJournal(tmp_path / "state.json")
    fence = Geofence(box(-60, 60, -60, 60), 30.0, 100.0, (box(20, 25, -10, 10),), ((*geo(0, 30), 4.0),), 3.0)
    checkpoint = Checkpoint(1, MissionStatus.READY, 0, -1, 5.0, "start")
    journal.save(JournalEntry(Plan(EAST.items, fence, plan_id=1), checkpoint, (fence, FenceSource.SET)))
    loaded = journal.load()
    assert loaded.fence == (fence, FenceSource.SET)
    assert loaded.plan.geofence == fence  # exclusions and floor survive in the plan too
    journal.save(JournalEntry(None, Checkpoint(0, MissionStatus.NO_PLAN, 0, -1, 5.0, "start")))
    assert journal.load().fence is None


def test_a_forced_goto_and_an_rtl_are_never_stopped_by_the_fence():
    """test_failsafes_in_flight: a go-to forced 25 m out with a 15 m fence must fly (health's breach
    → RTL is what it tests), and that RTL back from outside must not be cancelled either."""
    arbiter = CommandArbiter()
    short = Plan((Item("takeoff", z=5.0), Item("land")), Geofence(max_distance=15.0))
    assert arbiter.accept(short, HOME, 3600.0).plan is not None
    lat, lon = geo(25.0, 0.0)
    vehicle = Vehicle((0.0, 0.0, 5.0), True, True, int(Nav.HOLD))
    forced = arbiter.command(VehicleCommandId.GOTO, flying(), True, goto_target(lat, lon, 5.0, math.nan))
    assert forced.result == CommandResult.ACCEPTED and "forced" in forced.message
    _, (_, out) = arbiter.step(0.0, 0.02, vehicle)
    assert out.requests == [(Command.GOTO, 0.0)] and out.setpoint is not None and arbiter.detour.status == MissionStatus.ACTIVE
    outside = VehicleView(HOME, True, Landed.IN_AIR, (20.0, 0.0, 5.0))
    assert arbiter.command(VehicleCommandId.RETURN_TO_LAUNCH, outside).result == CommandResult.ACCEPTED
    vehicle.position = (20.0, 0.0, 5.0)
    _, (_, out) = arbiter.step(0.02, 0.02, vehicle)
    assert out.requests == [(Command.RETURN_TO_LAUNCH, 0.0)] and arbiter.detour.status == MissionStatus.ACTIVE
    assert arbiter.notices == []


def test_legs_from_outside_a_forced_fence_are_judged_by_what_they_make_worse():
    around = Geofence(exclusion_circles=((*geo(0.0, 0.0), 5.0),))
    assert leg_blocked(around, HOME, (1.0, 0.0, 5.0), (30.0, 0.0, 5.0)) == ""  # out of the zone it is in
    assert leg_blocked(PLAN_FENCE, HOME, (80.0, 0.0, 5.0), (0.0, 0.0, 5.0)) == ""  # back into the polygon
    far = Geofence(max_distance=30.0)
    assert leg_blocked(far, HOME, (40.0, 0.0, 5.0), (35.0, 0.0, 5.0)) == ""  # closer to home
    assert "beyond" in leg_blocked(far, HOME, (40.0, 0.0, 5.0), (45.0, 0.0, 5.0))  # further out


def test_an_rtl_pushed_back_by_the_barrier_still_returns():
    """test_failsafes_in_flight: an RTL from 14 m out with an 8 m fence climbed where the barrier
    held the vehicle (7 m out) and waited for ever for the climb's start point; the climb is judged
    by its altitude."""
    arbiter = CommandArbiter()
    vehicle = Vehicle((14.0, 0.0, 5.0), True, True, int(Nav.HOLD))
    assert arbiter.command(VehicleCommandId.RETURN_TO_LAUNCH, flying((14.0, 0.0, 5.0))).result == CommandResult.ACCEPTED
    requests, t = [], 0.0
    while t < 10.0 and len(requests) < 2:
        requests += arbiter.step(t, 0.02, vehicle)[1][1].requests
        vehicle.position = (7.0, 0.0, min(15.0, vehicle.position[2] + 0.05))  # pushed inside, climbing
        t += 0.02
    assert requests == [(Command.RETURN_TO_LAUNCH, 0.0)] * 2  # the climb, then the leg home
    assert arbiter.detour.leg[1][:2] == (0.0, 0.0)
