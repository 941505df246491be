"""Which source the navigation filter fuses for one axis group (horizontal position, or height), without ROS.

Parameters choose a primary and a secondary source (VehicleState.SOURCE_*). The active source is
left when it is lost — no sample fused for `timeout_s` (a source whose samples the gate keeps
rejecting is lost too) — or blocked (GNSS with a SPOOFED integrity verdict); the other configured
source takes over if it delivered a valid sample within `timeout_s`. The filter returns to the
primary once it has delivered valid samples without a gap for `recovery_s` (not their agreement
with the estimate: that follows the secondary, whose bias would keep a good primary out for
ever; the offset capture makes the return smooth whatever the disagreement). At start the
primary has `recovery_s` to deliver before it counts as lost (GNSS needs its home fixes, an
external source its alignment samples).

No step at a switch: the new source's first sample captures the offset between the estimate and
it (`offset = estimate − measurement`); the filter then fuses measurement + offset, and the offset
decays with time constant `blend_s`, so the estimate moves to the new source smoothly (at most
|offset| / blend_s per second) instead of jumping.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

NONE, GNSS, EXTERNAL, BARO, RANGE = 0, 1, 2, 3, 4  # == VehicleState.SOURCE_*
RECAPTURED = frozenset({EXTERNAL})  # sources re-captured when the gate keeps refusing them (see update)
NAMES = {"none": NONE, "gnss": GNSS, "external": EXTERNAL, "baro": BARO, "range": RANGE}
HORIZONTAL_CHOICES = ("gnss", "external")
HEIGHT_CHOICES = ("baro", "gnss", "external", "range")


@dataclass(frozen=True)
class SelectionConfig:
    primary: int
    secondary: int = NONE
    timeout_s: float = 1.0  # [s] no fused sample this long: the source is lost
    recovery_s: float = 5.0  # [s] the primary healthy this long: back to it
    blend_s: float = 10.0  # [s] time constant the switch offset decays with


class SourceSelector:
    """Active source, per-source health and the switch offset of one axis group (dimension `dim`)."""

    def __init__(self, config: SelectionConfig, dim: int) -> None:
        self.cfg = config
        self.active = config.primary
        self.offset = np.zeros(dim)
        self.capture_pending = False
        self.switches = 0
        self.last_switch_t = math.nan
        self.last_step_m = 0.0
        self._offset_t = math.nan
        self._start_t = math.nan
        self.last_fused: dict[int, float] = {}
        self._last_valid: dict[int, float] = {}
        self._healthy_since: dict[int, float] = {}
        self.blocked: set[int] = set()

    @property
    def configured(self) -> tuple[int, ...]:
        return tuple(s for s in (self.cfg.primary, self.cfg.secondary) if s != NONE)

    def sample(self, source: int, t: float) -> None:
        """A valid sample of `source` at sample time t."""
        if t - self._last_valid.get(source, -math.inf) > self.cfg.timeout_s:
            self._healthy_since[source] = t
        self._last_valid[source] = t

    def fused(self, source: int, t: float) -> None:
        self.last_fused[source] = t

    def fresh(self, source: int, t: float) -> bool:
        return source not in self.blocked and t - self._last_valid.get(source, -math.inf) <= self.cfg.timeout_s

    def fusing(self, t: float) -> int:
        """The source fused within timeout_s (NONE: dead reckoning)."""
        if t - self.last_fused.get(self.active, -math.inf) <= self.cfg.timeout_s and self.active not in self.blocked:
            return self.active
        return NONE

    def update(self, t: float) -> bool:
        """Switch if due at time t; True when the active source changed."""
        cfg = self.cfg
        if math.isnan(self._start_t):
            self._start_t = t
        if t - self._start_t < cfg.recovery_s and self.active not in self.last_fused and self.switches == 0:
            return False  # start: the primary has recovery_s to come up
        lost = self.active in self.blocked or t - self.last_fused.get(self.active, -math.inf) > cfg.timeout_s
        if lost:
            for candidate in self.configured:
                if candidate != self.active and self.fresh(candidate, t):
                    return self._switch(candidate, t)
            if self.active in RECAPTURED and self.fresh(self.active, t):
                # its samples keep coming but the gate has refused them for timeout_s and nothing else is
                # there: re-capture its offset (a reset onto it, without a step) rather than dead-reckon on.
                # Never GNSS: a re-capture would absorb a spoofer's jump (the EKF has its own reset after
                # an outage, gps_reset_after_s, and the integrity monitor judges the fixes first)
                return self._switch(self.active, t)
            return False
        primary = cfg.primary
        if self.active != primary and self.fresh(primary, t) and t - self._healthy_since.get(primary, math.inf) >= cfg.recovery_s:
            return self._switch(primary, t)
        return False

    def _switch(self, source: int, t: float) -> bool:
        self.active = source
        self.capture_pending = True
        self.switches += 1
        self.last_switch_t = t
        return True

    def measurement(self, z: np.ndarray, predicted: np.ndarray, t: float, capture: bool = True) -> np.ndarray:
        """The active source's measurement z at sample time t, shifted by the switch offset (captured
        from `predicted`, the estimate at t, on the first sample after a switch when `capture`)."""
        if self.capture_pending:
            self.capture_pending = False
            self.offset = (predicted - z) if capture else np.zeros_like(self.offset)
            self._offset_t = t
        elif math.isfinite(self._offset_t) and t > self._offset_t:
            self.offset = self.offset * math.exp(-(t - self._offset_t) / self.cfg.blend_s)
            self._offset_t = t
        return z + self.offset
