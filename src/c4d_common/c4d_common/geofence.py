"""Geofence geometry: the one check used by pre-flight plan validation and by health in flight.

A `Geofence` (c4d_common.plan) holds an inclusion polygon in geodetic coordinates, a ceiling
above home and a maximum distance from home (each optional). `LocalFence` converts it once to
the local ENU frame of a home position and answers the two questions every user asks: is this
point inside (`breach`), and does the straight leg between two points stay inside (`leg_inside`)?
`clamp` moves a point that is outside to the nearest point inside (the offboard gateway's
treatment of external position targets beyond the fence).
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


@dataclass(frozen=True)
class LocalFence:
    """A Geofence in the local ENU frame of `home` (metres east, north, up from home)."""

    polygon: tuple[Point2, ...]
    max_altitude: float  # <= 0: none
    max_distance: float  # <= 0: none

    @classmethod
    def from_geofence(cls, fence: Geofence, home: GeoOrigin) -> LocalFence:
        polygon = tuple(home.to_enu(lat, lon, home.altitude)[:2] for lat, lon in fence.polygon)
        return cls(tuple((float(e), float(n)) for e, n in polygon), fence.max_altitude, fence.max_distance)

    def leg_inside(self, a: Point2, b: Point2) -> bool:
        """The horizontal leg a → b stays inside the polygon (True when there is none)."""
        return not self.polygon or leg_inside(a, b, list(self.polygon))

    def clamp(self, position: Point3, margin: float = 0.1) -> Point3:
        """The point inside the fence nearest to `position` (`position` itself when inside): onto
        the polygon, then within max_distance of home, then below the ceiling, each `margin` [m]
        inside its limit so that the result passes `breach`. Why: an external position target
        beyond the fence is flown to the fence instead of being refused (the stream keeps going)."""
        x, y, z = position
        if self.polygon and not point_inside((x, y), list(self.polygon)):
            x, y = pull_inside((x, y), list(self.polygon), margin)
        distance = math.hypot(x, y)
        if self.max_distance > 0 and distance > self.max_distance:
            scale = max(self.max_distance - margin, 0.0) / distance
            x, y = x * scale, y * scale
        if self.max_altitude > 0 and z > self.max_altitude:
            z = self.max_altitude - margin
        return (x, y, z)

    def breach(self, position: Point3) -> Breach | None:
        """The first rule `position` violates (polygon, then ceiling, then distance), or None."""
        here = (position[0], position[1])
        if self.polygon and not point_inside(here, list(self.polygon)):
            return Breach(BreachKind.POLYGON, "outside the inclusion polygon")
        if self.max_altitude > 0 and position[2] > self.max_altitude:
            return Breach(BreachKind.CEILING, f"{position[2]:.1f} m above the {self.max_altitude:g} m ceiling")
        distance = math.hypot(*here)
        if self.max_distance > 0 and distance > self.max_distance:
            return Breach(BreachKind.DISTANCE, f"{distance:.0f} m from home (limit {self.max_distance:g} m)")
        return None
