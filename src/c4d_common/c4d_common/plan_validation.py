"""Plan validation before acceptance: every problem is reported item by item.

Checks: item count; coordinates present and finite; altitude above home within the geofence's
(or the vehicle's) maximum and above a minimum clearance; horizontal distance from home;
every leg (segment between consecutive positions, home → take-off → … → RTL) inside the
geofence inclusion polygon (both ends inside and no crossing of a polygon edge); an endurance
estimate (legs at the cruise speed in force, holds, climbs and descents) against the remaining
flight time. A plan with any error is rejected as a whole; warnings do not reject.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .geodesy import GeoOrigin
from .geofence import leg_inside
from .plan import GLOBAL, Geofence, Item, Plan

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


@dataclass(frozen=True)
class ValidationResult:
    errors: tuple[str, ...]
    warnings: tuple[str, ...]
    path_length: float  # [m] horizontal + vertical, home to home
    duration: float  # [s] estimated flight time

    @property
    def ok(self) -> bool:
        return not self.errors


def local_point(item, home: GeoOrigin) -> tuple[float, float, float]:
    if item.frame == GLOBAL:
        e, n, _ = home.to_enu(item.x, item.y, home.altitude)
        return e, n, item.z
    return item.x, item.y, item.z


def validate(plan: Plan, home: GeoOrigin, limits: VehicleLimits = VehicleLimits(),
             endurance_s: float | None = None) -> ValidationResult:
    errors: list[str] = []
    warnings: list[str] = []
    if not plan.items:
        errors.append("plan: no items")
    if len(plan.items) > MAX_ITEMS:
        errors.append(f"plan: {len(plan.items)} items exceed the limit of {MAX_ITEMS}")
    fence = plan.geofence
    ceiling = min(limits.max_altitude, fence.max_altitude) if fence.max_altitude > 0 else limits.max_altitude
    polygon = [home.to_enu(lat, lon, home.altitude)[:2] for lat, lon in fence.polygon]
    speed = plan.cruise_speed if plan.cruise_speed > 0 else limits.default_speed
    rtl_altitude = plan.rtl_altitude if plan.rtl_altitude > 0 else limits.default_rtl_altitude
    position = (0.0, 0.0, 0.0)
    length = duration = 0.0
    airborne = False

    def fly_to(k: int, target: tuple[float, float, float]) -> None:
        nonlocal position, length, duration
        if polygon and not leg_inside(position[:2], target[:2], polygon):
            errors.append(f"item {k}: leg leaves the geofence polygon")
        horizontal = math.hypot(target[0] - position[0], target[1] - position[1])
        vertical = target[2] - position[2]
        length += horizontal + abs(vertical)
        duration += horizontal / speed + (vertical / CLIMB_SPEED if vertical > 0 else -vertical / DESCENT_SPEED)
        position = target

    for k, item in enumerate(plan.items):
        if item.type == "takeoff":
            if not (0 < item.z <= ceiling):
                errors.append(f"item {k}: take-off altitude {item.z:g} m outside (0, {ceiling:g}] m")
            fly_to(k, (position[0], position[1], item.z))
            airborne = True
        elif item.type in ("waypoint", "loiter"):
            if not airborne:
                errors.append(f"item {k}: {item.type} before any take-off")
            if not all(math.isfinite(v) for v in (item.x, item.y, item.z)):
                errors.append(f"item {k}: {item.type} needs a position and an altitude")
                continue
            if item.frame == GLOBAL and not (-90 <= item.x <= 90 and -180 <= item.y <= 180):
                errors.append(f"item {k}: latitude/longitude out of range")
                continue
            target = local_point(item, home)
            if target[2] > ceiling:
                errors.append(f"item {k}: altitude {target[2]:g} m above the maximum {ceiling:g} m")
            elif target[2] < MIN_ALTITUDE:
                errors.append(f"item {k}: altitude {target[2]:g} m below the minimum {MIN_ALTITUDE:g} m")
            distance = math.hypot(target[0], target[1])
            if fence.max_distance > 0 and distance > fence.max_distance:
                errors.append(f"item {k}: {distance:.0f} m from home exceeds the geofence's {fence.max_distance:g} m")
            fly_to(k, target)
            duration += item.hold
        elif item.type == "change_speed":
            if item.speed > limits.max_speed:
                errors.append(f"item {k}: speed {item.speed:g} m/s above the vehicle's {limits.max_speed:g} m/s")
            speed = min(item.speed, limits.max_speed)
        elif item.type == "rtl":
            if rtl_altitude > ceiling:
                errors.append(f"item {k}: RTL altitude {rtl_altitude:g} m above the maximum {ceiling:g} m")
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
    if endurance_s is not None and endurance_s > 0:
        if duration > 0.8 * endurance_s:
            errors.append(f"plan: estimated {duration:.0f} s of flight exceeds 80 % of the {endurance_s:.0f} s left")
        elif duration > 0.6 * endurance_s:
            warnings.append(f"plan: estimated {duration:.0f} s of flight uses over 60 % of the {endurance_s:.0f} s left")
    if airborne:
        warnings.append("plan: ends in the air (no land or RTL item)")
    return ValidationResult(tuple(errors), tuple(warnings), length, duration)


def check_goto(target: Item, position: tuple[float, float, float], fence: Geofence, home: GeoOrigin,
               limits: VehicleLimits = VehicleLimits()) -> list[str]:
    """Why a go-to (DO_REPOSITION) from `position` (ENU, m) to `target` must be refused: the
    same altitude, distance and polygon rules as a plan leg, applied to the one leg flown now."""
    if not all(math.isfinite(v) for v in (target.x, target.y, target.z)):
        return ["go-to target needs a finite position and altitude"]
    if target.frame == GLOBAL and not (-90 <= target.x <= 90 and -180 <= target.y <= 180):
        return ["go-to target latitude/longitude out of range"]
    ceiling = min(limits.max_altitude, fence.max_altitude) if fence.max_altitude > 0 else limits.max_altitude
    point = local_point(target, home)
    errors = []
    if not MIN_ALTITUDE <= point[2] <= ceiling:
        errors.append(f"go-to altitude {point[2]:g} m outside [{MIN_ALTITUDE:g}, {ceiling:g}] m")
    if fence.max_distance > 0 and math.hypot(point[0], point[1]) > fence.max_distance:
        errors.append(f"go-to target {math.hypot(point[0], point[1]):.0f} m from home exceeds the geofence's "
                      f"{fence.max_distance:g} m")
    polygon = [home.to_enu(lat, lon, home.altitude)[:2] for lat, lon in fence.polygon]
    if polygon and not leg_inside(position[:2], point[:2], polygon):
        errors.append("go-to leg leaves the geofence polygon")
    return errors
