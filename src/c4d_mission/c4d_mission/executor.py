"""Mission executor: runs a validated plan item by item and produces the core's inputs.

ROS-free: `step(now, vehicle)` is called at the guidance rate (50 Hz) with the vehicle's
state; it returns the core requests to send (take-off, go-to, land — the core applies them at
its next tick) and the guidance setpoint to stream. Waypoint legs are flown by a carrot that
moves along the segment with a trapezoidal speed profile (cruise speed, acceleration limit), so
the setpoints are smooth; a waypoint is reached when the vehicle is within its acceptance
radius of it and the carrot has arrived; then its hold time runs. RTL climbs to the RTL
altitude, flies home and lands. Camera items update `camera` for the payload block. A waypoint
or loiter reached on the ground (a plan without a take-off item, started on the ground) is
preceded by a take-off to its altitude, at least `takeoff_altitude` (PX4: MIS_TAKEOFF_ALT).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from c4d_common.geodesy import GeoOrigin
from c4d_common.plan import Plan
from c4d_common.plan_validation import local_point
from c4d_common.vehicle import Command, MissionStatus, Nav

Vec = tuple[float, float, float]
# phases that carry over a restart: the take-off asked of the core (wait for its climb, never ask
# again) and a landing (asked, or about to be); any other phase restarts its item with a fresh leg
# from where the vehicle is, as a resume after a pause does
KEPT_PHASES = ("wait", "land", "landing")


@dataclass(frozen=True)
class Checkpoint:
    """What a restarted mission node needs to continue a plan: the executor's progress through it."""

    plan_id: int
    status: MissionStatus
    current: int
    last_reached: int
    speed: float  # [m/s] cruise speed in force (change_speed items passed so far)
    phase: str  # "start" or one of KEPT_PHASES
    camera_mode: str = "off"
    camera_distance: float = 0.0  # [m]
    captures_requested: int = 0


@dataclass
class Vehicle:
    position: Vec
    armed: bool
    in_air: bool
    core_nav: int  # Nav (VehicleStatus.NAV_*)
    yaw: float = 0.0


@dataclass
class Output:
    requests: list[tuple[Command, float]] = field(default_factory=list)  # (TAKEOFF, alt) | (GOTO | RTL | LAND | HOLD, 0)
    setpoint: tuple[Vec, Vec, float] | None = None  # position, velocity feed-forward, yaw
    reached: list[int] = field(default_factory=list)


@dataclass
class CameraState:
    """The camera as the plan's camera items have set it so far (for the payload block)."""

    mode: str = "off"  # "off" | "on" (capture at waypoints) | "distance" (every `distance` metres)
    distance: float = 0.0
    captures_requested: int = 0


class LegTracker:
    """Carrot along A→B: accelerate at `accel` to `speed`, brake to stop at B."""

    def __init__(self, start: Vec, end: Vec, speed: float, accel: float = 1.5) -> None:
        self.a, self.b = start, end
        self.ends = (start, end)
        self.length = math.dist(start, end)
        self.dir = tuple((e - s) / self.length for s, e in zip(start, end, strict=True)) if self.length > 1e-6 else (0, 0, 0)
        self.speed, self.accel = speed, accel
        self.s = self.v = 0.0

    @property
    def done(self) -> bool:
        return self.s >= self.length - 1e-6

    def advance(self, dt: float) -> tuple[Vec, Vec]:
        remaining = self.length - self.s
        self.v = min(self.speed, self.v + self.accel * dt, math.sqrt(max(0.0, 2 * self.accel * remaining)))
        self.s = min(self.length, self.s + self.v * dt)
        if self.done:
            self.v = 0.0
        position = tuple(a + d * self.s for a, d in zip(self.a, self.dir, strict=True))
        velocity = tuple(d * self.v for d in self.dir)
        return position, velocity  # type: ignore[return-value]


class MissionExecutor:
    """Runs one plan (or a one-item RTL / go-to plan) item by item: see the module docstring."""

    def __init__(self, default_speed: float = 5.0, default_rtl_altitude: float = 15.0,
                 takeoff_altitude: float = 2.5) -> None:
        self.plan: Plan | None = None
        self.home: GeoOrigin | None = None
        self.status = MissionStatus.NO_PLAN
        self.current = 0
        self.last_reached = -1
        self.default_speed, self.default_rtl_altitude = default_speed, default_rtl_altitude
        self.takeoff_altitude = takeoff_altitude  # [m] least altitude of a take-off the plan does not have
        self.speed = default_speed
        self.camera = CameraState()
        self._phase = "start"
        self._tracker: LegTracker | None = None
        self._hold_until = 0.0
        self._yaw = 0.0
        self.retries = 0
        self.last_error = ""
        self._now = 0.0
        self._retry_at = -math.inf
        self._armed = False  # as last seen: a disarm outside the plan's own landing aborts the mission

    # ------------------------------------------------------------------ control
    def load(self, plan: Plan, home: GeoOrigin) -> None:
        self.plan, self.home = plan, home
        self.status, self.current, self.last_reached = MissionStatus.READY, 0, -1
        self.speed = plan.cruise_speed if plan.cruise_speed > 0 else self.default_speed
        self._phase = "start"

    def checkpoint(self) -> Checkpoint:
        """The progress to persist; equal checkpoints mean nothing worth persisting changed."""
        c = self.camera
        return Checkpoint(self.plan.plan_id if self.plan else 0, self.status, self.current, self.last_reached, self.speed,
                          self._phase if self._phase in KEPT_PHASES else "start", c.mode, c.distance, c.captures_requested)

    def restore(self, plan: Plan, home: GeoOrigin, checkpoint: Checkpoint, status: MissionStatus) -> None:
        """Load `plan` at the progress of `checkpoint` with `status` (no core request is repeated
        for a kept phase: a take-off in progress is waited for, not asked again)."""
        self.load(plan, home)
        self.status, self.current, self.last_reached = status, checkpoint.current, checkpoint.last_reached
        self.speed = checkpoint.speed
        self._phase = checkpoint.phase if checkpoint.phase in KEPT_PHASES else "start"
        self.camera = CameraState(checkpoint.camera_mode, checkpoint.camera_distance, checkpoint.captures_requested)

    def clear(self) -> None:
        self.plan, self.status, self.current, self.last_reached = None, MissionStatus.NO_PLAN, 0, -1

    def start(self, item: int = 0) -> str:
        if self.plan is None:
            return "no plan loaded"
        if not 0 <= item < len(self.plan.items):
            return f"item {item} does not exist"
        self.current, self._phase, self.status, self._tracker = item, "start", MissionStatus.ACTIVE, None
        self._armed = False  # a new run: a disarm seen before it (not yet stepped) must not abort it
        return ""

    def set_current(self, item: int) -> str:
        """Make `item` the current one (MISSION_SET_CURRENT). An active mission flies to it at once,
        on a fresh leg from where the vehicle is (PX4: the vehicle goes to the new current item),
        never finishing the interrupted leg or treating the new item as already under way."""
        if self.plan is None:
            return "no plan loaded"
        if not 0 <= item < len(self.plan.items):
            return f"item {item} does not exist"
        self.current, self.retries = item, 0
        if self.status == MissionStatus.ACTIVE:
            self._phase, self._tracker = "start", None
        return ""

    def pause(self) -> str:
        if self.status != MissionStatus.ACTIVE:
            return "mission is not active"
        self.status = MissionStatus.PAUSED
        return ""

    def resume(self) -> str:
        if self.status != MissionStatus.PAUSED:
            return "mission is not paused"
        # a fresh leg from where the vehicle is now (it held, or flew a go-to, meanwhile): no jump back
        # to the interrupted leg's setpoint, and the new leg asks the core for GOTO again
        self.status, self._phase, self._tracker = MissionStatus.ACTIVE, "start", None
        return ""

    def request_rejected(self, command: Command, reason: str, max_retries: int = 10) -> None:
        """The core refused a request (e.g. inputs not fresh yet): retry the item, abort after
        `max_retries` refusals so a mission never waits forever."""
        self.retries += 1
        self.last_error = f"core refused {command.name.lower()}: {reason}"
        if self.retries > max_retries:
            self.abort()
            return
        self._phase, self._tracker = "start", None
        self._retry_at = self._now + 1.0  # give the vehicle a second before asking again

    def abort(self) -> None:
        if self.status in (MissionStatus.ACTIVE, MissionStatus.PAUSED):
            self.status = MissionStatus.ABORTED

    @property
    def leg(self) -> tuple[Vec, Vec] | None:
        """The straight leg being flown (start, end; local ENU), None between legs. A new leg is a
        new tuple: the arbiter checks each one against the fence in force once."""
        return self._tracker.ends if self._tracker is not None else None

    @property
    def progress(self) -> float:
        if self.plan is None or not self.plan.items:
            return 0.0
        if self.status == MissionStatus.COMPLETED:
            return 1.0
        return self.current / len(self.plan.items)

    # ------------------------------------------------------------------ execution
    def step(self, now: float, dt: float, v: Vehicle) -> Output:
        out = Output()
        self._now = now
        disarmed, self._armed = self._armed and not v.armed, v.armed
        if disarmed and self.status in (MissionStatus.ACTIVE, MissionStatus.PAUSED) and self._phase != "landing":
            self.abort()  # not the plan's own landing: a failsafe or a pilot ended the flight (issue 14.3)
            self.last_error = "vehicle disarmed outside the plan"
        if self.status != MissionStatus.ACTIVE or self.plan is None or self.home is None or now < self._retry_at:
            return out
        out = self._step_item(now, dt, v, out)
        if self.status == MissionStatus.ACTIVE and self.current >= len(self.plan.items):
            # completed in the step that passed the last item, so the end-of-plan HOLD is sent before
            # anyone can see the plan finished: a command reacting to that (RTL, a mode) reaches the
            # core after it, never before (CI: a GCS's mode change overridden by a late HOLD)
            self.status = MissionStatus.COMPLETED
            if v.armed and v.in_air:  # a plan ending in the air: hold here, not at the go-to's start
                out.requests.append((Command.HOLD, 0.0))
        return out

    def _step_item(self, now: float, dt: float, v: Vehicle, out: Output) -> Output:
        if self.current >= len(self.plan.items):
            return out
        item = self.plan.items[self.current]
        kind = item.type
        if kind == "change_speed":
            self.speed = item.speed
            return self._next(out)
        if kind.startswith("camera"):
            if kind == "camera_distance":
                self.camera.mode = "distance" if item.camera_distance > 0 else "off"
                self.camera.distance = item.camera_distance
            elif kind == "camera_start":
                self.camera.mode = "distance" if self.camera.distance > 0 else "on"
            elif kind == "camera_stop":
                self.camera.mode = "off"
            else:
                self.camera.captures_requested += 1
            return self._next(out)
        if kind == "takeoff":
            return self._takeoff(item.z, v, out)
        if kind in ("waypoint", "loiter"):
            target = local_point(item, self.home)
            if self._phase == "wait" or (self._phase == "start" and not v.in_air):
                return self._take_off_first(max(target[2], self.takeoff_altitude), v, out)
            return self._goto(now, dt, target, item.acceptance_radius, item.hold, item.yaw, v, out)
        if kind == "rtl":
            return self._rtl(now, dt, v, out)
        if kind == "land":
            if item.has_position and self._phase in ("start", "goto"):
                target = local_point(item, self.home)
                done = self._fly(now, dt, (target[0], target[1], v.position[2]), 1.0, v, out)
                if not done:
                    return out
                self._phase = "land"
            return self._land(v, out)
        return self._next(out)

    def _next(self, out: Output) -> Output:
        self.retries = 0
        self.last_reached = self.current
        out.reached.append(self.current)
        self.current += 1
        self._phase, self._tracker = "start", None
        return out

    def _takeoff(self, altitude: float, v: Vehicle, out: Output) -> Output:
        if self._phase == "start":
            if v.in_air:  # already flying: climb like a waypoint
                self._phase = "done"
                return self._next(out)
            out.requests.append((Command.TAKEOFF, altitude))
            self._phase = "wait"
        elif self._phase == "wait" and v.in_air and v.core_nav == Nav.HOLD:  # the core holds after the climb
            return self._next(out)
        return out

    def _take_off_first(self, altitude: float, v: Vehicle, out: Output) -> Output:
        """On the ground at a waypoint: take off (the plan has no take-off item), then fly the item."""
        if self._phase == "start":
            out.requests.append((Command.TAKEOFF, altitude))
            self._phase = "wait"
        elif v.in_air and v.core_nav == Nav.HOLD:  # the core holds after the climb: now the leg
            self._phase = "start"
        return out

    def _fly(self, now: float, dt: float, target: Vec, radius: float, v: Vehicle, out: Output, yaw: float = math.nan,
             follow: Command = Command.GOTO) -> bool:
        if self._tracker is None:
            # Every new leg asks the core to follow our setpoints (`follow`: GOTO, or RETURN_TO_LAUNCH on
            # an RTL's legs so that the vehicle's status says RTL), even when the reported navigation
            # state already says so: that report can be stale. A "hold" sent just before (a plan ending in
            # the air, then an RTL or go-to commanded at once) is still in flight, and requests reach the
            # core in order, so only a later "goto" is sure to be the one it keeps.
            out.requests.append((follow, 0.0))
            self._tracker = LegTracker(v.position, target, self.speed)
            dx, dy = target[0] - v.position[0], target[1] - v.position[1]
            self._yaw = yaw if math.isfinite(yaw) else (math.atan2(dy, dx) if math.hypot(dx, dy) > 1.0 else v.yaw)
        position, velocity = self._tracker.advance(dt)
        out.setpoint = (position, velocity, self._yaw)
        return self._tracker.done and math.dist(v.position, target) <= radius

    def _goto(self, now, dt, target, radius, hold, yaw, v, out) -> Output:
        if self._phase in ("start", "goto"):
            self._phase = "goto"
            if self._fly(now, dt, target, radius, v, out, yaw):
                self._phase, self._hold_until = "hold", now + hold
        if self._phase == "hold":
            out.setpoint = (target, (0.0, 0.0, 0.0), self._yaw)
            if now >= self._hold_until:
                return self._next(out)
        return out

    def _rtl(self, now, dt, v, out) -> Output:
        altitude = self.plan.rtl_altitude if self.plan and self.plan.rtl_altitude > 0 else self.default_rtl_altitude
        if self._phase == "start":
            self._phase, self._tracker = "climb", None
        if self._phase == "climb":
            target = (v.position[0], v.position[1], max(v.position[2], altitude)) if self._tracker is None else self._tracker.b
            self._fly(now, dt, target, 1.0, v, out, follow=Command.RETURN_TO_LAUNCH)
            # the climb is judged by its altitude alone: the core's barrier may hold the vehicle away
            # from where the RTL started (an RTL from beyond the fence is pushed back inside) and the
            # return must not wait for a point it cannot reach (issue 18)
            if self._tracker is not None and self._tracker.done and abs(v.position[2] - target[2]) <= 1.0:
                self._phase, self._tracker = "home", None
            return out
        if self._phase == "home":
            z = self._tracker.b[2] if self._tracker else max(v.position[2], altitude)
            if self._fly(now, dt, (0.0, 0.0, z), 1.0, v, out, follow=Command.RETURN_TO_LAUNCH):
                self._phase = "land"
            return out
        return self._land(v, out)

    def _land(self, v: Vehicle, out: Output) -> Output:
        if self._phase != "landing":
            out.requests.append((Command.LAND, 0.0))
            self._phase = "landing"
        elif not v.armed:
            return self._next(out)
        return out
