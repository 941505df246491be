"""Three-axis PID with the protections a flight controller needs.

- anti-windup: the integrator is clamped to ±i_limit and frozen on an axis while the
  downstream stage reports saturation, except to shrink it (unwind);
- derivative on measurement (not on error), so setpoint steps do not kick the output;
- optional conditional integration (only while |error| < integrate_below), so a large
  manoeuvre does not charge the integrator that then takes seconds to unwind;
- first-order low-pass filter on that derivative (cutoff in Hz), because differentiated gyro
  or velocity noise would otherwise reach the motors.
"""

from __future__ import annotations

import math

from c4d_common.airframe import AxisGains

Vec = tuple[float, float, float]


class VectorPid:
    def __init__(self, gains: AxisGains, d_cutoff_hz: float | None = None, integrate_below: float = math.inf) -> None:
        self.gains = gains
        self.d_cutoff_hz = d_cutoff_hz
        self.integrate_below = integrate_below  # integrate an axis only while |error| is below this
        self.reset()

    def reset(self) -> None:
        self.integral = [0.0, 0.0, 0.0]
        self.last_measurement: list[float] | None = None
        self.d_filtered = [0.0, 0.0, 0.0]

    def update(self, error: Vec, measurement: Vec, dt: float, saturated: tuple[bool, bool, bool] = (False, False, False)) -> Vec:
        g = self.gains
        if self.last_measurement is None or dt <= 0:
            derivative = [0.0, 0.0, 0.0]
        else:
            raw = [(m - last) / dt for m, last in zip(measurement, self.last_measurement, strict=True)]
            if self.d_cutoff_hz:
                alpha = 1.0 - math.exp(-2.0 * math.pi * self.d_cutoff_hz * dt)
                derivative = [f + alpha * (r - f) for f, r in zip(self.d_filtered, raw, strict=True)]
            else:
                derivative = raw
        self.d_filtered = derivative
        self.last_measurement = list(measurement)
        out = []
        for k in range(3):
            e = error[k]
            if abs(e) < self.integrate_below and (not saturated[k] or e * self.integral[k] < 0):
                limit = g.i_limit[k]
                self.integral[k] = max(-limit, min(limit, self.integral[k] + g.i[k] * e * dt))
            out.append(g.p[k] * e + self.integral[k] - g.d[k] * derivative[k])
        return out[0], out[1], out[2]
