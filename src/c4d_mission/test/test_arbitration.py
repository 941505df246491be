"""Command arbitration without ROS: mission / RTL / go-to / hold / set mode, and the race fixes."""

import math
from pathlib import Path

from c4d_common.geodesy import GeoOrigin
from c4d_common.plan import Item, Plan
from c4d_common.plan_files import load_plan
from c4d_common.plan_validation import IssueKind
from c4d_common.vehicle import Command, CommandResult, Landed, MissionAction, MissionStatus, Nav, VehicleCommandId
from c4d_mission.arbitration import CommandArbiter, VehicleView, goto_target
from c4d_mission.executor import Vehicle

ROOT = Path(__file__).resolve().parents[3]
HOME = GeoOrigin(43.5629, 1.4815, 146.0)
FLYING = VehicleView(HOME, True, Landed.IN_AIR, (0.0, 0.0, 8.0))
GROUNDED = VehicleView(HOME, False, Landed.ON_GROUND, (0.0, 0.0, 0.0))


def survey_arbiter() -> CommandArbiter:
    arbiter = CommandArbiter()
    verdict = arbiter.accept(load_plan(ROOT / "missions" / "survey.yaml"), HOME, 3600.0)
    assert verdict.plan is not None and verdict.plan.plan_id == 1 and not verdict.errors
    return arbiter


def target(east, north, alt):
    lat, lon, _ = HOME.to_geodetic(east, north, 0.0)
    return goto_target(lat, lon, alt, math.nan)


def test_plan_acceptance_needs_home_and_no_active_mission():
    arbiter = CommandArbiter()
    plan = load_plan(ROOT / "missions" / "survey.yaml")
    assert [i.kind for i in arbiter.accept(plan, None, None).errors] == [IssueKind.NO_HOME]
    assert arbiter.accept(plan, HOME, 3600.0).plan.plan_id == 1
    assert arbiter.control(MissionAction.START).result == CommandResult.ACCEPTED
    refused = arbiter.accept(plan, HOME, 3600.0)
    assert refused.plan is None and [str(e) for e in refused.errors] == ["plan: a mission is active (pause or land first)"]
    assert refused.errors[0].kind == IssueKind.MISSION_ACTIVE


def test_a_plan_is_never_accepted_unvalidated_battery_unknown_is_a_typed_retry():
    """Issue 14.1: without a battery report the endurance was skipped and a 50 km plan flew."""
    from c4d_common.plan import plan_from_yaml_text
    from c4d_common.plan_validation import flight_time_left
    from c4d_common.vehicle import UploadRefusal

    far = plan_from_yaml_text("name: far\nitems:\n  - {type: takeoff, altitude: 10}\n"
                              "  - {type: waypoint, east: 50000, north: 0, alt: 10}\n  - {type: land}\n")
    arbiter = CommandArbiter()
    unknown = arbiter.accept(far, HOME, None)
    assert unknown.plan is None and [i.kind for i in unknown.errors] == [IssueKind.BATTERY_UNKNOWN]
    assert unknown.refusal == UploadRefusal.BATTERY_UNKNOWN and unknown.refusal.retry
    assert arbiter.accept(far, None, None).refusal == UploadRefusal.NO_HOME
    full = arbiter.accept(far, HOME, flight_time_left(5.0, 20.0))  # the SITL pack at full charge: 720 s
    assert full.plan is None and IssueKind.ENDURANCE in {i.kind for i in full.errors}
    assert full.refusal == UploadRefusal.INVALID and not full.refusal.retry
    assert arbiter.accept(load_plan(ROOT / "missions" / "hop.yaml"), HOME, 0.0).refusal == UploadRefusal.INVALID  # empty
    accepted = arbiter.accept(load_plan(ROOT / "missions" / "hop.yaml"), HOME, flight_time_left(5.0, 20.0))
    assert accepted.refusal == UploadRefusal.NONE and arbiter.mission.status == MissionStatus.READY


def test_mission_control_results_and_the_hold_on_pause():
    arbiter = survey_arbiter()
    assert arbiter.control(99).result == CommandResult.UNSUPPORTED
    assert arbiter.control(MissionAction.PAUSE).message == "mission is not active"
    assert arbiter.control(MissionAction.START).result == CommandResult.ACCEPTED
    assert arbiter.control(MissionAction.CLEAR).message == "mission is active (pause it first)"
    paused = arbiter.control(MissionAction.PAUSE)
    assert paused.result == CommandResult.ACCEPTED and paused.message == "accepted" and paused.core == (Command.HOLD,)
    assert arbiter.control(MissionAction.SET_CURRENT, 99).message == "item 99 does not exist"
    assert arbiter.control(MissionAction.SET_CURRENT, 3).result == CommandResult.ACCEPTED and arbiter.mission.current == 3
    assert arbiter.control(MissionAction.CLEAR).result == CommandResult.ACCEPTED and arbiter.mission.plan is None


def test_rtl_aborts_the_mission_and_needs_an_armed_vehicle_with_home():
    arbiter = survey_arbiter()
    arbiter.control(MissionAction.START)
    denied = arbiter.command(VehicleCommandId.RETURN_TO_LAUNCH, GROUNDED)
    assert denied.result == CommandResult.DENIED and denied.message == "RTL needs an armed vehicle with a home position"
    rtl = arbiter.command(VehicleCommandId.RETURN_TO_LAUNCH, FLYING)
    assert rtl.result == CommandResult.ACCEPTED and rtl.message == "returning to launch" and not rtl.forward
    assert arbiter.mission.status == MissionStatus.ABORTED and arbiter.detour.status == MissionStatus.ACTIVE
    assert arbiter.detour.plan.rtl_altitude == arbiter.mission.plan.rtl_altitude


def test_goto_pauses_the_mission_and_resume_takes_over_again():
    arbiter = survey_arbiter()
    arbiter.control(MissionAction.START)
    assert arbiter.command(VehicleCommandId.GOTO, GROUNDED, target=target(10, 10, 8)).message == \
        "go-to needs a flying vehicle (take off first)"
    going = arbiter.command(VehicleCommandId.GOTO, FLYING, target=target(10, 10, 8))
    assert going.result == CommandResult.ACCEPTED and going.message == "going to the target"
    assert arbiter.mission.status == MissionStatus.PAUSED and arbiter.detour.status == MissionStatus.ACTIVE
    assert arbiter.detour.plan.items[0].hold == math.inf
    assert arbiter.control(MissionAction.RESUME).result == CommandResult.ACCEPTED
    assert arbiter.mission.status == MissionStatus.ACTIVE and arbiter.detour.status == MissionStatus.NO_PLAN


def test_goto_outside_the_fence_only_when_forced_and_never_a_malformed_target():
    arbiter = survey_arbiter()
    refused = arbiter.command(VehicleCommandId.GOTO, FLYING, target=target(200, 0, 8))
    assert refused.result == CommandResult.DENIED and "leaves the geofence polygon" in refused.message
    forced = arbiter.command(VehicleCommandId.GOTO, FLYING, force=True, target=target(200, 0, 8))
    assert forced.result == CommandResult.ACCEPTED and forced.message.startswith("going to the target (forced: ")
    malformed = goto_target(95.0, 1.0, 8.0, math.nan)
    refused = arbiter.command(VehicleCommandId.GOTO, FLYING, force=True, target=malformed)
    assert refused.result == CommandResult.DENIED and refused.message == "go-to target latitude/longitude out of range"


def test_hold_land_disarm_and_mode_changes_take_the_vehicle_from_the_plan():
    arbiter = survey_arbiter()
    arbiter.control(MissionAction.START)
    arbiter.command(VehicleCommandId.RETURN_TO_LAUNCH, FLYING)
    arbiter.control(MissionAction.START)  # the plan again: the RTL is cancelled
    assert arbiter.detour.status == MissionStatus.NO_PLAN
    hold = arbiter.command(VehicleCommandId.HOLD, FLYING)
    assert hold.forward and arbiter.mission.status == MissionStatus.ACTIVE  # the core decides first
    arbiter.core_replied(VehicleCommandId.HOLD, CommandResult.ACCEPTED)
    assert arbiter.mission.status == MissionStatus.PAUSED
    arbiter.control(MissionAction.RESUME)
    arbiter.command(VehicleCommandId.GOTO, FLYING, target=target(10, 10, 8))
    assert arbiter.command(VehicleCommandId.LAND, FLYING).forward
    arbiter.core_replied(VehicleCommandId.LAND, CommandResult.ACCEPTED)
    assert arbiter.mission.status == MissionStatus.ABORTED and arbiter.detour.status == MissionStatus.NO_PLAN

    arbiter = survey_arbiter()
    arbiter.control(MissionAction.START)
    assert arbiter.command(VehicleCommandId.SET_MODE, FLYING).forward
    arbiter.core_replied(VehicleCommandId.SET_MODE, CommandResult.DENIED)
    assert arbiter.mission.status == MissionStatus.ACTIVE  # refused by the core: nothing changes
    arbiter.core_replied(VehicleCommandId.SET_MODE, CommandResult.ACCEPTED)
    assert arbiter.mission.status == MissionStatus.PAUSED
    assert arbiter.command(VehicleCommandId.ARM, GROUNDED).forward


def test_a_plan_ending_in_the_air_holds_then_an_rtl_at_once_still_asks_to_follow():
    """The MAVSDK CI race: the plan's final HOLD is sent in the step that completes it; an RTL
    commanded right after, on a status that still says GOTO, must ask the core to follow again
    (as RETURN_TO_LAUNCH, so that the status reports RTL: issue 14.11)."""
    arbiter = CommandArbiter()
    plan = Plan((Item("takeoff", z=5.0), Item("waypoint", x=0.0, y=0.0, z=5.0)))
    assert arbiter.accept(plan, HOME, 3600.0).plan is not None
    arbiter.control(MissionAction.START)
    stale = Vehicle((0.0, 0.0, 5.0), True, True, int(Nav.GOTO))
    t = 0.0
    while arbiter.mission.status == MissionStatus.ACTIVE and t < 1.0:
        steps = arbiter.step(t, 0.02, stale)
        assert [runner for runner, _ in steps] == [arbiter.mission, arbiter.detour]  # the mission first, every tick
        t += 0.02
    assert steps[0][1].requests[-1] == (Command.HOLD, 0.0) and arbiter.mission.status == MissionStatus.COMPLETED
    assert arbiter.command(VehicleCommandId.RETURN_TO_LAUNCH, FLYING).result == CommandResult.ACCEPTED
    (_, mission_out), (_, detour_out) = arbiter.step(t, 0.02, stale)
    assert mission_out.requests == [] and detour_out.requests == [(Command.RETURN_TO_LAUNCH, 0.0)]


def test_a_refused_disarm_in_the_air_changes_nothing_and_the_plan_waits_for_the_answer():
    """Issue 14: DISARM in flight is DENIED by the core; the mission used to be aborted before the
    command was forwarded (ABORTED, the vehicle flew back to where its leg started)."""
    arbiter = survey_arbiter()
    arbiter.control(MissionAction.START)
    flying = Vehicle((0.0, 0.0, 8.0), True, True, int(Nav.GOTO))
    t = 0.0
    for _ in range(200):  # past the take-off item, on the first leg
        arbiter.step(t, 0.02, flying)
        t += 0.02
    current, leg = arbiter.mission.current, arbiter.mission._tracker
    assert current >= 1 and leg is not None
    disarm = arbiter.command(VehicleCommandId.DISARM, FLYING)
    assert disarm.forward and arbiter.mission.status == MissionStatus.ACTIVE
    # while the core decides, neither executor runs: no new-leg GOTO can overtake the command
    assert all(out.requests == [] and out.setpoint is None for _, out in arbiter.step(t, 0.02, flying))
    arbiter.core_replied(VehicleCommandId.DISARM, CommandResult.DENIED)
    assert arbiter.mission.status == MissionStatus.ACTIVE and arbiter.mission.current == current
    (_, out), _ = arbiter.step(t + 0.02, 0.02, flying)
    assert out.setpoint is not None and arbiter.mission._tracker is leg  # the same leg goes on
    # accepted (forced on the ground or in the air): the plan ends
    arbiter.command(VehicleCommandId.DISARM, FLYING, force=True)
    arbiter.core_replied(VehicleCommandId.DISARM, CommandResult.ACCEPTED)
    assert arbiter.mission.status == MissionStatus.ABORTED


def test_a_lost_core_answer_freezes_the_plan_only_briefly():
    arbiter = survey_arbiter()
    arbiter.control(MissionAction.START)
    grounded = Vehicle((0.0, 0.0, 0.0), True, False, int(Nav.HOLD))
    arbiter.command(VehicleCommandId.HOLD, FLYING)
    assert arbiter.step(0.0, 0.02, grounded)[0][1].requests == []
    assert arbiter.step(0.4, 0.02, grounded)[0][1].requests == []
    assert [c for c, _ in arbiter.step(0.6, 0.02, grounded)[0][1].requests] == [Command.TAKEOFF]  # no answer: it goes on
    assert arbiter.mission.status == MissionStatus.ACTIVE


def test_set_current_flies_to_the_new_item_at_once():
    """Issue 14: MISSION_SET_CURRENT was acknowledged, but the executor went on with the old leg's
    carrot and waited for the new item there (35 s); an RTL item landed on the spot."""
    arbiter = CommandArbiter()
    plan = Plan((Item("takeoff", z=5.0), Item("waypoint", x=20.0, y=0.0, z=5.0), Item("waypoint", x=0.0, y=15.0, z=5.0),
                 Item("rtl")), rtl_altitude=8.0)
    assert arbiter.accept(plan, HOME, 3600.0).plan is not None
    arbiter.control(MissionAction.START, 1)
    v = Vehicle((8.0, 0.0, 5.0), True, True, int(Nav.GOTO))
    for k in range(50):
        arbiter.step(k * 0.02, 0.02, v)
    assert arbiter.control(MissionAction.SET_CURRENT, 2).result == CommandResult.ACCEPTED
    (_, out), _ = arbiter.step(1.0, 0.02, v)
    assert out.requests == [(Command.GOTO, 0.0)] and arbiter.mission.current == 2
    assert math.dist(out.setpoint[0], v.position) < 0.1  # a fresh leg from where the vehicle is ...
    assert out.setpoint[1][1] > 0 and out.setpoint[1][0] < 0  # ... towards (0, 15), not on to (20, 0)
    assert arbiter.control(MissionAction.SET_CURRENT, 3).result == CommandResult.ACCEPTED
    (_, out), _ = arbiter.step(1.02, 0.02, v)
    assert (Command.LAND, 0.0) not in out.requests and out.setpoint[1][2] > 0  # the RTL climbs, it does not land here


def test_a_disarm_outside_the_plan_ends_the_mission_its_own_landing_completes_it():
    """Issue 14.3: after a failsafe landing commanded straight to the core and the disarm, the
    mission stayed ACTIVE for ever; a disarm that is not the plan's own landing aborts it."""
    arbiter = survey_arbiter()
    assert arbiter.control(MissionAction.START).result == CommandResult.ACCEPTED
    arbiter.mission.current = 3  # a waypoint leg
    flying = Vehicle((0.0, 0.0, 8.0), True, True, int(Nav.GOTO))
    arbiter.step(0.0, 0.02, flying)
    landed_by_core = Vehicle((0.0, 0.0, 0.0), True, False, int(Nav.LAND))
    arbiter.step(0.02, 0.02, landed_by_core)
    assert arbiter.mission.status == MissionStatus.ACTIVE  # armed on the ground: not over yet
    arbiter.step(0.04, 0.02, Vehicle((0.0, 0.0, 0.0), False, False, int(Nav.NONE)))
    assert arbiter.mission.status == MissionStatus.ABORTED and arbiter.mission.last_error == "vehicle disarmed outside the plan"
    # the plan's own landing: the disarm completes the land item, then the plan
    hop = CommandArbiter()
    assert hop.accept(load_plan(ROOT / "missions" / "hop.yaml"), HOME, 3600.0).plan is not None
    hop.control(MissionAction.START, 2)  # the land item
    out = hop.step(0.0, 0.02, Vehicle((0.0, 8.0, 4.0), True, True, int(Nav.GOTO)))
    assert (Command.LAND, 0.0) in out[0][1].requests
    hop.step(0.02, 0.02, Vehicle((0.0, 8.0, 0.0), False, False, int(Nav.NONE)))
    assert hop.mission.status == MissionStatus.COMPLETED


def test_a_start_right_after_a_failsafe_landing_is_flown_not_aborted_by_the_old_disarm():
    """CI race: MISSION_START arrived within one tick of the disarm after an RTL; the first step then
    saw armed (from the flight) → disarmed and aborted the fresh start, though START was ACCEPTED."""
    arbiter = survey_arbiter()
    arbiter.control(MissionAction.START)
    arbiter.mission.current = 3
    arbiter.step(0.0, 0.02, Vehicle((0.0, 0.0, 8.0), True, True, int(Nav.RTL)))
    arbiter.mission.abort()  # the failsafe's RTL ended the plan; the landing and disarm not stepped yet
    assert arbiter.control(MissionAction.START).result == CommandResult.ACCEPTED
    out = arbiter.step(0.02, 0.02, Vehicle((0.0, 0.0, 0.0), False, False, int(Nav.NONE)))
    assert arbiter.mission.status == MissionStatus.ACTIVE, arbiter.mission.last_error
    assert any(command == Command.TAKEOFF for _, o in out for command, _ in o.requests)
