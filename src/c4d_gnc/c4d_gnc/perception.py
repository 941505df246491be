"""Sensor conditioning and health: validation, calibration, rate / freshness / freeze monitoring.

Each sensor has a SensorMonitor. `accept()` rejects (and counts) samples with NaN/inf or values
outside physical ranges — they never reach the estimator — and tracks arrival times and
repeated identical samples. `health()` classifies the sensor: OK, STALE (no sample for
`timeout_s`), FROZEN (the last `frozen_count` samples identical — a stuck driver), INVALID
(more than half of the recent samples rejected), LOW_RATE (measured rate below half of the
expected one). The perception node publishes these as diagnostic_msgs/DiagnosticArray.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from enum import Enum

Vec = tuple[float, float, float]


class Health(Enum):
    OK = "ok"
    STALE = "stale"
    FROZEN = "frozen"
    INVALID = "invalid"
    LOW_RATE = "low rate"
    WAITING = "no data yet"


# Physical limits used to reject samples (generous: a multirotor never gets close)
LIMITS = {
    "gyro": 35.0,  # [rad/s] per axis (2000 °/s)
    "accel": 160.0,  # [m/s²] per axis (16 g)
    "pressure": (30_000.0, 110_000.0),  # [Pa] ~ −700 m .. 9000 m
    "mag": 1e-3,  # [T] per axis
    "range": (0.0, 100.0),  # [m]
}


@dataclass
class SensorMonitor:
    name: str
    expected_rate_hz: float
    timeout_s: float
    frozen_count: int = 50
    accepted: int = 0
    rejected: int = 0
    last_time: float = -math.inf
    _last_values: tuple | None = None
    _same: int = 0
    _times: deque = field(default_factory=lambda: deque(maxlen=200))
    _recent: deque = field(default_factory=lambda: deque(maxlen=50))  # True = accepted

    def accept(self, t: float, values: tuple, valid: bool, can_freeze: bool = True) -> bool:
        """Count a sample; `can_freeze=False` for readings that are legitimately constant
        (a range finder's ±inf on the ground or out of range)."""
        self._recent.append(valid)
        if not valid:
            self.rejected += 1
            return False
        self.accepted += 1
        self.last_time = t
        self._times.append(t)
        if can_freeze and values == self._last_values:
            self._same += 1
        else:
            self._same = 0
            self._last_values = values
        return True

    def rate(self) -> float:
        if len(self._times) < 2 or self._times[-1] <= self._times[0]:
            return 0.0
        return (len(self._times) - 1) / (self._times[-1] - self._times[0])

    def health(self, now: float) -> Health:
        if self.accepted == 0 and self.rejected == 0:
            return Health.WAITING
        if self._recent and sum(1 for ok in self._recent if not ok) > len(self._recent) / 2:
            return Health.INVALID
        if now - self.last_time > self.timeout_s:
            return Health.STALE
        if self._same >= self.frozen_count:
            return Health.FROZEN
        if len(self._times) >= 10 and self.rate() < 0.5 * self.expected_rate_hz:
            return Health.LOW_RATE
        return Health.OK


def _finite(values) -> bool:
    return all(math.isfinite(v) for v in values)


def valid_imu(gyro: Vec, accel: Vec) -> bool:
    return (_finite(gyro) and _finite(accel) and max(map(abs, gyro)) <= LIMITS["gyro"]
            and max(map(abs, accel)) <= LIMITS["accel"])


def valid_pressure(pressure: float) -> bool:
    lo, hi = LIMITS["pressure"]
    return math.isfinite(pressure) and lo <= pressure <= hi


def valid_mag(field_: Vec) -> bool:
    return _finite(field_) and max(map(abs, field_)) <= LIMITS["mag"] and any(v != 0.0 for v in field_)


def valid_fix(latitude: float, longitude: float, altitude: float, has_fix: bool) -> bool:
    return (has_fix and _finite((latitude, longitude, altitude)) and -90.0 <= latitude <= 90.0
            and -180.0 <= longitude <= 180.0 and -500.0 < altitude < 10_000.0)


def valid_range(distance: float) -> bool:
    """REP 117: +inf (nothing within range) and −inf (closer than the minimum range) are valid
    readings; NaN and finite values outside [0, 100] m are not."""
    lo, hi = LIMITS["range"]
    return math.isinf(distance) or (math.isfinite(distance) and lo <= distance <= hi)


@dataclass(frozen=True)
class ImuCalibration:
    """Constant offsets and scale factors removed from raw samples (from a calibration run)."""

    gyro_offset: Vec = (0.0, 0.0, 0.0)
    accel_offset: Vec = (0.0, 0.0, 0.0)
    accel_scale: Vec = (1.0, 1.0, 1.0)

    @property
    def identity(self) -> bool:
        """True when apply() returns its input unchanged (a node may forward the sample as it came)."""
        zero = (0.0, 0.0, 0.0)
        return self.gyro_offset == zero and self.accel_offset == zero and self.accel_scale == (1.0, 1.0, 1.0)

    def apply(self, gyro: Vec, accel: Vec) -> tuple[Vec, Vec]:
        g = tuple(gyro[k] - self.gyro_offset[k] for k in range(3))
        a = tuple((accel[k] - self.accel_offset[k]) * self.accel_scale[k] for k in range(3))
        return g, a  # type: ignore[return-value]
