"""Translational loops: position P → velocity PID → acceleration → thrust vector + attitude.

World frame ENU. The acceleration setpoint becomes a thrust vector F = m(a + g·ẑ); its tilt
from vertical is limited to max_tilt with vertical priority (the vertical component is kept,
the horizontal one shortened), its magnitude to [min, max] thrust ratio. The attitude target
puts body z along F with the requested yaw; the collective thrust is F projected on the
current body z axis (so a still-tilting vehicle does not climb or sink).
"""

from __future__ import annotations

import math

from c4d_common import quat
from c4d_common.airframe import GRAVITY, Airframe

from .pid import VectorPid

Vec = tuple[float, float, float]
NAN = float("nan")


def _finite(v: Vec) -> bool:
    return all(math.isfinite(x) for x in v)


class TranslationController:
    def __init__(self, airframe: Airframe) -> None:
        self.af = airframe
        self.velocity_pid = VectorPid(airframe.velocity, integrate_below=0.5)
        self.saturated_xy = False
        self.saturated_z = False

    def reset(self) -> None:
        self.velocity_pid.reset()

    def velocity_setpoint(self, position: Vec, target: Vec, feedforward: Vec) -> Vec:
        """Position P (+ feed-forward), limited to the airframe's speeds."""
        kp = self.af.position_p
        ff = feedforward if _finite(feedforward) else (0.0, 0.0, 0.0)
        v = [kp[k] * (target[k] - position[k]) + ff[k] for k in range(3)]
        horizontal = math.hypot(v[0], v[1])
        if horizontal > self.af.max_horizontal_speed:
            scale = self.af.max_horizontal_speed / horizontal
            v[0] *= scale
            v[1] *= scale
        v[2] = max(-self.af.max_descent_speed, min(self.af.max_climb_speed, v[2]))
        return v[0], v[1], v[2]

    def acceleration_setpoint(self, velocity: Vec, target: Vec, feedforward: Vec, dt: float) -> Vec:
        """Velocity PID (D on measured velocity, anti-windup from the thrust-vector limits)."""
        error = (target[0] - velocity[0], target[1] - velocity[1], target[2] - velocity[2])
        sat = (self.saturated_xy, self.saturated_xy, self.saturated_z)
        a = self.velocity_pid.update(error, velocity, dt, sat)
        ff = feedforward if _finite(feedforward) else (0.0, 0.0, 0.0)
        return a[0] + ff[0], a[1] + ff[1], a[2] + ff[2]

    def thrust_and_attitude(self, acceleration: Vec, yaw: float, orientation: quat.Quat) -> tuple[float, quat.Quat]:
        """Thrust vector limits → (collective thrust [N], attitude target)."""
        m, af = self.af.mass, self.af
        fx, fy, fz = m * acceleration[0], m * acceleration[1], m * (acceleration[2] + GRAVITY)
        f_min = af.min_thrust_ratio * af.total_max_thrust
        f_max = af.max_thrust_ratio * af.total_max_thrust
        self.saturated_z = False
        if fz < f_min * math.cos(af.max_tilt):  # never command a downward or near-zero vertical push
            fz = f_min * math.cos(af.max_tilt)
            self.saturated_z = True
        horizontal = math.hypot(fx, fy)
        max_horizontal = fz * math.tan(af.max_tilt)
        self.saturated_xy = horizontal > max_horizontal
        if self.saturated_xy:  # vertical priority: shorten the horizontal part only
            fx, fy = fx * max_horizontal / horizontal, fy * max_horizontal / horizontal
        norm = math.sqrt(fx * fx + fy * fy + fz * fz)
        if norm > f_max:
            if fz >= f_max:  # even the vertical part alone saturates: keep it, no horizontal
                fx, fy, fz = 0.0, 0.0, f_max
                self.saturated_z = True
            else:
                max_h = math.sqrt(f_max * f_max - fz * fz)
                h = math.hypot(fx, fy)
                fx, fy = fx * max_h / h, fy * max_h / h
                self.saturated_xy = True
            norm = f_max
        zb = (fx / norm, fy / norm, fz / norm)
        heading = (math.cos(yaw), math.sin(yaw), 0.0)
        yb = _cross(zb, heading)
        n = math.sqrt(yb[0] ** 2 + yb[1] ** 2 + yb[2] ** 2)
        yb = (yb[0] / n, yb[1] / n, yb[2] / n)
        xb = _cross(yb, zb)
        target = quat.from_axes(xb, yb, zb)
        current_z = quat.body_z(orientation)
        projected = fx * current_z[0] + fy * current_z[1] + fz * current_z[2]
        thrust = max(f_min, min(f_max, projected))
        return thrust, target


def _cross(a: Vec, b: Vec) -> Vec:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])
