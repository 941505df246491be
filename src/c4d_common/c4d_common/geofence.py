"""Geofence geometry: the one check used by pre-flight plan validation and by health in flight.

A `Geofence` (c4d_common.plan) holds an inclusion polygon in geodetic coordinates, a ceiling
above home and a maximum distance from home (each optional). `LocalFence` converts it once to
the local ENU frame of a home position and answers the two questions every user asks: is this
point inside (`breach`), and does the straight leg between two points stay inside (`leg_inside`)?
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
