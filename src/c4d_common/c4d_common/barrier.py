"""Potential barriers for obstacles and the geofence (D3.3 §6.7): an APF term and a braking cap on the
velocity setpoint, plus a blocked-progress detector that adds a tangential detour.

Why: the position loop must keep the vehicle off obstacles and inside the fence whatever the guided
setpoint asks (mission leg, go-to, RTL, offboard). D3.3 §6.7 asks for a potential that is bounded in
range (zero beyond the detection range D), infinite at the protection radius r, decreasing with the
distance, with continuous first and second derivatives. The potential used here, for a distance
d to the surface of an obstacle or to the fence boundary, is

    U(d) = (D - d)^3 / ((D - r)(d - r))    for r < d < D,    U(d) = 0 for d >= D,

(a dimensionless form is s^3 / (1 - s) with s = (D - d)/(D - r)). With u = D - d, w = d - r, c = D - r:

    U'(d)  = -(3 u^2 w + u^3) / (c w^2)                    < 0 on (r, D): strictly decreasing
    U''(d) = (6 u w^2 + 6 u^2 w + 2 u^3) / (c w^3)         > 0 on (r, D)

At d = D (u = 0) U, U' and U'' are 0 from the left, equal to the zero branch on the right: U is C^2
on (r, inf) (the third derivative jumps by -6/c^2, so exactly C^2); as d -> r+ (w -> 0+) U -> +inf
(and -U' -> +inf). src/c4d_common/test/test_barrier.py checks each property analytically and by
finite differences.

The repulsion is the force -U'(d) along the surface normal n (from the surface towards the vehicle),
scaled by `gain` [m/s per unit force] and saturated at `max_repulsion` [m/s] (a velocity setpoint
cannot be infinite; the potential is). On top, a braking cap bounds the speed of approach to every
surface (relative to the surface's own velocity, so movers count with their closing speed) by the
speed that still stops `margin` outside the protection radius with the vehicle's velocity-loop lag
tau and deceleration a: v·tau + v^2/(2a) = d - r - margin (minus closing speed x tau for a mover
coming closer: it keeps coming while the vehicle responds). The cap is what guarantees "never
crosses" at any speed (the braking margin v^2/2a of the fence); the APF shapes the motion near
surfaces and pushes back out of the protection zone.

Blocked progress (a local minimum: the setpoint pulls straight into an obstacle and the barrier
holds the vehicle): when the vehicle's low-passed speed towards its target stays below
`stall_speed` for `detour_after` seconds with an obstacle inside D, a tangential velocity of
`detour_speed` is added around that obstacle, on the side closer to the target (ties go
counter-clockwise), until the straight line to the target clears the obstacle. Deterministic.
ROS-free; the core calls `Barrier.shield` from its position control at 100 Hz.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .geodesy import GeoOrigin
from .geofence import nearest_on_segment, point_inside
from .plan import Geofence

Vec = tuple[float, float, float]
Point2 = tuple[float, float]
INF = math.inf


# ----------------------------------------------------------------------------- the potential
def potential_terms(d: float, detection_range: float, protection_radius: float) -> tuple[float, float, float]:
    """(U(d), -U'(d), U''(d)): all 0 for d >= D, all +inf at or below r, the closed forms on (r, D)."""
    big_d, r = detection_range, protection_radius
    if d >= big_d:
        return 0.0, 0.0, 0.0
    if d <= r:
        return INF, INF, INF
    u, w, c = big_d - d, d - r, big_d - r
    return (u * u * u / (c * w), u * u * (3.0 * w + u) / (c * w * w),
            (6.0 * u * w * w + 6.0 * u * u * w + 2.0 * u * u * u) / (c * w * w * w))


def potential(d: float, detection_range: float, protection_radius: float) -> float:
    """U(d): 0 for d >= D, (D - d)^3 / ((D - r)(d - r)) on (r, D), +inf at or below r."""
    return potential_terms(d, detection_range, protection_radius)[0]


def repulsion(d: float, detection_range: float, protection_radius: float) -> float:
    """-U'(d) >= 0: the magnitude of the repulsive force (0 beyond D, +inf at or below r)."""
    return potential_terms(d, detection_range, protection_radius)[1]


def potential_second_derivative(d: float, detection_range: float, protection_radius: float) -> float:
    """U''(d) (0 beyond D, +inf at or below r); for the smoothness proof."""
    return potential_terms(d, detection_range, protection_radius)[2]


# ----------------------------------------------------------------------------- parameters and inputs
class BarrierError(ValueError):
    """Invalid barrier parameters (one line)."""


@dataclass(frozen=True)
class BarrierParams:
    """The barrier's tuning (SI units). D and r as in D3.3 §6.7 (2 m, 0.5 m)."""

    detection_range: float = 2.0  # D [m]: the APF is zero beyond this distance to a surface
    protection_radius: float = 0.5  # r [m]: the APF is infinite here; the vehicle must stay outside
    brake_decel: float = 4.0  # a [m/s^2]: deceleration the braking cap plans with
    response_time: float = 0.3  # tau [s]: velocity-loop lag the braking cap allows for
    margin: float = 0.25  # [m]: the cap stops this far outside the protection radius
    gain: float = 0.5  # [m/s per unit force]: repulsion speed = gain * (-U'(d))
    max_repulsion: float = 3.0  # [m/s]: saturation of the repulsion speed
    detour_after: float = 1.0  # T [s]: blocked this long with an obstacle inside D -> detour
    detour_speed: float = 1.5  # [m/s]: tangential speed of the detour
    stall_speed: float = 0.3  # [m/s]: low-passed speed towards the target below which progress stalls

    def __post_init__(self) -> None:
        if not (math.isfinite(self.protection_radius) and self.protection_radius > 0):
            raise BarrierError(f"protection radius must be > 0 m (got {self.protection_radius:g})")
        if not (math.isfinite(self.detection_range) and self.detection_range > self.protection_radius):
            raise BarrierError(f"detection range {self.detection_range:g} m must exceed the protection radius "
                               f"{self.protection_radius:g} m")
        for name in ("brake_decel", "response_time", "gain", "max_repulsion", "detour_after", "detour_speed",
                     "stall_speed"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise BarrierError(f"barrier {name} must be > 0 (got {value:g})")
        if not (math.isfinite(self.margin) and self.margin >= 0):
            raise BarrierError(f"barrier margin must be >= 0 m (got {self.margin:g})")

    def stop_speed(self, room: float) -> float:
        """The highest approach speed that stops within `room` [m] (lag tau, then deceleration a):
        v·tau + v^2/(2a) = room. Negative room (inside the margin): a speed away that closes the
        deficit in tau, at most max_repulsion."""
        a, tau = self.brake_decel, self.response_time
        if room <= 0.0:
            return max(-self.max_repulsion, room / tau)
        return a * (math.sqrt(tau * tau + 2.0 * room / a) - tau)


@dataclass(frozen=True)
class Obstacle:
    """A vertical cylinder (what perception tracks): centre and velocity in the local ENU frame at `stamp`."""

    ident: int
    x: float
    y: float
    radius: float
    vx: float = 0.0
    vy: float = 0.0
    top: float = INF  # [m] height of its top above home (inf: unknown / taller than any flight)
    stamp: float = 0.0  # [s] time of the position

    def at(self, now: float) -> Point2:
        """Centre predicted at `now` (constant velocity from `stamp`)."""
        dt = max(0.0, now - self.stamp)
        return self.x + self.vx * dt, self.y + self.vy * dt


@dataclass(frozen=True)
class Contact:
    """The nearest point of one surface: distance to it, unit normal towards the vehicle, its velocity."""

    distance: float
    normal: Vec
    velocity: Vec = (0.0, 0.0, 0.0)
    ident: int = -1  # obstacle id; -1 for the fence


def obstacle_contact(obstacle: Obstacle, position: Vec, now: float) -> Contact:
    """Distance and normal from a cylinder's surface (side, or top rim when above it) to `position`."""
    cx, cy = obstacle.at(now)
    dx, dy = position[0] - cx, position[1] - cy
    rho = math.hypot(dx, dy)
    ex, ey = (dx / rho, dy / rho) if rho > 1e-9 else (1.0, 0.0)
    side = rho - obstacle.radius
    velocity = (obstacle.vx, obstacle.vy, 0.0)
    above = position[2] - obstacle.top
    if above <= 0.0:
        return Contact(side, (ex, ey, 0.0), velocity, obstacle.ident)
    h = max(side, 0.0)
    d = math.hypot(h, above)
    return Contact(d, (ex * h / d, ey * h / d, above / d), velocity, obstacle.ident)


# ----------------------------------------------------------------------------- the fence
def _polygon_contacts(p: Point2, polygon: tuple[Point2, ...], keep_inside: bool, out: list[Contact]) -> None:
    """One contact per edge: distance to the edge, normal into the allowed side (flipped when the
    vehicle is on the wrong side: then the distance is 0, the barrier's strongest push)."""
    wrong_side = point_inside(p, list(polygon)) != keep_inside
    for a, b in zip(polygon, polygon[1:] + polygon[:1], strict=True):
        q = nearest_on_segment(p, a, b)
        dx, dy = p[0] - q[0], p[1] - q[1]
        d = math.hypot(dx, dy)
        if d < 1e-9:
            ex, ey = b[1] - a[1], a[0] - b[0]  # edge normal (either way; only on the boundary itself)
            n = math.hypot(ex, ey) or 1.0
            dx, dy, d = ex / n * 1e-9, ey / n * 1e-9, 1e-9
        if wrong_side:
            out.append(Contact(0.0, (-dx / d, -dy / d, 0.0)))
        else:
            out.append(Contact(d, (dx / d, dy / d, 0.0)))


@dataclass(frozen=True)
class FenceGeometry:
    """A Geofence in the local ENU frame of home, as surfaces for the barrier: inclusion polygon edges,
    exclusion polygons and circles, ceiling, floor and maximum distance from home (<= 0: none)."""

    inclusion: tuple[Point2, ...] = ()
    exclusion_polygons: tuple[tuple[Point2, ...], ...] = ()
    exclusion_circles: tuple[tuple[float, float, float], ...] = ()  # (east, north, radius)
    ceiling: float = 0.0
    floor: float = 0.0
    max_distance: float = 0.0

    @classmethod
    def from_geofence(cls, fence: Geofence, home: GeoOrigin) -> FenceGeometry:
        """Convert once (the core does it when a fence or a new home arrives, never per tick)."""
        def local(points: tuple[tuple[float, float], ...]) -> tuple[Point2, ...]:
            return tuple(_en(home, lat, lon) for lat, lon in points)

        circles = tuple((*_en(home, lat, lon), float(radius)) for lat, lon, radius in fence.exclusion_circles)
        return cls(local(fence.polygon), tuple(local(p) for p in fence.exclusion_polygons), circles,
                   float(fence.max_altitude), float(fence.min_altitude), float(fence.max_distance))

    @property
    def empty(self) -> bool:
        return not (self.inclusion or self.exclusion_polygons or self.exclusion_circles or self.ceiling > 0
                    or self.floor > 0 or self.max_distance > 0)

    def contacts(self, position: Vec, with_floor: bool = True) -> list[Contact]:
        """Every fence surface's nearest point to `position` (the floor only when `with_floor`)."""
        out: list[Contact] = []
        p = (position[0], position[1])
        if self.inclusion:
            _polygon_contacts(p, self.inclusion, True, out)
        for polygon in self.exclusion_polygons:
            _polygon_contacts(p, polygon, False, out)
        for cx, cy, radius in self.exclusion_circles:
            dx, dy = p[0] - cx, p[1] - cy
            rho = math.hypot(dx, dy)
            ex, ey = (dx / rho, dy / rho) if rho > 1e-9 else (1.0, 0.0)
            out.append(Contact(max(rho - radius, 0.0), (ex, ey, 0.0)))
        if self.max_distance > 0:
            rho = math.hypot(*p)
            ex, ey = (p[0] / rho, p[1] / rho) if rho > 1e-9 else (1.0, 0.0)
            out.append(Contact(max(self.max_distance - rho, 0.0), (-ex, -ey, 0.0)))
        if self.ceiling > 0:
            out.append(Contact(max(self.ceiling - position[2], 0.0), (0.0, 0.0, -1.0)))
        if with_floor and self.floor > 0:
            out.append(Contact(max(position[2] - self.floor, 0.0), (0.0, 0.0, 1.0)))
        return out


def _en(home: GeoOrigin, lat: float, lon: float) -> Point2:
    east, north, _ = home.to_enu(lat, lon, home.altitude)
    return float(east), float(north)


# ----------------------------------------------------------------------------- the barrier
@dataclass
class Shielded:
    """What the barrier did this step (for status and tests)."""

    velocity: Vec
    nearest: float = INF  # [m] distance to the nearest surface (obstacle or fence)
    nearest_obstacle: float = INF  # [m] to the nearest obstacle surface
    limited: bool = False  # the cap or the repulsion changed the setpoint
    detour: int = 0  # +1 counter-clockwise, -1 clockwise around `detour_obstacle`, 0 none
    detour_obstacle: int = -1


@dataclass
class _Detour:
    stalled_for: float = 0.0
    progress: float = 0.0  # low-passed speed towards the target [m/s]
    side: int = 0
    obstacle: int = -1
    elapsed: float = 0.0


class Barrier:
    """Shields a velocity setpoint from obstacles and the fence; keeps the detour state between calls."""

    DETOUR_MAX_S = 30.0  # a detour that has not cleared after this long is dropped (re-armed by a new stall)

    def __init__(self, params: BarrierParams | None = None) -> None:
        self.p = params or BarrierParams()
        self.state = _Detour()
        self.last = Shielded((0.0, 0.0, 0.0))

    def reset(self) -> None:
        """Forget the detour and the stall timer (mode change, new target source)."""
        self.state = _Detour()

    def shield(self, now: float, dt: float, position: Vec, velocity: Vec, v_sp: Vec, target: Vec | None,
               obstacles: tuple[Obstacle, ...] | list[Obstacle], fence: FenceGeometry | None,
               with_floor: bool = True) -> Shielded:
        """The velocity setpoint `v_sp` made safe: + detour (if blocked), + repulsion, then capped.

        `target`: where the setpoint leads (position target, or None: no progress judgement);
        `velocity`: the vehicle's velocity (for the stall detector)."""
        p = self.p
        obstacle_contacts = [obstacle_contact(o, position, now) for o in obstacles]
        contacts = obstacle_contacts + (fence.contacts(position, with_floor) if fence is not None else [])
        result = Shielded(v_sp)
        if not contacts:
            self.state = _Detour()
            self.last = result
            return result
        result.nearest = min(c.distance for c in contacts)
        if obstacle_contacts:
            result.nearest_obstacle = min(c.distance for c in obstacle_contacts)
        vx, vy, vz = v_sp
        if obstacles and target is not None:
            ox, oy = self._detour(now, dt, position, velocity, target, obstacles, obstacle_contacts, result)
            vx, vy = vx + ox, vy + oy
        for c in contacts:  # the APF term
            if c.distance < p.detection_range:
                push = min(p.max_repulsion, p.gain * repulsion(c.distance, p.detection_range, p.protection_radius))
                vx, vy, vz = vx + push * c.normal[0], vy + push * c.normal[1], vz + push * c.normal[2]
        for _ in range(3):  # the braking cap, a few passes (corners: two surfaces at once)
            changed = False
            for c in contacts:
                n, s = c.normal, c.velocity
                approach = -((vx - s[0]) * n[0] + (vy - s[1]) * n[1] + (vz - s[2]) * n[2])
                # a closing mover keeps coming while the vehicle's velocity loop responds: its closest point
                # is shifted by (closing speed) x tau
                closing = max(0.0, s[0] * n[0] + s[1] * n[1] + s[2] * n[2])
                limit = p.stop_speed(c.distance - p.protection_radius - p.margin - closing * p.response_time)
                if approach > limit + 1e-9:
                    excess = approach - limit
                    vx, vy, vz = vx + excess * n[0], vy + excess * n[1], vz + excess * n[2]
                    changed = True
            if not changed:
                break
        result.velocity = (vx, vy, vz)
        result.limited = result.velocity != v_sp
        self.last = result
        return result

    def _detour(self, now: float, dt: float, position: Vec, velocity: Vec, target: Vec,
                obstacles: tuple[Obstacle, ...] | list[Obstacle], contacts: list[Contact], result: Shielded) -> Point2:
        """The tangential detour velocity (0, 0 unless blocked); updates the stall detector."""
        p, st = self.p, self.state
        gx, gy = target[0] - position[0], target[1] - position[1]
        goal = math.hypot(gx, gy)
        if goal < 1.0:  # arrived (or hovering): nothing to make progress towards
            self.state = _Detour()
            return 0.0, 0.0
        ux, uy = gx / goal, gy / goal
        alpha = min(1.0, dt / 0.3)
        st.progress += alpha * (velocity[0] * ux + velocity[1] * uy - st.progress)
        if st.side:
            k = next((i for i, o in enumerate(obstacles) if o.ident == st.obstacle), -1)
            st.elapsed += dt
            if k < 0 or st.elapsed > self.DETOUR_MAX_S or contacts[k].distance > p.detection_range + 1.0 or \
                    self._line_clear(position, target, obstacles[k], now):
                self.state = _Detour(progress=st.progress)
                return 0.0, 0.0
            n = contacts[k].normal
            tx, ty = -n[1] * st.side, n[0] * st.side
            norm = math.hypot(tx, ty) or 1.0
            result.detour, result.detour_obstacle = st.side, st.obstacle
            return p.detour_speed * tx / norm, p.detour_speed * ty / norm
        near = [k for k, c in enumerate(contacts) if c.distance < p.detection_range]
        if not near or st.progress >= p.stall_speed:
            st.stalled_for = 0.0
            return 0.0, 0.0
        st.stalled_for += dt
        if st.stalled_for < p.detour_after:
            return 0.0, 0.0
        # blocked: go around the obstacle that stands most in the way (normal most against the target)
        k = min(near, key=lambda i: contacts[i].normal[0] * ux + contacts[i].normal[1] * uy)
        n = contacts[k].normal
        tx, ty = -n[1], n[0]  # counter-clockwise tangent
        towards = tx * ux + ty * uy
        st.side = 1 if towards >= -0.05 else -1  # the side closer to the target; a tie goes counter-clockwise
        st.obstacle, st.elapsed, st.stalled_for = obstacles[k].ident, 0.0, 0.0
        return self._detour(now, 0.0, position, velocity, target, obstacles, contacts, result)

    def _line_clear(self, position: Vec, target: Vec, obstacle: Obstacle, now: float) -> bool:
        """The straight line to the target passes the obstacle outside its protection zone (+ margin)."""
        c = obstacle.at(now)
        q = nearest_on_segment(c, (position[0], position[1]), (target[0], target[1]))
        return math.dist(q, c) > obstacle.radius + self.p.protection_radius + self.p.margin + 0.3
