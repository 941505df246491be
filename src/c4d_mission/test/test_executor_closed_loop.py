"""Mission executor flying the example survey in the deterministic closed loop (plant + core)."""

import math
from pathlib import Path

import yaml
from closed_loop import ClosedLoop

from c4d_common import quat
from c4d_common.airframe import default_airframe_path, load_airframe
from c4d_common.geodesy import GeoOrigin
from c4d_common.plan_files import load_plan
from c4d_common.plan_validation import local_point, validate
from c4d_common.vehicle import SetpointSource
from c4d_gnc.core_config import default_config_path
from c4d_gnc.gnc import Command, Landed, Level, Nav, Request, Setpoint
from c4d_mission.executor import MissionExecutor, MissionStatus, Vehicle
from c4d_mission.payload import CameraTrigger

ROOT = Path(__file__).resolve().parents[3]
HOME = GeoOrigin(43.5629, 1.4815, 146.0)


def point_along(path, s):
    """The point at arc length s along a horizontal polyline."""
    for a, b in zip(path, path[1:], strict=False):
        length = math.dist(a, b)
        if s <= length:
            return (a[0] + (b[0] - a[0]) * s / length, a[1] + (b[1] - a[1]) * s / length)
        s -= length
    return path[-1]


class Sitl:
    """The deterministic closed loop (plant + core) with the mission node's adapters: the vehicle
    snapshot executors see, their requests to the core, their setpoints."""

    def __init__(self) -> None:
        config = yaml.safe_load(default_config_path().read_text())["executive"]
        self.loop = ClosedLoop(load_airframe(default_airframe_path("quad_x")), config, seed=3)

    def vehicle(self) -> Vehicle:
        s, out = self.loop.plant.state, self.loop.core.out
        return Vehicle(s.position, out.armed, out.landed not in (Landed.ON_GROUND,), int(out.nav), quat.yaw_of(s.orientation))

    def send(self, requests) -> None:
        for command, value in requests:
            ok, reason = self.loop.core.request(Request(command, altitude=value))
            assert ok, (command, reason)

    def step(self, executor: MissionExecutor, dt: float, vehicle: Vehicle | None = None):
        """One guidance step of `executor` (on a possibly stale `vehicle`); its output is applied."""
        result = executor.step(self.loop.t, dt, vehicle or self.vehicle())
        self.send(result.requests)
        if result.setpoint is not None:
            position, velocity, yaw = result.setpoint
            self.loop.core.receive_setpoint(SetpointSource.MISSION, Setpoint(self.loop.t, Level.POSITION, position, velocity,
                                                                             yaw=yaw))
        return result


def fly(plan, timeout=240.0):
    sitl = Sitl()
    loop = sitl.loop
    executor = MissionExecutor()
    executor.load(plan, HOME)
    assert executor.start() == ""
    trigger, captures = CameraTrigger(), []
    reached = {}
    dt = 0.02
    while loop.t < timeout and executor.status == MissionStatus.ACTIVE:
        position = loop.plant.state.position
        for k in sitl.step(executor, dt).reached:
            reached[k] = position
        captures += trigger.update(plan, executor.current, executor.last_reached, position, HOME)
        loop.run(dt)
    fly.captures = captures
    return loop, executor, reached


def test_survey_completes_every_waypoint_within_acceptance_and_lands_home():
    plan = load_plan(ROOT / "missions" / "survey.yaml")
    assert validate(plan, HOME).ok
    loop, executor, reached = fly(plan)
    assert executor.status == MissionStatus.COMPLETED, (executor.current, executor.status)
    for k, item in enumerate(plan.items):
        if item.type == "waypoint":
            target = local_point(item, HOME)
            assert math.dist(reached[k], target) <= item.acceptance_radius, (k, reached[k], target)
    assert not loop.core.out.armed and loop.plant.state.position[2] < 0.05
    assert math.hypot(*loop.plant.state.position[:2]) < 1.0  # back home
    assert executor.camera.mode == "off" and executor.camera.distance == 5
    assert loop.executive.profiler.overruns_total == 0
    # camera every 5 m along the six survey legs (88 m): 17 captures, each within 1 m of its planned spot
    path = [(0.0, 0.0)] + [local_point(i, HOME)[:2] for i in plan.items if i.type == "waypoint"]
    captures = fly.captures
    assert len(captures) == 17 and all(c.trigger == "distance" for c in captures)
    for k, c in enumerate(captures):
        planned = point_along(path, 5.0 * (k + 1))
        assert math.dist(c.position[:2], planned) <= 1.0, (k, c.position, planned)


def test_refused_requests_are_retried_then_the_mission_aborts():
    from c4d_common.plan import Item, Plan

    executor = MissionExecutor()
    executor.load(Plan((Item("takeoff", z=5.0),)), HOME)
    executor.start()
    grounded = Vehicle((0.0, 0.0, 0.0), False, False, 0)
    assert executor.step(0.0, 0.02, grounded).requests == [(Command.TAKEOFF, 5.0)]
    last = 0.0  # time of the step that sent the refused request
    for _ in range(10):
        executor.request_rejected(Command.TAKEOFF, "navigation state is stale")
        assert executor.step(last + 0.5, 0.02, grounded).requests == []  # waits a second between attempts
        last += 1.01
        assert executor.step(last, 0.02, grounded).requests == [(Command.TAKEOFF, 5.0)]
    executor.request_rejected(Command.TAKEOFF, "navigation state is stale")
    assert executor.status == MissionStatus.ABORTED and "stale" in executor.last_error


def test_rtl_commanded_right_after_a_plan_ends_in_the_air_is_flown_despite_a_stale_status():
    """The race CI met with MAVSDK: a plan ending in the air completes and asks the core to hold; an
    RTL commanded at once starts while the vehicle status still reports NAV_GOTO (the hold is in
    flight). The RTL's first leg must still ask the core to follow, after the hold, or the core holds
    forever — as RETURN_TO_LAUNCH, so that the vehicle's status reports RTL, not GOTO (issue 14.11)."""
    from c4d_common.plan import Item, Plan

    sitl, dt = Sitl(), 0.02
    loop = sitl.loop
    executor, rtl = MissionExecutor(), MissionExecutor()
    executor.load(Plan((Item("takeoff", z=5.0), Item("waypoint", x=4.0, y=3.0, z=5.0))), HOME)
    assert executor.start() == ""
    while loop.t < 60.0:
        result = sitl.step(executor, dt, stale := sitl.vehicle())
        if executor.status != MissionStatus.ACTIVE:
            break
        loop.run(dt)
    # the step that passes the last item completes the plan and asks for the HOLD at once
    assert executor.status == MissionStatus.COMPLETED and result.reached == [1] and result.requests == [(Command.HOLD, 0.0)]
    assert stale.core_nav == 4  # the snapshot the RTL starts from still says GOTO

    rtl.load(Plan((Item("rtl"),), rtl_altitude=8.0), HOME)
    rtl.start()
    assert sitl.step(rtl, dt, stale).requests == [(Command.RETURN_TO_LAUNCH, 0.0)]  # after the hold: the core follows the RTL
    navs = []
    while rtl.status == MissionStatus.ACTIVE and loop.t < 120.0:
        loop.run(dt)
        sitl.step(rtl, dt)
        if not navs or navs[-1] != loop.core.out.nav:
            navs.append(loop.core.out.nav)
    assert rtl.status == MissionStatus.COMPLETED, (rtl.status, loop.plant.state.position)
    assert navs == [Nav.RTL, Nav.LAND, Nav.NONE], navs  # returning, its landing, disarmed
    assert not loop.core.out.armed and math.hypot(*loop.plant.state.position[:2]) < 1.0


def test_pause_mid_leg_holds_and_resume_continues_from_where_the_vehicle_is():
    """Pause (the mission node then sends HOLD) in the middle of a leg, move the vehicle with a go-to,
    resume: the mission flies a fresh leg from the vehicle's position — no jump back to the
    interrupted leg's setpoint — asks the core for GOTO again, and completes."""
    from c4d_common.plan import Item, Plan

    sitl, dt = Sitl(), 0.02
    loop = sitl.loop
    executor, goto = MissionExecutor(), MissionExecutor()
    executor.load(Plan((Item("takeoff", z=5.0), Item("waypoint", x=20.0, y=0.0, z=5.0), Item("land"))), HOME)
    executor.start()
    while loop.plant.state.position[0] < 8.0 and loop.t < 60.0:
        sitl.step(executor, dt)
        loop.run(dt)
    assert executor.current == 1 and executor.pause() == ""
    sitl.send([(Command.HOLD, 0.0)])
    paused_at = loop.plant.state.position
    for _ in range(int(3.0 / dt)):
        assert sitl.step(executor, dt).setpoint is None  # paused: no guidance
        loop.run(dt)
    assert math.dist(loop.plant.state.position, paused_at) < 1.5  # braked and held near the pause point

    goto.load(Plan((Item("waypoint", x=8.0, y=-6.0, z=7.0),)), HOME)  # a go-to moves the vehicle away
    goto.start()
    while goto.status == MissionStatus.ACTIVE and loop.t < 90.0:
        sitl.step(goto, dt)
        loop.run(dt)
    assert goto.status == MissionStatus.COMPLETED

    assert executor.resume() == ""
    here = loop.plant.state.position
    first = sitl.step(executor, dt)
    assert first.requests == [(Command.GOTO, 0.0)]  # the core held after the go-to: following again needs GOTO
    assert math.dist(first.setpoint[0], here) < 0.5, (first.setpoint[0], here)  # the leg starts where the vehicle is
    while executor.status == MissionStatus.ACTIVE and loop.t < 180.0:
        loop.run(dt)
        sitl.step(executor, dt)
    assert executor.status == MissionStatus.COMPLETED and executor.last_reached == 2
    assert not loop.core.out.armed and math.dist(loop.plant.state.position[:2], (20.0, 0.0)) < 1.0


def fly_until(sitl: Sitl, executor: MissionExecutor, done, timeout: float) -> dict[int, tuple]:
    """Step `executor` in the closed loop until done() or `timeout` [s]; the reached items and where."""
    loop, reached = sitl.loop, {}
    while not done() and loop.t < timeout and executor.status == MissionStatus.ACTIVE:
        position = loop.plant.state.position
        for k in sitl.step(executor, 0.02).reached:
            reached[k] = position
        loop.run(0.02)
    return reached


def test_set_current_mid_leg_flies_to_the_new_item_and_to_an_rtl_item_home():
    """Issue 14: MISSION_SET_CURRENT was acknowledged but the vehicle held on the old leg; set to
    the RTL item it landed on the spot, 28.6 m from home."""
    from c4d_common.plan import Item, Plan

    plan = Plan((Item("takeoff", z=5.0), Item("waypoint", x=20.0, y=0.0, z=5.0), Item("waypoint", x=0.0, y=15.0, z=5.0),
                 Item("rtl")), rtl_altitude=6.0)
    sitl, executor = Sitl(), MissionExecutor()
    executor.load(plan, HOME)
    executor.start()
    fly_until(sitl, executor, lambda: sitl.loop.plant.state.position[0] > 8.0, 60.0)
    assert executor.current == 1 and executor.set_current(2) == ""
    t0 = sitl.loop.t
    reached = fly_until(sitl, executor, lambda: executor.current > 2, t0 + 30.0)
    assert 1 not in reached and math.dist(reached[2], (0.0, 15.0, 5.0)) <= 1.0, reached  # straight to the new item
    assert sitl.loop.t - t0 < 15.0  # ~11 m at 5 m/s, not a 35 s wait on the old leg

    executor.start(1)  # again mid-leg towards (20, 0), then the RTL item
    fly_until(sitl, executor, lambda: sitl.loop.plant.state.position[0] > 8.0, sitl.loop.t + 30.0)
    assert executor.set_current(3) == ""
    fly_until(sitl, executor, lambda: False, sitl.loop.t + 90.0)
    assert executor.status == MissionStatus.COMPLETED and not sitl.loop.core.out.armed
    assert math.hypot(*sitl.loop.plant.state.position[:2]) < 1.0  # landed home, not where it was


def test_a_plan_without_take_off_started_on_the_ground_takes_off_to_the_first_waypoint():
    """Issue 14 (PX4 semantics): no take-off item — the vehicle takes off to the first waypoint's
    altitude (at least takeoff_altitude) and flies the plan."""
    from c4d_common.plan import Item, Plan

    plan = Plan((Item("waypoint", x=6.0, y=0.0, z=4.0), Item("waypoint", x=6.0, y=6.0, z=4.0), Item("land")))
    assert validate(plan, HOME).ok
    sitl, executor = Sitl(), MissionExecutor(takeoff_altitude=2.5)
    executor.load(plan, HOME)
    executor.start()
    first = sitl.step(executor, 0.02)
    assert first.requests == [(Command.TAKEOFF, 4.0)]
    peak = 0.0
    reached = {}
    while executor.status == MissionStatus.ACTIVE and sitl.loop.t < 90.0:
        position = sitl.loop.plant.state.position
        for k in sitl.step(executor, 0.02).reached:
            reached[k] = position
        sitl.loop.run(0.02)
        peak = max(peak, position[2])
    assert executor.status == MissionStatus.COMPLETED and not sitl.loop.core.out.armed
    assert math.dist(reached[0], (6.0, 0.0, 4.0)) <= 1.0 and math.dist(reached[1], (6.0, 6.0, 4.0)) <= 1.0, reached
    assert peak < 4.6, peak
