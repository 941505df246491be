"""Command arbitration: who flies the vehicle — the uploaded plan, an RTL / go-to, or the core alone.

Why a class of its own: the mission node serves four sources of intent (mission/control, the
vehicle/command service's RTL and go-to, hold / land / disarm / set mode forwarded to the core,
and the plan's own requests), and the races between them were found only in whole-graph CI runs.
Here they are plain method calls, tested without ROS (test_arbitration.py).

Two executors: `mission` runs the accepted plan; `detour` runs a one-item plan for an RTL or a
go-to commanded outside the plan. The rules:
- RTL aborts the mission and flies home (needs an armed vehicle with a home position).
- go-to pauses the mission (resume continues it from where the vehicle is) and loiters at the
  target (needs a flying vehicle; checked against the plan's geofence unless forced — a target
  that is itself malformed is never forced).
- HOLD, LAND, DISARM and a mode set by hand are the core's to decide: they act on the plan only
  once the core accepts them (HOLD and a mode pause the mission, LAND and DISARM abort it; each
  cancels a detour). A refused one changes nothing (issue 14: a DISARM refused in the air used to
  abort the mission). While the core decides, the executors are not stepped (at most AWAIT_S), so
  no new-leg GOTO can reach the core after the command and undo an accepted HOLD / LAND / mode.
- mission/control start and resume cancel a detour (the plan takes over again); pause asks the
  core to HOLD.
- The fence in force (`fence`, fence.ActiveFence) validates plans and go-to targets; geofence/set
  replaces it (`set_geofence`). A plan leg that the fence in force blocks — the one being flown
  when a new fence arrives, or any new leg after — is not flown: the mission pauses and the core
  is asked to HOLD, with the reason in `notices`. A go-to or RTL is never stopped here: a go-to
  was checked (or forced) when commanded, and an RTL — a failsafe's too — must not be cancelled
  by the fence it returns from; the core's barrier keeps both out of the fence.
- `step()` runs the mission before the detour every tick, so the requests both send reach the core
  in that order: a plan's final HOLD always precedes the GOTO of an RTL commanded at once (the
  executor asks GOTO on every new leg and completes a plan in the step that passes its last item).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from c4d_common.geodesy import GeoOrigin
from c4d_common.plan import GLOBAL, Geofence, Item, Plan
from c4d_common.plan_validation import IssueKind, PlanIssue, ValidationResult, VehicleLimits, check_goto, validate
from c4d_common.vehicle import Command, CommandResult, Landed, MissionAction, MissionStatus, UploadRefusal, VehicleCommandId

from .executor import Checkpoint, MissionExecutor, Output, Vehicle
from .fence import ActiveFence, leg_blocked, refusal

Vec = tuple[float, float, float]
# forwarded commands that take the vehicle from the plan when the core accepts them
TAKES_VEHICLE = (VehicleCommandId.HOLD, VehicleCommandId.LAND, VehicleCommandId.DISARM, VehicleCommandId.SET_MODE)
AWAIT_S = 0.5  # [s] longest the executors wait for the core's answer (a lost reply must not freeze the plan)


@dataclass(frozen=True)
class VehicleView:
    """What arbitration needs to know about the vehicle (from navigation/state and vehicle/status)."""

    home: GeoOrigin | None  # None until the estimator has an origin
    armed: bool
    landed: Landed
    position: Vec  # local ENU [m] from home


@dataclass(frozen=True)
class Decision:
    """The answer to a command: result and message for the caller, and what the core must get."""

    result: CommandResult
    message: str
    forward: bool = False  # the core decides: pass the request on and answer with its reply
    core: tuple[Command, ...] = ()  # requests to send to the core besides (not awaited)


@dataclass(frozen=True)
class Acceptance:
    """The verdict on an uploaded plan: the accepted plan (with its id) or the issues against it."""

    plan: Plan | None
    errors: tuple[PlanIssue, ...]
    warnings: tuple[PlanIssue, ...]
    validation: ValidationResult | None = None

    @property
    def refusal(self) -> UploadRefusal:
        """Why the plan was refused, for callers to decide on (retry, fix the plan, wait): NONE when accepted."""
        if self.plan is not None:
            return UploadRefusal.NONE
        kinds = {issue.kind for issue in self.errors}
        return next((refusal for kind, refusal in _REFUSALS if kind in kinds), UploadRefusal.INVALID)


_REFUSALS = ((IssueKind.NO_HOME, UploadRefusal.NO_HOME), (IssueKind.BATTERY_UNKNOWN, UploadRefusal.BATTERY_UNKNOWN),
             (IssueKind.MISSION_ACTIVE, UploadRefusal.MISSION_ACTIVE))


def _refused(kind: IssueKind, text: str) -> Acceptance:
    return Acceptance(None, (PlanIssue(kind, None, text),), ())


def _accepted(message: str) -> Decision:
    return Decision(CommandResult.ACCEPTED, message)


class CommandArbiter:
    """Owns the plan executor and the RTL / go-to executor and applies the rules of the module docstring."""

    def __init__(self, limits: VehicleLimits | None = None) -> None:
        self.limits = limits or VehicleLimits()
        self.mission = MissionExecutor(takeoff_altitude=self.limits.takeoff_altitude)
        self.detour = MissionExecutor()  # RTL and go-to commanded outside a plan
        self._next_id = 1
        self._awaiting = 0  # TAKES_VEHICLE commands forwarded, the core's answer not yet in
        self._awaiting_since: float | None = None
        self.fence = ActiveFence()
        self.notices: list[str] = []  # for the log: legs blocked by the fence (the node drains it)
        self._checked_leg: object = None  # the plan's last leg checked against the fence

    # ------------------------------------------------------------------ plans
    def accept(self, plan: Plan, home: GeoOrigin | None, endurance_s: float | None) -> Acceptance:
        """Validate `plan` and, if it passes and no mission is active, load it with a new id. Never
        accepts a plan it could not fully validate: without a home position or an endurance (no
        battery state yet) the plan is refused with a retry kind (NO_HOME, BATTERY_UNKNOWN)."""
        if home is None:
            return _refused(IssueKind.NO_HOME, "plan: no home position yet (estimator not ready)")
        if endurance_s is None:
            return _refused(IssueKind.BATTERY_UNKNOWN, "plan: battery state unknown yet (no battery report): "
                                                       "endurance not checked, retry")
        plan = self.fence.for_plan(plan)  # a plan without a fence flies under one set in flight
        result = validate(plan, home, self.limits, endurance_s)
        if not result.ok:
            return Acceptance(None, result.issues, result.notices, result)
        if self.mission.status == MissionStatus.ACTIVE:
            return _refused(IssueKind.MISSION_ACTIVE, "plan: a mission is active (pause or land first)")
        plan = plan.with_id(self._next_id)
        self._next_id += 1
        self.mission.load(plan, home)
        self.fence.plan_accepted(plan)
        return Acceptance(plan, (), result.notices, result)

    def restore(self, plan: Plan, home: GeoOrigin, checkpoint: Checkpoint, status: MissionStatus) -> None:
        """Take back a plan persisted before a restart (already accepted then: not validated again);
        later uploads get ids after its id."""
        self.mission.restore(plan, home, checkpoint, status)
        self._next_id = max(self._next_id, plan.plan_id + 1)

    def _rtl_altitude(self) -> float:
        return self.mission.plan.rtl_altitude if self.mission.plan else 0.0

    # ------------------------------------------------------------------ mission/control
    def control(self, action: int, item: int = 0) -> Decision:
        """mission/control: start (at `item`), pause, resume, clear, set current item."""
        try:
            kind = MissionAction(action)
        except ValueError:
            return Decision(CommandResult.UNSUPPORTED, "unknown action")
        core: tuple[Command, ...] = ()
        if kind == MissionAction.START:
            reason = self.mission.start(item)
            if not reason:
                self.detour.clear()
        elif kind == MissionAction.PAUSE:
            reason = self.mission.pause()
            core = () if reason else (Command.HOLD,)
        elif kind == MissionAction.RESUME:
            reason = self.mission.resume()
            if not reason:
                self.detour.clear()  # a go-to interrupted the mission: the plan takes over again
        elif kind == MissionAction.CLEAR:
            reason = "mission is active (pause it first)" if self.mission.status == MissionStatus.ACTIVE else ""
            if not reason:
                self.mission.clear()
        else:  # SET_CURRENT: an active mission flies to the new item at once
            reason = self.mission.set_current(item)
        if reason:
            return Decision(CommandResult.DENIED, reason)
        return Decision(CommandResult.ACCEPTED, "accepted", core=core)

    # ------------------------------------------------------------------ vehicle/command
    def command(self, command: int, vehicle: VehicleView, force: bool = False, target: Item | None = None) -> Decision:
        """vehicle/command after the pre-arm checks: RTL and go-to are flown here, everything else
        is forwarded to the core; the caller must report the core's answer (or that there was
        none) to `core_replied`."""
        if command == VehicleCommandId.RETURN_TO_LAUNCH:
            return self._return_to_launch(vehicle)
        if command == VehicleCommandId.GOTO:
            return self._go_to(vehicle, force, target)
        if command in TAKES_VEHICLE:
            self._awaiting += 1
        return Decision(CommandResult.ACCEPTED, "", forward=True)

    def core_replied(self, command: int, result: int) -> None:
        """The core's answer to a forwarded command (CommandResult; anything but ACCEPTED when it
        did not answer). Accepted HOLD, LAND, DISARM or mode set by hand (pilot, GCS) take the
        vehicle from the plan: HOLD and a mode pause the mission (set mission mode again to resume
        where it stopped), LAND and DISARM abort it; an RTL or go-to is cancelled. Refused: nothing."""
        if command not in TAKES_VEHICLE:
            return
        self._awaiting = max(0, self._awaiting - 1)
        if result != CommandResult.ACCEPTED:
            return
        if command in (VehicleCommandId.LAND, VehicleCommandId.DISARM):
            self.mission.abort()
        else:
            self.mission.pause()
        self.detour.clear()

    def _return_to_launch(self, vehicle: VehicleView) -> Decision:
        if vehicle.home is None or not vehicle.armed:
            return Decision(CommandResult.DENIED, "RTL needs an armed vehicle with a home position")
        self.mission.abort()
        self.detour.load(Plan((Item("rtl"),), rtl_altitude=self._rtl_altitude()), vehicle.home)
        self.detour.start()
        return _accepted("returning to launch")

    def _go_to(self, vehicle: VehicleView, force: bool, target: Item | None) -> Decision:
        if vehicle.home is None or not vehicle.armed or vehicle.landed != Landed.IN_AIR or target is None:
            return Decision(CommandResult.DENIED, "go-to needs a flying vehicle (take off first)")
        issues = check_goto(target, vehicle.position, self.fence.fence, vehicle.home, self.limits)
        if issues and (not force or any(i.kind.malformed for i in issues)):
            return Decision(CommandResult.DENIED, "; ".join(map(str, issues)))
        self.mission.pause()  # a running mission can be resumed after the go-to
        self.detour.load(Plan((target,), rtl_altitude=self._rtl_altitude()), vehicle.home)
        self.detour.start()
        forced = f" (forced: {'; '.join(map(str, issues))})" if issues else ""
        return _accepted("going to the target" + forced)

    # ------------------------------------------------------------------ geofence/set
    def set_geofence(self, fence: Geofence, force: bool, vehicle: VehicleView) -> Decision:
        """Replace the fence in force at once (module docstring of fence.py): refused when the
        vehicle is outside it unless `force`; a leg being flown that it blocks is stopped (HOLD)."""
        flying = vehicle.armed and vehicle.landed == Landed.IN_AIR
        why = refusal(fence, force, vehicle.home, vehicle.position, flying)
        if why:
            return Decision(CommandResult.DENIED, why)
        self.fence.set(fence)
        self._checked_leg = None
        said = self._stop_blocked(vehicle.position)
        message = ("fence cleared" if fence.empty else "fence in force") + (f"; {said}" if said else "")
        return Decision(CommandResult.ACCEPTED, message, core=(Command.HOLD,) if said else ())

    def _stop_blocked(self, position: Vec) -> str:
        """Pause the mission when the fence in force blocks its leg from `position`; the reason, ""
        when not blocked or not flying a leg."""
        mission, leg = self.mission, self.mission.leg
        if mission.status != MissionStatus.ACTIVE or leg is None or mission.home is None:
            return ""
        why = leg_blocked(self.fence.fence, mission.home, position, leg[1])
        if not why:
            return ""
        mission.pause()
        text = f"mission paused: the leg to item {mission.current + 1} {why}"
        self.notices.append(text)
        return text

    def _check_new_leg(self, out: Output, position: Vec) -> None:
        """Each new leg of the plan is checked once against the fence in force; a blocked one is not flown."""
        leg = self.mission.leg
        if leg is None or self._checked_leg is leg:
            return
        self._checked_leg = leg
        if self._stop_blocked(position):
            out.requests.append((Command.HOLD, 0.0))  # after the leg's GOTO: the core keeps the HOLD
            out.setpoint = None

    # ------------------------------------------------------------------ guidance
    def step(self, now: float, dt: float, vehicle: Vehicle) -> list[tuple[MissionExecutor, Output]]:
        """One guidance step of the mission, then of the detour (this order is the contract);
        nothing while the core decides a forwarded command (module docstring)."""
        if self._awaiting:
            self._awaiting_since = now if self._awaiting_since is None else self._awaiting_since
            if now - self._awaiting_since < AWAIT_S:
                return [(self.mission, Output()), (self.detour, Output())]
            self._awaiting = 0  # no answer: the plan goes on
        self._awaiting_since = None
        outputs = []
        for runner in (self.mission, self.detour):
            out = runner.step(now, dt, vehicle)
            if runner is self.mission:
                self._check_new_leg(out, vehicle.position)
            outputs.append((runner, out))
        return outputs


def goto_target(latitude: float, longitude: float, altitude: float, yaw: float) -> Item:
    """A go-to target as the one item of a detour plan: loiter there until told otherwise."""
    return Item("loiter", frame=GLOBAL, x=latitude, y=longitude, z=altitude, hold=math.inf, yaw=yaw)
