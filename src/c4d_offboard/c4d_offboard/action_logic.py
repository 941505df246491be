"""What the TakeOff / Land / GoTo / FollowPath action servers decide, without ROS.

Why here: the action servers (action_servers.py) only copy message fields in and out; which goal
is refused and why, the motion profile streamed in OFFBOARD, and when a goal has succeeded or
failed are plain functions and small state machines, unit-tested without DDS
(test/test_action_logic.py).

- `goal_refusal` / `path_refusal`: why a GoTo / FollowPath goal is rejected (not flying, non-finite,
  wrong frame, outside the geofence — the same `check_goto` rules as a MAVLink go-to).
- `PathProfile`: a straight-line or polyline trajectory at constant cruise speed with acceleration
  and deceleration limits (trapezoidal speed along the arc length): position + velocity
  feed-forward at any time.
- `OffboardRun`: a GoTo / FollowPath goal in time — stream the start point until the core has had
  a live stream long enough (>= 1.1 s, the core wants >= 1 s), ask for OFFBOARD, fly the profile
  once OFFBOARD is in force, succeed when close and slow at the end.
- `TakeoffTracker` / `LandTracker`: success or failure of the core's own take-off and landing
  from the vehicle status.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import Enum

from c4d_common.geodesy import GeoOrigin
from c4d_common.plan import LOCAL, Geofence, Item
from c4d_common.plan_validation import VehicleLimits, check_goto
from c4d_common.vehicle import Landed, Mode, Nav

Point3 = tuple[float, float, float]

DEFAULT_SPEED = 2.0  # [m/s] GoTo / FollowPath speed when the goal gives none (<= 0 or NaN)
DEFAULT_RADIUS = 0.3  # [m] GoTo acceptance radius when the goal gives none
TAKEOFF_TOLERANCE = 0.3  # [m] take-off reached when this close to the target altitude (and the core holds)
SLOW = 0.3  # [m/s] "slow" for arrival: the vehicle settles before the goal succeeds
OFFBOARD_AFTER_S = 1.1  # [s] stream this long before asking for OFFBOARD (the core needs >= 1 s live)
OFFBOARD_RETRY_S = 0.5  # [s] between OFFBOARD requests refused as "not yet"
OFFBOARD_GIVE_UP_S = 5.0  # [s] of streaming without OFFBOARD after which the goal aborts
LIMITS = VehicleLimits()  # the vehicle's default ceiling and speeds (as the mission node's go-to)
SETTLE_S = 15.0  # [s] after the profile's end to get within the acceptance radius


def finite(*values: float) -> bool:
    return all(math.isfinite(v) for v in values)


def speed_or_default(speed: float) -> float:
    return speed if math.isfinite(speed) and speed > 0 else DEFAULT_SPEED


def radius_or_default(radius: float) -> float:
    return radius if math.isfinite(radius) and radius > 0 else DEFAULT_RADIUS


# ------------------------------------------------------------------------------ goal checks
@dataclass(frozen=True)
class VehicleView:
    """What the goal checks need of the vehicle: landed state, estimated position (ENU, m from
    home) and home (None until the estimator has an origin)."""

    landed: Landed
    position: Point3 | None
    home: GeoOrigin | None


def flight_refusal(vehicle: VehicleView | None) -> str | None:
    """Why a goal that moves a flying vehicle cannot start now (None: it can)."""
    if vehicle is None or vehicle.position is None:
        return "no vehicle status / estimate yet"
    if vehicle.landed != Landed.IN_AIR:
        return f"the vehicle is not flying (landed state {vehicle.landed.name}): take off first"
    if vehicle.home is None:
        return "no home position yet"
    return None


def leg_refusal(start: Point3, end: Point3, fence: Geofence, home: GeoOrigin,
                limits: VehicleLimits = LIMITS) -> str | None:
    """Why the straight leg start → end is refused: non-finite, outside the altitude band, beyond
    the fence's distance, or leaving its polygon (the rules of a MAVLink go-to, `check_goto`)."""
    issues = check_goto(Item("waypoint", LOCAL, *end), start, fence, home, limits)
    return "; ".join(map(str, issues)) if issues else None


def goal_refusal(target: Point3, vehicle: VehicleView | None, fence: Geofence | None,
                 limits: VehicleLimits = LIMITS) -> str | None:
    """Why a GoTo goal to `target` (map ENU, m) is rejected, or None."""
    if not finite(*target):
        return "target position must be finite"
    refusal = flight_refusal(vehicle)
    if refusal is not None:
        return refusal
    assert vehicle is not None and vehicle.position is not None and vehicle.home is not None
    return leg_refusal(vehicle.position, target, fence or Geofence(), vehicle.home, limits)


@dataclass(frozen=True)
class PathPose:
    """One pose of a nav_msgs/Path as the check needs it: frame and position."""

    frame_id: str
    position: Point3


def path_refusal(frame_id: str, poses: Sequence[PathPose], vehicle: VehicleView | None, fence: Geofence | None,
                 limits: VehicleLimits = LIMITS) -> str | None:
    """Why a FollowPath goal is rejected: empty, not in `map`, a non-finite pose, not flying, or a
    leg (from the vehicle to the first pose, then pose to pose) refused by the fence rules."""
    if not poses:
        return "the path is empty"
    if frame_id != "map":
        return f"the path must be in frame 'map' (got '{frame_id}')"
    for k, pose in enumerate(poses):
        if pose.frame_id not in ("", "map"):
            return f"pose {k}: frame '{pose.frame_id}' is not 'map'"
        if not finite(*pose.position):
            return f"pose {k}: position must be finite"
    refusal = flight_refusal(vehicle)
    if refusal is not None:
        return refusal
    assert vehicle is not None and vehicle.position is not None and vehicle.home is not None
    start = vehicle.position
    for k, pose in enumerate(poses):
        refusal = leg_refusal(start, pose.position, fence or Geofence(), vehicle.home, limits)
        if refusal is not None:
            return f"pose {k}: {refusal}"
        start = pose.position
    return None


# ------------------------------------------------------------------------------ motion profile
@dataclass(frozen=True)
class ProfilePoint:
    position: Point3
    velocity: Point3
    segment: int  # index of the leg being flown (leg k ends at points[k + 1])
    s: float  # [m] arc length flown along the profile
    done: bool  # the profile has ended (at rest at its last point)


@dataclass(frozen=True)
class PathProfile:
    """Constant speed along a polyline, with acceleration `accel` at the start and deceleration at
    the end (a trapezoidal speed over the arc length; a triangle when the path is too short to
    reach `speed`). The speed is lowered so that no leg climbs or sinks faster than
    `vertical_speed`. Corners are flown at speed (the position loop rounds them)."""

    points: tuple[Point3, ...]
    speed: float  # [m/s] cruise, after the vertical limit
    accel: float  # [m/s^2]
    cumulative: tuple[float, ...] = field(repr=False)  # arc length at each point

    @classmethod
    def build(cls, points: Sequence[Point3], speed: float, accel: float, vertical_speed: float) -> PathProfile:
        if len(points) < 1 or speed <= 0 or accel <= 0 or vertical_speed <= 0:
            raise ValueError("a profile needs a point, and positive speed, acceleration and vertical speed")
        cumulative = [0.0]
        steepest = 0.0
        for a, b in zip(points, points[1:], strict=False):
            length = math.dist(a, b)
            cumulative.append(cumulative[-1] + length)
            if length > 0:
                steepest = max(steepest, abs(b[2] - a[2]) / length)
        if steepest > 0:
            speed = min(speed, vertical_speed / steepest)
        return cls(tuple(points), speed, accel, tuple(cumulative))

    @property
    def length(self) -> float:
        return self.cumulative[-1]

    @property
    def peak_speed(self) -> float:
        return min(self.speed, math.sqrt(self.length * self.accel))

    @property
    def duration(self) -> float:
        v = self.peak_speed
        if v <= 0:
            return 0.0
        ramp = v / self.accel
        return 2 * ramp + (self.length - v * ramp) / v

    def arc(self, t: float) -> tuple[float, float]:
        """(arc length, speed) at time t after the start."""
        v, a, length = self.peak_speed, self.accel, self.length
        if v <= 0 or t >= self.duration:
            return length, 0.0
        t = max(0.0, t)
        ramp = v / a
        cruise = self.duration - 2 * ramp
        if t < ramp:
            return 0.5 * a * t * t, a * t
        if t < ramp + cruise:
            return 0.5 * v * ramp + v * (t - ramp), v
        left = self.duration - t
        return length - 0.5 * a * left * left, a * left

    def at(self, t: float) -> ProfilePoint:
        """Setpoint (position on the polyline, velocity along it) at time t after the start."""
        s, speed = self.arc(t)
        done = t >= self.duration
        if len(self.points) == 1:
            return ProfilePoint(self.points[0], (0.0, 0.0, 0.0), 0, 0.0, True)
        k = min(bisect_right(self.cumulative, s) - 1, len(self.points) - 2)
        a, b = self.points[k], self.points[k + 1]
        length = self.cumulative[k + 1] - self.cumulative[k]
        if length <= 0:
            return ProfilePoint(b, (0.0, 0.0, 0.0), k, s, done)
        f = min(1.0, max(0.0, (s - self.cumulative[k]) / length))
        position = tuple(p + f * (q - p) for p, q in zip(a, b, strict=True))
        velocity = tuple(speed * (q - p) / length for p, q in zip(a, b, strict=True))
        return ProfilePoint(position, velocity, k, s, done)  # type: ignore[arg-type]

    def passed(self, s: float) -> int:
        """How many points after the first have been passed at arc length `s`."""
        return sum(1 for c in self.cumulative[1:] if c <= s + 1e-9)


@dataclass(frozen=True)
class Brake:
    """Stop along the current velocity at constant deceleration: the setpoints a cancelled goal
    streams before it commands HOLD. Why: HOLD captures where the vehicle is, so a vehicle at
    cruise speed would overshoot that point by v²/2a and fly back (seen: still > 0.3 m/s 2 s after
    a cancel at 3 m/s); braking first makes HOLD capture a vehicle that has already stopped."""

    start: Point3
    velocity: Point3
    decel: float  # [m/s^2]

    @property
    def duration(self) -> float:
        return math.sqrt(sum(v * v for v in self.velocity)) / self.decel

    def at(self, t: float) -> ProfilePoint:
        speed = math.sqrt(sum(v * v for v in self.velocity))
        t = min(max(t, 0.0), self.duration)
        if speed <= 0:
            return ProfilePoint(self.start, (0.0, 0.0, 0.0), 0, 0.0, True)
        s = speed * t - 0.5 * self.decel * t * t
        left = speed - self.decel * t
        position = tuple(p + s * v / speed for p, v in zip(self.start, self.velocity, strict=True))
        velocity = tuple(left * v / speed for v in self.velocity)
        return ProfilePoint(position, velocity, 0, s, t >= self.duration)  # type: ignore[arg-type]


# ------------------------------------------------------------------------------ goal runs
@dataclass(frozen=True)
class Outcome:
    """The end of a goal: success or not, and one line saying why."""

    success: bool
    message: str


class Phase(Enum):
    WARMUP = "warmup"  # streaming the start point, OFFBOARD not in force yet
    FLYING = "flying"  # OFFBOARD in force, flying the profile
    ENDED = "ended"


@dataclass
class Step:
    """What the action server does on one 50 Hz step of an OffboardRun."""

    setpoint: ProfilePoint
    request_offboard: bool = False  # send vehicle/command SET_MODE OFFBOARD now
    outcome: Outcome | None = None  # the goal ends with this (the server then holds and releases)


class OffboardRun:
    """One GoTo / FollowPath goal over time.

    WARMUP: the start point (where the vehicle was) is streamed at rest; after OFFBOARD_AFTER_S of
    streaming, OFFBOARD is requested (again every OFFBOARD_RETRY_S while it is refused as "not
    yet"), and the goal aborts if OFFBOARD is not in force after OFFBOARD_GIVE_UP_S. FLYING: the
    profile's clock starts when the status first shows OFFBOARD (the vehicle does not chase a
    setpoint that left without it); the goal succeeds once the profile has ended and the vehicle is
    within `radius` of the end and slower than SLOW, and fails when the mode leaves OFFBOARD
    (a failsafe, a pilot, a GCS took over) or the end is not reached SETTLE_S after the profile.
    """

    def __init__(self, profile: PathProfile, radius: float, start_time: float) -> None:
        self.profile = profile
        self.radius = radius
        self.start_time = start_time
        self.phase = Phase.WARMUP
        self.flying_since: float | None = None
        self.next_request = start_time + OFFBOARD_AFTER_S
        self.last_refusal = ""
        self.last: ProfilePoint = profile.at(0.0)

    def refused(self, reason: str, retry: bool) -> Outcome | None:
        """The core's answer to an OFFBOARD request was a refusal: retried later when `retry`
        (a "not yet"), else the goal ends with the reason."""
        self.last_refusal = reason
        if retry:
            return None
        self.phase = Phase.ENDED
        return Outcome(False, f"OFFBOARD refused: {reason}")

    def step(self, now: float, mode: Mode, position: Point3, speed: float) -> Step:
        if self.phase == Phase.WARMUP:
            if mode == Mode.OFFBOARD:
                self.phase, self.flying_since = Phase.FLYING, now
            else:
                if now - self.start_time > OFFBOARD_GIVE_UP_S:
                    self.phase = Phase.ENDED
                    why = f": {self.last_refusal}" if self.last_refusal else ""
                    return Step(self.last, outcome=Outcome(False, f"OFFBOARD not entered within {OFFBOARD_GIVE_UP_S:g} s{why}"))
                request = now >= self.next_request
                if request:
                    self.next_request = now + OFFBOARD_RETRY_S
                return Step(self.profile.at(0.0), request_offboard=request)
        if self.phase == Phase.ENDED:
            return Step(self.last)
        assert self.flying_since is not None
        if mode != Mode.OFFBOARD:
            self.phase = Phase.ENDED
            return Step(self.last, outcome=Outcome(False, f"OFFBOARD left (mode {mode.name}): someone else took the vehicle"))
        t = now - self.flying_since
        self.last = self.profile.at(t)
        end = self.profile.points[-1]
        if self.last.done and math.dist(position, end) <= self.radius and speed < SLOW:
            self.phase = Phase.ENDED
            return Step(self.last, outcome=Outcome(True, "reached"))
        if t > self.profile.duration + SETTLE_S:
            self.phase = Phase.ENDED
            miss = math.dist(position, end)
            return Step(self.last, outcome=Outcome(False, f"not within {self.radius:g} m of the end {SETTLE_S:g} s after "
                                                          f"the profile ({miss:.2f} m away, {speed:.2f} m/s)"))
        return Step(self.last)

    def distance_to_go(self, position: Point3) -> float:
        """Remaining length along the profile from the setpoint, plus how far the vehicle lags it."""
        return self.profile.length - self.last.s + math.dist(position, self.last.position)


# ------------------------------------------------------------------------------ take-off and landing
class TakeoffTracker:
    """The core's take-off (vehicle/command TAKEOFF) seen through the vehicle status: success once
    the core has switched to HOLD after taking off, within TAKEOFF_TOLERANCE of the target (when
    the goal named one; <= 0 = the airframe default, unknown here); failure if the take-off is
    interrupted (another command, a failsafe) or the vehicle disarms."""

    def __init__(self, altitude: float) -> None:
        self.target = altitude if math.isfinite(altitude) and altitude > 0 else math.nan
        self.started = False

    def distance_to_go(self, z: float) -> float:
        return self.target - z if math.isfinite(self.target) else math.nan

    def update(self, armed: bool, mode: Mode, nav: Nav, z: float) -> Outcome | None:
        if nav == Nav.TAKEOFF:
            self.started = True
            return None
        if not self.started:
            return None  # the status has not shown the accepted take-off yet
        close = not math.isfinite(self.target) or abs(z - self.target) < TAKEOFF_TOLERANCE
        if armed and mode == Mode.AUTO and nav == Nav.HOLD and close:
            return Outcome(True, "reached")
        if not armed:
            return Outcome(False, "disarmed during the take-off")
        if mode != Mode.AUTO or nav != Nav.HOLD:
            return Outcome(False, f"take-off interrupted (mode {mode.name}, nav {nav.name})")
        return None


class LandTracker:
    """The core's landing (vehicle/command LAND): success when disarmed on the ground; failure if
    another mode or navigation state takes over while still armed."""

    def __init__(self) -> None:
        self.started = False

    def update(self, armed: bool, landed: Landed, mode: Mode, nav: Nav) -> Outcome | None:
        if armed and nav == Nav.LAND:
            self.started = True
            return None
        if not self.started:
            return None
        if not armed and landed == Landed.ON_GROUND:
            return Outcome(True, "landed and disarmed")
        return Outcome(False, f"landing interrupted (mode {mode.name}, nav {nav.name})")
