"""Mission plan model and its two file formats: the project YAML and QGroundControl `.plan`.

A plan is a list of items (take-off, waypoint, loiter, change speed, land, return to launch,
camera start / stop / by distance / single capture), a geofence (inclusion polygon, maximum
altitude above home, maximum distance from home, exclusion polygons and circles, a floor while
flying), a cruise speed and an RTL altitude.
Positions are global (latitude/longitude in degrees, altitude above home in metres) or local
ENU metres relative to home. Parsing errors are PlanError with one line naming the item.

Project YAML:
    name: survey
    cruise_speed: 4.0            # m/s
    rtl_altitude: 15.0           # m above home
    geofence: {polygon: [[lat, lon], ...], max_altitude: 60, max_distance: 400, min_altitude: 3,
               exclusion_polygons: [[[lat, lon], ...]], exclusion_circles: [{lat: 43.5, lon: 1.4, radius: 10}]}
    items:
      - {type: takeoff, altitude: 10}
      - {type: waypoint, lat: 43.5630, lon: 1.4816, alt: 10, acceptance_radius: 1.0, hold: 0, yaw_deg: 90}
      - {type: waypoint, east: 20, north: 0, alt: 10}          # local ENU relative to home
      - {type: camera_distance, distance: 5}
      - {type: loiter, east: 0, north: 0, alt: 10, hold: 5}
      - {type: change_speed, speed: 6}
      - {type: camera_stop}
      - {type: rtl}
      - {type: land}
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import yaml

from .config_file import yaml_error_text

NAN = float("nan")

ITEM_TYPES = ("takeoff", "waypoint", "loiter", "change_speed", "land", "rtl", "camera_start", "camera_stop",
              "camera_distance", "camera_capture")
GLOBAL, LOCAL = "global", "local"


class PlanError(ValueError):
    """A plan file or plan message that cannot be parsed (one line naming the item)."""


@dataclass(frozen=True)
class Item:
    type: str
    frame: str = LOCAL
    x: float = NAN  # latitude [deg] (global) or east [m] (local); NaN = current
    y: float = NAN  # longitude [deg] or north [m]
    z: float = NAN  # altitude above home [m]
    acceptance_radius: float = 1.0
    hold: float = 0.0  # [s]
    yaw: float = NAN  # [rad] ENU; NaN = face the direction of travel
    speed: float = NAN
    camera_distance: float = 0.0

    @property
    def has_position(self) -> bool:
        """Waypoint, loiter or land with a horizontal position (take-off has only an altitude)."""
        return self.type in ("waypoint", "loiter", "land") and math.isfinite(self.x) and math.isfinite(self.y)


@dataclass(frozen=True)
class Geofence:
    polygon: tuple[tuple[float, float], ...] = ()  # (lat, lon) vertices of the inclusion polygon
    max_altitude: float = 0.0  # <= 0: none
    max_distance: float = 0.0
    exclusion_polygons: tuple[tuple[tuple[float, float], ...], ...] = ()  # each: (lat, lon) vertices
    exclusion_circles: tuple[tuple[float, float, float], ...] = ()  # each: (lat, lon, radius [m])
    min_altitude: float = 0.0  # [m] floor above home while flying; <= 0: none

    @property
    def empty(self) -> bool:
        return not (self.polygon or self.max_altitude > 0 or self.max_distance > 0 or self.exclusion_polygons
                    or self.exclusion_circles or self.min_altitude > 0)


@dataclass(frozen=True)
class Plan:
    items: tuple[Item, ...]
    geofence: Geofence = field(default_factory=Geofence)
    name: str = "plan"
    cruise_speed: float = 0.0  # <= 0: vehicle default
    rtl_altitude: float = 0.0
    plan_id: int = 0

    def with_id(self, plan_id: int) -> Plan:
        return replace(self, plan_id=plan_id)


def _num(item: dict[str, object], key: str, where: str, default: float | None = None) -> float:
    if key not in item:
        if default is None:
            raise PlanError(f"{where}: missing '{key}'")
        return default
    value = item[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise PlanError(f"{where}: '{key}' must be a finite number, got {value!r}")
    return float(value)


def _item_from_yaml(doc: object, k: int) -> Item:
    where = f"item {k + 1}"
    if not isinstance(doc, dict):
        raise PlanError(f"{where}: must be a mapping")
    kind = doc.get("type")
    if kind not in ITEM_TYPES:
        raise PlanError(f"{where}: unknown item type {kind!r} (known: {', '.join(ITEM_TYPES)})")
    allowed = {"type", "lat", "lon", "east", "north", "alt", "altitude", "acceptance_radius", "hold", "yaw_deg",
               "speed", "distance"}
    unknown = set(doc) - allowed
    if unknown:
        raise PlanError(f"{where}: unknown field(s) {', '.join(sorted(unknown))}")
    yaw = math.radians(_num(doc, "yaw_deg", where)) if "yaw_deg" in doc else NAN
    common = {"acceptance_radius": _num(doc, "acceptance_radius", where, 1.0), "hold": _num(doc, "hold", where, 0.0),
              "yaw": yaw}
    if common["acceptance_radius"] <= 0 or common["hold"] < 0:
        raise PlanError(f"{where}: acceptance_radius must be > 0 and hold >= 0")
    if kind == "takeoff":
        return Item(kind, LOCAL, NAN, NAN, _num(doc, "altitude", where), **common)
    if kind in ("waypoint", "loiter", "land"):
        if "lat" in doc or "lon" in doc:
            frame, x, y = GLOBAL, _num(doc, "lat", where), _num(doc, "lon", where)
        elif "east" in doc or "north" in doc:
            frame, x, y = LOCAL, _num(doc, "east", where), _num(doc, "north", where)
        elif kind == "land":
            frame, x, y = LOCAL, NAN, NAN  # land here
        else:
            raise PlanError(f"{where}: {kind} needs lat/lon or east/north")
        z = _num(doc, "alt", where) if kind != "land" else _num(doc, "alt", where, 0.0)
        return Item(kind, frame, x, y, z, **common)
    if kind == "change_speed":
        speed = _num(doc, "speed", where)
        if speed <= 0:
            raise PlanError(f"{where}: speed must be > 0")
        return Item(kind, speed=speed)
    if kind == "camera_distance":
        distance = _num(doc, "distance", where)
        if distance < 0:
            raise PlanError(f"{where}: distance must be >= 0")
        return Item(kind, camera_distance=distance)
    return Item(kind)


FENCE_KEYS = ("polygon", "max_altitude", "max_distance", "min_altitude", "exclusion_polygons", "exclusion_circles")


def _polygon_from_yaml(vertices: object, what: str) -> tuple[tuple[float, float], ...]:
    if not isinstance(vertices, list):
        raise PlanError(f"{what}: must be a list of [lat, lon] vertices")
    polygon = []
    for k, vertex in enumerate(vertices):
        if not (isinstance(vertex, list) and len(vertex) == 2 and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in vertex)):
            raise PlanError(f"{what} vertex {k}: must be [lat, lon]")
        polygon.append((float(vertex[0]), float(vertex[1])))
    if polygon and len(polygon) < 3:
        raise PlanError(f"{what} needs at least 3 vertices")
    return tuple(polygon)


def geofence_from_yaml(fence: object) -> Geofence:
    """The `geofence` mapping of a YAML plan (or a fence file): inclusion `polygon`, `max_altitude`,
    `max_distance`, `min_altitude` (floor while flying), `exclusion_polygons` (a list of vertex
    lists) and `exclusion_circles` (a list of {lat, lon, radius}); PlanError names the bad part."""
    if not isinstance(fence, dict):
        raise PlanError("geofence must be a mapping")
    unknown = set(fence) - set(FENCE_KEYS)
    if unknown:
        raise PlanError(f"geofence: unknown field(s) {', '.join(sorted(map(str, unknown)))} (known: {', '.join(FENCE_KEYS)})")
    polygon = _polygon_from_yaml(fence.get("polygon") or [], "geofence polygon")
    exclusions = fence.get("exclusion_polygons") or []
    if not isinstance(exclusions, list):
        raise PlanError("geofence exclusion_polygons: must be a list of polygons")
    polygons = tuple(_polygon_from_yaml(p, f"geofence exclusion polygon {k}") for k, p in enumerate(exclusions))
    if any(not p for p in polygons):
        raise PlanError("geofence exclusion polygon with no vertices")
    circles: list[tuple[float, float, float]] = []
    raw_circles = fence.get("exclusion_circles") or []
    if not isinstance(raw_circles, list):
        raise PlanError("geofence exclusion_circles: must be a list of {lat, lon, radius}")
    for k, circle in enumerate(raw_circles):
        where = f"geofence exclusion circle {k}"
        if not isinstance(circle, dict) or set(circle) != {"lat", "lon", "radius"}:
            raise PlanError(f"{where}: must be {{lat, lon, radius}}")
        lat, lon, radius = (_num(circle, key, where) for key in ("lat", "lon", "radius"))
        if radius <= 0:
            raise PlanError(f"{where}: radius must be > 0 m")
        circles.append((lat, lon, radius))
    ceiling, floor = _num(fence, "max_altitude", "geofence", 0.0), _num(fence, "min_altitude", "geofence", 0.0)
    if floor > 0 and ceiling > 0 and floor >= ceiling:
        raise PlanError(f"geofence floor {floor:g} m is not below its ceiling {ceiling:g} m")
    return Geofence(polygon, ceiling, _num(fence, "max_distance", "geofence", 0.0), polygons, tuple(circles), floor)


def plan_from_yaml_text(text: str) -> Plan:
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise PlanError(yaml_error_text(exc)) from None
    if not isinstance(doc, dict) or not isinstance(doc.get("items"), list):
        raise PlanError("a plan needs an 'items' list")
    unknown = set(doc) - {"name", "cruise_speed", "rtl_altitude", "geofence", "items"}
    if unknown:
        raise PlanError(f"plan: unknown field(s) {', '.join(sorted(unknown))}")
    geofence = geofence_from_yaml(doc.get("geofence") or {})
    return Plan(tuple(_item_from_yaml(item, k) for k, item in enumerate(doc["items"])), geofence,
                str(doc.get("name", "plan")), _num(doc, "cruise_speed", "plan", 0.0), _num(doc, "rtl_altitude", "plan", 0.0))
