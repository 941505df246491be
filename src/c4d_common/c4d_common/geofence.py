"""Geofence geometry: the one check used by pre-flight plan validation and by health in flight.

A `Geofence` (c4d_common.plan) holds an inclusion polygon in geodetic coordinates, a ceiling
above home, a maximum distance from home, exclusion polygons, exclusion circles (vertical
cylinders) and a floor above home (each optional). `LocalFence` converts it once to the local
ENU frame of a home position and answers the two questions every user asks: is this point
inside (`breach`), and does the straight leg between two points stay inside (`leg_inside`:
inside the inclusion polygon and through no exclusion zone)? `clamp` moves a point that is
outside to the nearest point inside (the offboard gateway's treatment of external position
targets beyond the fence).

The floor applies while flying only: take-off and landing pass through it, so `breach` judges
it when asked (`with_floor`) and leg checks leave it to the altitude rules of plan validation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

from .geodesy import GeoOrigin
from .plan import Geofence

Point2 = tuple[float, float]
Point3 = tuple[float, float, float]


class BreachKind(Enum):
    POLYGON = "polygon"
    CEILING = "ceiling"
    DISTANCE = "distance"
    EXCLUSION_POLYGON = "exclusion_polygon"
    EXCLUSION_CIRCLE = "exclusion_circle"
    FLOOR = "floor"


@dataclass(frozen=True)
class Breach:
    """Why a point is outside the fence (kind for decisions, text for people)."""

    kind: BreachKind
    text: str


def point_inside(point: Point2, polygon: list[Point2]) -> bool:
    """Even-odd ray casting: is `point` inside the closed `polygon` (vertices in order)?"""
    x, y = point
    inside = False
    for (x1, y1), (x2, y2) in zip(polygon, polygon[1:] + polygon[:1], strict=True):
        if (y1 > y) != (y2 > y) and x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
            inside = not inside
    return inside


def _cross(o: Point2, a: Point2, b: Point2) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def _segments_intersect(p1: Point2, p2: Point2, q1: Point2, q2: Point2) -> bool:
    d1, d2 = _cross(q1, q2, p1), _cross(q1, q2, p2)
    d3, d4 = _cross(p1, p2, q1), _cross(p1, p2, q2)
    return (d1 > 0) != (d2 > 0) and (d3 > 0) != (d4 > 0)


def nearest_on_segment(p: Point2, a: Point2, b: Point2) -> Point2:
    """The point of the segment a–b closest to `p`."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    length2 = dx * dx + dy * dy
    t = 0.0 if length2 == 0.0 else max(0.0, min(1.0, ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / length2))
    return (a[0] + t * dx, a[1] + t * dy)


def pull_inside(point: Point2, polygon: list[Point2], margin: float) -> Point2:
    """A point `margin` inside `polygon` next to the boundary point nearest to `point` (an outside
    point). The nudge goes on along point → boundary (inward at an edge); at an acute vertex where
    that leaves the polygon, towards the vertices' centroid; failing both, the boundary point."""
    edges = zip(polygon, polygon[1:] + polygon[:1], strict=True)
    nearest = min((nearest_on_segment(point, a, b) for a, b in edges), key=lambda q: math.dist(q, point))
    centroid = (sum(v[0] for v in polygon) / len(polygon), sum(v[1] for v in polygon) / len(polygon))
    for source, target in ((point, nearest), (nearest, centroid)):
        dx, dy = target[0] - source[0], target[1] - source[1]
        norm = math.hypot(dx, dy)
        if norm > 0.0:
            candidate = (nearest[0] + margin * dx / norm, nearest[1] + margin * dy / norm)
            if point_inside(candidate, polygon):
                return candidate
    return nearest


def leg_inside(a: Point2, b: Point2, polygon: list[Point2]) -> bool:
    """Both ends inside `polygon` and the segment a–b crosses none of its edges."""
    if not (point_inside(a, polygon) and point_inside(b, polygon)):
        return False
    edges = zip(polygon, polygon[1:] + polygon[:1], strict=True)
    return not any(_segments_intersect(a, b, e1, e2) for e1, e2 in edges)


def segment_circle_distance(a: Point2, b: Point2, centre: Point2) -> float:
    """The least distance from `centre` to the segment a–b."""
    return math.dist(nearest_on_segment(centre, a, b), centre)


def leg_enters_polygon(a: Point2, b: Point2, polygon: list[Point2]) -> bool:
    """The segment a–b touches the inside of `polygon` (an exclusion zone): an end inside, or a
    crossing of one of its edges (a leg through the zone with both ends outside)."""
    if point_inside(a, polygon) or point_inside(b, polygon):
        return True
    edges = zip(polygon, polygon[1:] + polygon[:1], strict=True)
    return any(_segments_intersect(a, b, e1, e2) for e1, e2 in edges)


def _local(home: GeoOrigin, lat: float, lon: float) -> Point2:
    east, north, _ = home.to_enu(lat, lon, home.altitude)
    return float(east), float(north)


@dataclass(frozen=True)
class LocalFence:
    """A Geofence in the local ENU frame of `home` (metres east, north, up from home)."""

    polygon: tuple[Point2, ...]
    max_altitude: float  # <= 0: none
    max_distance: float  # <= 0: none
    exclusion_polygons: tuple[tuple[Point2, ...], ...] = ()
    exclusion_circles: tuple[tuple[float, float, float], ...] = ()  # (east, north, radius [m])
    min_altitude: float = 0.0  # floor [m above home] while flying; <= 0: none

    @classmethod
    def from_geofence(cls, fence: Geofence, home: GeoOrigin) -> LocalFence:
        def local(points: tuple[tuple[float, float], ...]) -> tuple[Point2, ...]:
            return tuple(_local(home, lat, lon) for lat, lon in points)

        circles = tuple((*_local(home, lat, lon), float(radius)) for lat, lon, radius in fence.exclusion_circles)
        return cls(local(fence.polygon), fence.max_altitude, fence.max_distance,
                   tuple(local(p) for p in fence.exclusion_polygons), circles, fence.min_altitude)

    def leg_inside(self, a: Point2, b: Point2) -> bool:
        """The horizontal leg a → b stays inside the polygon (True when there is none)."""
        return not self.polygon or leg_inside(a, b, list(self.polygon))

    def leg_exclusion(self, a: Point2, b: Point2) -> str:
        """Which exclusion zone the horizontal leg a → b enters ("" when none): "exclusion polygon k"
        or "exclusion circle k" (0-based, in the fence's order)."""
        for k, polygon in enumerate(self.exclusion_polygons):
            if leg_enters_polygon(a, b, list(polygon)):
                return f"exclusion polygon {k}"
        for k, (x, y, radius) in enumerate(self.exclusion_circles):
            if segment_circle_distance(a, b, (x, y)) < radius:
                return f"exclusion circle {k}"
        return ""

    def clamp(self, position: Point3, margin: float = 0.1) -> Point3:
        """The point inside the fence nearest to `position` (`position` itself when inside): out of
        the exclusion zones, onto the polygon, then within max_distance of home, then below the
        ceiling, each `margin` [m] inside its limit so that the result passes `breach` (exclusion
        zones overlapping the inclusion boundary may leave it inside one; the floor is not
        clamped: it does not apply to landings). Why: an external position target
        beyond the fence is flown to the fence instead of being refused (the stream keeps going)."""
        x, y, z = position
        x, y = self._out_of_exclusions((x, y), margin)
        if self.polygon and not point_inside((x, y), list(self.polygon)):
            x, y = pull_inside((x, y), list(self.polygon), margin)
        distance = math.hypot(x, y)
        if self.max_distance > 0 and distance > self.max_distance:
            scale = max(self.max_distance - margin, 0.0) / distance
            x, y = x * scale, y * scale
        if self.max_altitude > 0 and z > self.max_altitude:
            z = self.max_altitude - margin
        return (x, y, z)

    def _out_of_exclusions(self, p: Point2, margin: float) -> Point2:
        """`p` moved `margin` outside every exclusion zone it is in (to the nearest boundary point)."""
        for polygon in self.exclusion_polygons:
            if point_inside(p, list(polygon)):
                edges = zip(polygon, polygon[1:] + polygon[:1], strict=True)
                q = min((nearest_on_segment(p, a, b) for a, b in edges), key=lambda c: math.dist(c, p))
                dx, dy = q[0] - p[0], q[1] - p[1]
                norm = math.hypot(dx, dy)
                p = (q[0] + margin * dx / norm, q[1] + margin * dy / norm) if norm > 0 else q
        for cx, cy, radius in self.exclusion_circles:
            rho = math.dist(p, (cx, cy))
            if rho < radius:
                ex, ey = ((p[0] - cx) / rho, (p[1] - cy) / rho) if rho > 1e-9 else (1.0, 0.0)
                p = (cx + (radius + margin) * ex, cy + (radius + margin) * ey)
        return p

    def breach(self, position: Point3, with_floor: bool = False) -> Breach | None:
        """The first rule `position` violates (polygon, ceiling, distance, exclusion polygons,
        exclusion circles, then — only `with_floor`, i.e. while flying — the floor), or None."""
        here = (position[0], position[1])
        if self.polygon and not point_inside(here, list(self.polygon)):
            return Breach(BreachKind.POLYGON, "outside the inclusion polygon")
        if self.max_altitude > 0 and position[2] > self.max_altitude:
            return Breach(BreachKind.CEILING, f"{position[2]:.1f} m above the {self.max_altitude:g} m ceiling")
        distance = math.hypot(*here)
        if self.max_distance > 0 and distance > self.max_distance:
            return Breach(BreachKind.DISTANCE, f"{distance:.0f} m from home (limit {self.max_distance:g} m)")
        for k, polygon in enumerate(self.exclusion_polygons):
            if point_inside(here, list(polygon)):
                return Breach(BreachKind.EXCLUSION_POLYGON, f"inside exclusion polygon {k}")
        for k, (x, y, radius) in enumerate(self.exclusion_circles):
            if math.dist(here, (x, y)) < radius:
                return Breach(BreachKind.EXCLUSION_CIRCLE, f"inside exclusion circle {k} ({radius:g} m)")
        if with_floor and self.min_altitude > 0 and position[2] < self.min_altitude:
            return Breach(BreachKind.FLOOR, f"{position[2]:.1f} m below the {self.min_altitude:g} m floor")
        return None
