"""Plan validation before acceptance: every problem is reported item by item.

Checks: item count; coordinates present and finite; altitude above home within the geofence's
(or the vehicle's) maximum and above a minimum clearance; horizontal distance from home;
every leg (segment between consecutive positions, home → take-off → … → RTL) inside the
geofence inclusion polygon (both ends inside and no crossing of a polygon edge) and through none
of its exclusion polygons / circles; take-off, waypoint and loiter altitudes not below the
geofence floor (take-off and landing pass through it); an endurance
estimate (legs at the cruise speed in force, holds, climbs and descents) against the remaining
flight time. A plan with any error is rejected as a whole; warnings do not reject. A waypoint
or loiter flown from the ground (no take-off item before it, as PX4 allows) is preceded by a
take-off to its altitude, at least `VehicleLimits.takeoff_altitude` (PX4: MIS_TAKEOFF_ALT): the
mission executor inserts it, the estimate counts it.

Every problem is a `PlanIssue` (kind, item, text): callers decide on the kind, people read the
text (`str(issue)`), so no decision depends on a message's wording.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

from .geodesy import GeoOrigin
from .geofence import LocalFence, leg_inside, point_inside
from .plan import GLOBAL, Geofence, Item, Plan

__all__ = ["IssueKind", "PlanIssue", "ValidationResult", "VehicleLimits", "ceiling_of", "check_goto", "flight_time_left",
           "leg_inside", "local_point", "validate"]

MAX_ITEMS = 500
DEFAULT_MAX_ALTITUDE = 120.0  # [m] above home, the usual open-category ceiling
MIN_ALTITUDE = 1.0  # [m] waypoints below this would scrape the ground
CLIMB_SPEED, DESCENT_SPEED = 1.5, 0.7


@dataclass(frozen=True)
class VehicleLimits:
    max_altitude: float = DEFAULT_MAX_ALTITUDE
    default_speed: float = 5.0
    max_speed: float = 8.0
    default_rtl_altitude: float = 15.0
    takeoff_altitude: float = 2.5  # [m] least altitude of the take-off before a waypoint flown from the ground


class IssueKind(Enum):
    """What is wrong with a plan or a go-to target (the decision-relevant part of a PlanIssue)."""

    NO_ITEMS = "no items"
    TOO_MANY_ITEMS = "too many items"
    TAKEOFF_ALTITUDE = "take-off altitude"
    NO_POSITION = "no finite position"  # the target itself is malformed: never forced
    COORDINATES_OUT_OF_RANGE = "coordinates out of range"  # malformed too
    ABOVE_CEILING = "above the ceiling"
    BELOW_MINIMUM = "below the minimum altitude"
    OUTSIDE_ALTITUDE_BAND = "outside the altitude band"
    TOO_FAR = "too far from home"
    LEAVES_POLYGON = "leaves the polygon"
    ENTERS_EXCLUSION = "enters an exclusion zone"
    BELOW_FLOOR = "below the geofence floor"
    SPEED = "speed above the vehicle's"
    RTL_ALTITUDE = "RTL altitude above the ceiling"
    ENDURANCE = "exceeds the endurance"
    ENDURANCE_MARGIN = "uses most of the endurance"  # warning
    ENDS_IN_AIR = "ends in the air"  # warning
    NO_HOME = "no home position"  # acceptance: the estimator has no origin yet
    MISSION_ACTIVE = "a mission is active"  # acceptance: the running plan cannot be replaced
    BATTERY_UNKNOWN = "battery state unknown"  # acceptance: no battery report yet, the endurance cannot be checked

    @property
    def malformed(self) -> bool:
        """The request itself is unusable (a go-to's `force` cannot override it)."""
        return self in (IssueKind.NO_POSITION, IssueKind.COORDINATES_OUT_OF_RANGE)


@dataclass(frozen=True)
class PlanIssue:
    """One problem: `kind` for decisions, `item` (index, None for the whole plan), `text` for people."""

    kind: IssueKind
    item: int | None
    text: str

    def __str__(self) -> str:
        return self.text


@dataclass(frozen=True)
class ValidationResult:
    issues: tuple[PlanIssue, ...]  # errors: any rejects the plan
    notices: tuple[PlanIssue, ...]  # warnings: reported, the plan is accepted
    path_length: float  # [m] horizontal + vertical, home to home
    duration: float  # [s] estimated flight time

    @property
    def ok(self) -> bool:
        return not self.issues

    @property
    def errors(self) -> tuple[str, ...]:
        return tuple(i.text for i in self.issues)

    @property
    def warnings(self) -> tuple[str, ...]:
        return tuple(i.text for i in self.notices)


def flight_time_left(charge_ah: float, hover_current_a: float, reserve: float = 0.2) -> float | None:
    """Flight time left [s] at hover current from the battery's remaining charge, keeping
    `reserve` (a fraction) untouched; None when the charge is unknown (NaN, negative), 0 when empty.
    With the pack's full capacity it is the endurance `c4d fly` checks offline, before anything starts."""
    if not math.isfinite(charge_ah) or charge_ah < 0 or not math.isfinite(hover_current_a) or hover_current_a <= 0:
        return None
    return charge_ah * (1.0 - reserve) / hover_current_a * 3600.0


def label(index: int) -> str:
    """How an item is named to people: 1-based, as in the plan file and QGroundControl's list
    (`PlanIssue.item` keeps the 0-based index for programs)."""
    return f"item {index + 1}"


def local_point(item: Item, home: GeoOrigin) -> tuple[float, float, float]:
    if item.frame == GLOBAL:
        e, n, _ = home.to_enu(item.x, item.y, home.altitude)
        return e, n, item.z
    return item.x, item.y, item.z


def validate(plan: Plan, home: GeoOrigin, limits: VehicleLimits = VehicleLimits(),
             endurance_s: float | None = None) -> ValidationResult:
    errors: list[PlanIssue] = []
    warnings: list[PlanIssue] = []

    def error(kind: IssueKind, item: int | None, text: str) -> None:
        errors.append(PlanIssue(kind, item, text))

    if not plan.items:
        error(IssueKind.NO_ITEMS, None, "plan: no items")
    if len(plan.items) > MAX_ITEMS:
        error(IssueKind.TOO_MANY_ITEMS, None, f"plan: {len(plan.items)} items exceed the limit of {MAX_ITEMS}")
    fence = LocalFence.from_geofence(plan.geofence, home)
    ceiling = ceiling_of(plan.geofence, limits)
    speed = plan.cruise_speed if plan.cruise_speed > 0 else limits.default_speed
    rtl_altitude = plan.rtl_altitude if plan.rtl_altitude > 0 else limits.default_rtl_altitude
    position = (0.0, 0.0, 0.0)
    length = duration = 0.0
    airborne = False

    def fly_to(k: int, target: tuple[float, float, float]) -> None:
        """One straight leg; a polygon error names one fact about item k: its point lies outside, or
        (both ends inside) its leg cuts a corner. The way back from an outside point is not a new error."""
        nonlocal position, length, duration
        if not fence.leg_inside(position[:2], target[:2]) and not any(
                e.kind is IssueKind.LEAVES_POLYGON and e.item == k for e in errors):
            if not point_inside(target[:2], list(fence.polygon)):
                error(IssueKind.LEAVES_POLYGON, k, f"{label(k)}: outside the geofence polygon")
            elif point_inside(position[:2], list(fence.polygon)):
                error(IssueKind.LEAVES_POLYGON, k, f"{label(k)}: leg leaves the geofence polygon")
        zone = fence.leg_exclusion(position[:2], target[:2])
        if zone and not any(e.kind is IssueKind.ENTERS_EXCLUSION and e.item == k for e in errors):
            error(IssueKind.ENTERS_EXCLUSION, k, f"{label(k)}: leg enters the geofence's {zone}")
        horizontal = math.hypot(target[0] - position[0], target[1] - position[1])
        vertical = target[2] - position[2]
        length += horizontal + abs(vertical)
        duration += horizontal / speed + (vertical / CLIMB_SPEED if vertical > 0 else -vertical / DESCENT_SPEED)
        position = target

    for k, item in enumerate(plan.items):
        if item.type == "takeoff":
            if not (0 < item.z <= ceiling):
                error(IssueKind.TAKEOFF_ALTITUDE, k, f"{label(k)}: take-off altitude {item.z:g} m outside (0, {ceiling:g}] m")
            elif fence.min_altitude > 0 and item.z < fence.min_altitude:
                error(IssueKind.BELOW_FLOOR, k, f"{label(k)}: take-off altitude {item.z:g} m below the geofence floor "
                                                f"{fence.min_altitude:g} m")
            fly_to(k, (position[0], position[1], item.z))
            airborne = True
        elif item.type in ("waypoint", "loiter"):
            if not all(math.isfinite(v) for v in (item.x, item.y, item.z)):
                error(IssueKind.NO_POSITION, k, f"{label(k)}: {item.type} needs a position and an altitude")
                continue
            if item.frame == GLOBAL and not (-90 <= item.x <= 90 and -180 <= item.y <= 180):
                error(IssueKind.COORDINATES_OUT_OF_RANGE, k, f"{label(k)}: latitude/longitude out of range")
                continue
            target = local_point(item, home)
            if target[2] > ceiling:
                error(IssueKind.ABOVE_CEILING, k, f"{label(k)}: altitude {target[2]:g} m above the maximum {ceiling:g} m")
            elif target[2] < MIN_ALTITUDE:
                error(IssueKind.BELOW_MINIMUM, k, f"{label(k)}: altitude {target[2]:g} m below the minimum {MIN_ALTITUDE:g} m")
            elif fence.min_altitude > 0 and target[2] < fence.min_altitude:
                error(IssueKind.BELOW_FLOOR, k, f"{label(k)}: altitude {target[2]:g} m below the geofence floor "
                                                f"{fence.min_altitude:g} m")
            distance = math.hypot(target[0], target[1])
            if fence.max_distance > 0 and distance > fence.max_distance:
                error(IssueKind.TOO_FAR, k,
                      f"{label(k)}: {distance:.0f} m from home exceeds the geofence's {fence.max_distance:g} m")
            if not airborne:  # flown from the ground: the executor takes off first
                climb = max(target[2], limits.takeoff_altitude)
                if climb > ceiling:
                    error(IssueKind.TAKEOFF_ALTITUDE, k, f"{label(k)}: take-off altitude {climb:g} m above the maximum "
                                                         f"{ceiling:g} m")
                fly_to(k, (position[0], position[1], climb))
                airborne = True
            fly_to(k, target)
            duration += item.hold
        elif item.type == "change_speed":
            if item.speed > limits.max_speed:
                error(IssueKind.SPEED, k, f"{label(k)}: speed {item.speed:g} m/s above the vehicle's {limits.max_speed:g} m/s")
            speed = min(item.speed, limits.max_speed)
        elif item.type == "rtl":
            if rtl_altitude > ceiling:
                error(IssueKind.RTL_ALTITUDE, k, f"{label(k)}: RTL altitude {rtl_altitude:g} m above the maximum {ceiling:g} m")
            fly_to(k, (position[0], position[1], max(position[2], rtl_altitude)))
            fly_to(k, (0.0, 0.0, position[2]))
            fly_to(k, (0.0, 0.0, 0.0))
            airborne = False
        elif item.type == "land":
            if math.isfinite(item.x) and math.isfinite(item.y):
                target = local_point(item, home)
                fly_to(k, (target[0], target[1], position[2]))
            fly_to(k, (position[0], position[1], 0.0))
            airborne = False
    if endurance_s is not None:  # None: not checked (the mission node refuses instead: BATTERY_UNKNOWN)
        if duration > 0.8 * endurance_s:
            error(IssueKind.ENDURANCE, None,
                  f"plan: estimated {duration:.0f} s of flight exceeds 80 % of the {endurance_s:.0f} s left")
        elif duration > 0.6 * endurance_s:
            margin = f"plan: estimated {duration:.0f} s of flight uses over 60 % of the {endurance_s:.0f} s left"
            warnings.append(PlanIssue(IssueKind.ENDURANCE_MARGIN, None, margin))
    if airborne:
        warnings.append(PlanIssue(IssueKind.ENDS_IN_AIR, None, "plan: ends in the air (no land or RTL item)"))
    return ValidationResult(tuple(errors), tuple(warnings), length, duration)


def ceiling_of(fence: Geofence, limits: VehicleLimits) -> float:
    """The altitude limit above home in force: the vehicle's, lowered by the fence's if it has one."""
    return min(limits.max_altitude, fence.max_altitude) if fence.max_altitude > 0 else limits.max_altitude


def check_goto(target: Item, position: tuple[float, float, float], fence: Geofence, home: GeoOrigin,
               limits: VehicleLimits = VehicleLimits()) -> list[PlanIssue]:
    """Why a go-to (DO_REPOSITION) from `position` (ENU, m) to `target` must be refused: the
    same altitude, distance, polygon, exclusion and floor rules as a plan leg, applied to the one
    leg flown now (`fence`: the fence in force, geofence/active)."""
    if not all(math.isfinite(v) for v in (target.x, target.y, target.z)):
        return [PlanIssue(IssueKind.NO_POSITION, None, "go-to target needs a finite position and altitude")]
    if target.frame == GLOBAL and not (-90 <= target.x <= 90 and -180 <= target.y <= 180):
        return [PlanIssue(IssueKind.COORDINATES_OUT_OF_RANGE, None, "go-to target latitude/longitude out of range")]
    ceiling = ceiling_of(fence, limits)
    point = local_point(target, home)
    local = LocalFence.from_geofence(fence, home)
    issues = []
    if not MIN_ALTITUDE <= point[2] <= ceiling:
        issues.append(PlanIssue(IssueKind.OUTSIDE_ALTITUDE_BAND, None,
                                f"go-to altitude {point[2]:g} m outside [{MIN_ALTITUDE:g}, {ceiling:g}] m"))
    distance = math.hypot(point[0], point[1])
    if local.max_distance > 0 and distance > local.max_distance:
        issues.append(PlanIssue(IssueKind.TOO_FAR, None, f"go-to target {distance:.0f} m from home exceeds the geofence's "
                                                         f"{local.max_distance:g} m"))
    if not local.leg_inside(position[:2], point[:2]):
        issues.append(PlanIssue(IssueKind.LEAVES_POLYGON, None, "go-to leg leaves the geofence polygon"))
    zone = local.leg_exclusion(position[:2], point[:2])
    if zone:
        issues.append(PlanIssue(IssueKind.ENTERS_EXCLUSION, None, f"go-to leg enters the geofence's {zone}"))
    if local.min_altitude > 0 and point[2] < local.min_altitude:
        issues.append(PlanIssue(IssueKind.BELOW_FLOOR, None, f"go-to altitude {point[2]:g} m below the geofence floor "
                                                             f"{local.min_altitude:g} m"))
    return issues
