"""The simulated world around the vehicle: static obstacles, moving obstacles and the wind field.

Why a model of its own: the lidar (lidar.py) renders scans from it, the sim publishes it as the
truth on `sim/obstacles`, and tests measure the vehicle's true clearance against it — all three
must agree on one geometry. It is read from a world YAML file (docs/flight_loop.md, "World file";
examples in worlds/), strictly: an unknown or malformed field is one line naming it.

Geometry is in the home ENU frame (`map`, metres, the frame of sim/ground_truth). Every obstacle
is a vertical prism standing on the ground (z = 0) up to its height:
- cylinder: centre (x, y), radius;
- box: centre (x, y), size (along its own x, y), yaw (rad, ENU, counter-clockwise from east);
- wall: a box between two end points (length = their distance, width = thickness);
- mover: a cylinder whose centre travels along a polyline at a constant speed, either looping
  (back to the first point after the last) or back and forth.
The wind is a mean vector plus a (1 - cos) gust along the mean's horizontal direction (east when
the mean has none), the gust model the sim had before worlds existed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from c4d_common.config_file import ConfigError, read_yaml_mapping, reject_unknown

Vec3 = tuple[float, float, float]


class WorldError(ConfigError):
    """The world file is unusable; the text is one line naming the field."""


@dataclass(frozen=True)
class Cylinder:
    """A vertical cylinder standing on the ground."""

    x: float
    y: float
    radius: float
    height: float

    def distance(self, px: float, py: float) -> float:
        """[m] horizontal distance from (px, py) to the surface (negative inside)."""
        return math.hypot(px - self.x, py - self.y) - self.radius


@dataclass(frozen=True)
class Box:
    """A box standing on the ground, rotated by `yaw` about its centre (walls are boxes too)."""

    x: float
    y: float
    size_x: float
    size_y: float
    yaw: float
    height: float

    @property
    def bounding_radius(self) -> float:
        return 0.5 * math.hypot(self.size_x, self.size_y)

    def distance(self, px: float, py: float) -> float:
        """[m] horizontal distance from (px, py) to the surface (negative inside)."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        dx, dy = px - self.x, py - self.y
        qx, qy = abs(c * dx + s * dy) - 0.5 * self.size_x, abs(-s * dx + c * dy) - 0.5 * self.size_y
        outside = math.hypot(max(qx, 0.0), max(qy, 0.0))
        return outside if outside > 0.0 else max(qx, qy)


@dataclass(frozen=True)
class Mover:
    """A vertical cylinder whose centre moves along `path` at `speed`, looping or back and forth."""

    path: tuple[tuple[float, float], ...]
    speed: float  # [m/s]
    radius: float
    height: float
    back_and_forth: bool
    _cumulative: tuple[float, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        points = list(self.path) + ([] if self.back_and_forth else [self.path[0]])
        lengths = [0.0]
        for (ax, ay), (bx, by) in zip(points, points[1:], strict=False):
            lengths.append(lengths[-1] + math.hypot(bx - ax, by - ay))
        object.__setattr__(self, "_cumulative", tuple(lengths))

    def _points(self) -> list[tuple[float, float]]:
        return list(self.path) + ([] if self.back_and_forth else [self.path[0]])

    def state(self, t: float) -> tuple[tuple[float, float], tuple[float, float]]:
        """((x, y) [m], (vx, vy) [m/s]) at time t [s] (t = 0: at the first point, heading to the second)."""
        total = self._cumulative[-1]
        s = self.speed * max(0.0, t)
        sign = 1.0
        if self.back_and_forth:
            s %= 2.0 * total
            if s > total:
                s, sign = 2.0 * total - s, -1.0
        else:
            s %= total
        points, cum = self._points(), self._cumulative
        i = 0
        while i < len(cum) - 2 and s > cum[i + 1]:
            i += 1
        (ax, ay), (bx, by) = points[i], points[i + 1]
        seg = cum[i + 1] - cum[i]
        u = (s - cum[i]) / seg if seg > 0 else 0.0
        ux, uy = ((bx - ax) / seg, (by - ay) / seg) if seg > 0 else (0.0, 0.0)
        return (ax + u * (bx - ax), ay + u * (by - ay)), (sign * self.speed * ux, sign * self.speed * uy)

    def cylinder(self, t: float) -> Cylinder:
        (x, y), _ = self.state(t)
        return Cylinder(x, y, self.radius, self.height)


@dataclass(frozen=True)
class WindField:
    """Mean wind plus a (1 - cos) gust of `gust` amplitude and `gust_period` along the mean's
    horizontal direction (east when the mean is vertical or zero). Wind = air-mass velocity."""

    mean: Vec3 = (0.0, 0.0, 0.0)  # [m/s] ENU
    gust: float = 0.0  # [m/s]
    gust_period: float = 6.0  # [s]

    def at(self, t: float, extra_gust: float = 0.0) -> Vec3:
        """[m/s] ENU air velocity at time t; `extra_gust` adds to the amplitude (the sim's gust fault)."""
        g = (self.gust + extra_gust) * 0.5 * (1.0 - math.cos(2.0 * math.pi * t / self.gust_period))
        h = math.hypot(self.mean[0], self.mean[1])
        ux, uy = (self.mean[0] / h, self.mean[1] / h) if h > 1e-9 else (1.0, 0.0)
        return (self.mean[0] + g * ux, self.mean[1] + g * uy, self.mean[2])


@dataclass(frozen=True)
class World:
    """Static obstacles, movers and (optionally) the wind field that replaces the sim config's."""

    cylinders: tuple[Cylinder, ...] = ()
    boxes: tuple[Box, ...] = ()  # walls included
    movers: tuple[Mover, ...] = ()
    wind: WindField | None = None
    name: str = ""

    @property
    def obstacle_count(self) -> int:
        return len(self.cylinders) + len(self.boxes) + len(self.movers)

    def cylinders_at(self, t: float) -> list[Cylinder]:
        """The static cylinders and the movers at time t."""
        return list(self.cylinders) + [m.cylinder(t) for m in self.movers]

    def clearance(self, x: float, y: float, z: float, t: float) -> float:
        """[m] distance from the point to the nearest obstacle (horizontal while below its top,
        3-D to its top edge above it); inf without obstacles. What tests compare with the protection radius."""
        best = math.inf
        shapes: list[Cylinder | Box] = [*self.cylinders_at(t), *self.boxes]
        for shape in shapes:
            d = shape.distance(x, y)
            above = z - shape.height
            if above > 0.0:
                d = math.hypot(max(d, 0.0), above)
            best = min(best, d)
        return best


# --- loading ---------------------------------------------------------------------------------------------

def _num(doc: dict[str, Any], key: str, where: str, low: float | None = None, positive: bool = False,
         default: float | None = None) -> float:
    if key not in doc and default is not None:
        return default
    value: Any = doc.get(key)
    bad = isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value)
    if bad or (positive and value <= 0) or (low is not None and value < low):
        need = "a positive number" if positive else (f"a number >= {low:g}" if low is not None else "a number")
        raise WorldError(f"world: field '{where}{key}' must be {need}, got {value!r}")
    return float(value)


def _point(value: Any, where: str, n: int = 2) -> tuple[float, ...]:
    if (not isinstance(value, list) or len(value) != n
            or any(isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) for v in value)):
        raise WorldError(f"world: field '{where}' must be a list of {n} numbers, got {value!r}")
    return tuple(float(v) for v in value)


def _entries(doc: dict[str, Any], key: str) -> list[dict[str, Any]]:
    items = doc.get(key) or []
    if not isinstance(items, list) or not all(isinstance(i, dict) for i in items):
        raise WorldError(f"world: field '{key}' must be a list of mappings")
    return items


def _cylinder(d: dict[str, Any], w: str) -> Cylinder:
    reject_unknown(d, {"center", "radius", "height"}, f"world: {w}", WorldError)
    x, y = _point(d.get("center"), w + ".center")
    return Cylinder(x, y, _num(d, "radius", w + ".", positive=True), _num(d, "height", w + ".", positive=True))


def _box(d: dict[str, Any], w: str) -> Box:
    reject_unknown(d, {"center", "size", "yaw_deg", "height"}, f"world: {w}", WorldError)
    x, y = _point(d.get("center"), w + ".center")
    sx, sy = _point(d.get("size"), w + ".size")
    if sx <= 0 or sy <= 0:
        raise WorldError(f"world: field '{w}.size' must be two positive numbers, got {[sx, sy]!r}")
    return Box(x, y, sx, sy, math.radians(_num(d, "yaw_deg", w + ".", default=0.0)),
               _num(d, "height", w + ".", positive=True))


def _wall(d: dict[str, Any], w: str) -> Box:
    reject_unknown(d, {"from", "to", "thickness", "height"}, f"world: {w}", WorldError)
    (ax, ay), (bx, by) = _point(d.get("from"), w + ".from"), _point(d.get("to"), w + ".to")
    length = math.hypot(bx - ax, by - ay)
    if length <= 0:
        raise WorldError(f"world: field '{w}.to' must differ from '{w}.from'")
    return Box(0.5 * (ax + bx), 0.5 * (ay + by), length, _num(d, "thickness", w + ".", positive=True, default=0.2),
               math.atan2(by - ay, bx - ax), _num(d, "height", w + ".", positive=True))


def _mover(d: dict[str, Any], w: str) -> Mover:
    reject_unknown(d, {"path", "speed", "radius", "height", "mode"}, f"world: {w}", WorldError)
    path = d.get("path")
    if not isinstance(path, list) or len(path) < 2:
        raise WorldError(f"world: field '{w}.path' must be a list of at least 2 [x, y] points")
    points = tuple((x, y) for x, y in (_point(p, f"{w}.path[{i}]") for i, p in enumerate(path)))
    mode = d.get("mode", "loop")
    if mode not in ("loop", "back_and_forth"):
        raise WorldError(f"world: field '{w}.mode' must be 'loop' or 'back_and_forth', got {mode!r}")
    if all(p == points[0] for p in points):
        raise WorldError(f"world: field '{w}.path' must not be a single point")
    return Mover(points, _num(d, "speed", w + ".", positive=True), _num(d, "radius", w + ".", positive=True),
                 _num(d, "height", w + ".", positive=True), mode == "back_and_forth")


def parse_wind(doc: Any, where: str = "wind") -> WindField:
    """A wind mapping {mean_enu_m_s: [e, n, u], gust_m_s, gust_period_s} (the sim config's format)."""
    if not isinstance(doc, dict):
        raise WorldError(f"world: field '{where}' must be a mapping")
    reject_unknown(doc, {"mean_enu_m_s", "gust_m_s", "gust_period_s"}, f"world: {where}", WorldError)
    mean = _point(doc.get("mean_enu_m_s", [0.0, 0.0, 0.0]), where + ".mean_enu_m_s", 3)
    return WindField((mean[0], mean[1], mean[2]), _num(doc, "gust_m_s", where + ".", low=0.0, default=0.0),
                     _num(doc, "gust_period_s", where + ".", positive=True, default=6.0))


def load_world(path: str | Path) -> World:
    """Read a world YAML file; WorldError (one line naming the field) when it is unusable."""
    doc = read_yaml_mapping(path, "world", WorldError)
    reject_unknown(doc, {"name", "cylinders", "boxes", "walls", "movers", "wind"}, "world", WorldError)
    return World(
        cylinders=tuple(_cylinder(d, f"cylinders[{i}]") for i, d in enumerate(_entries(doc, "cylinders"))),
        boxes=tuple(_box(d, f"boxes[{i}]") for i, d in enumerate(_entries(doc, "boxes")))
        + tuple(_wall(d, f"walls[{i}]") for i, d in enumerate(_entries(doc, "walls"))),
        movers=tuple(_mover(d, f"movers[{i}]") for i, d in enumerate(_entries(doc, "movers"))),
        wind=parse_wind(doc["wind"]) if "wind" in doc else None,
        name=str(doc.get("name", Path(path).stem)),
    )


@dataclass(frozen=True)
class TruthObstacle:
    """One obstacle as the simulator knows it (sim/obstacles): ids are stable, 1-based, in file order
    (cylinders, boxes, walls, movers)."""

    id: int
    x: float
    y: float
    vx: float
    vy: float
    radius: float  # [m] horizontal bounding circle
    height: float


def truth(world: World, t: float) -> list[TruthObstacle]:
    """Every obstacle of `world` at time t, with its bounding circle and velocity."""
    out = [TruthObstacle(i + 1, c.x, c.y, 0.0, 0.0, c.radius, c.height) for i, c in enumerate(world.cylinders)]
    out += [TruthObstacle(len(out) + i + 1, b.x, b.y, 0.0, 0.0, b.bounding_radius, b.height)
            for i, b in enumerate(world.boxes)]
    for m in world.movers:
        (x, y), (vx, vy) = m.state(t)
        out.append(TruthObstacle(len(out) + 1, x, y, vx, vy, m.radius, m.height))
    return out
