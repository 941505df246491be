"""Flight summary and progress lines for `c4d fly` (no ROS: fed with plain numbers).

FlightSummary accumulates while the flight runs:
- duration: first arm to last disarm;
- distance: estimated 3-D path length while armed, accumulated in steps of at least
  `min_step_m` so that estimator noise at rest does not add up;
- tracking error: distance between each position setpoint and the estimated position at the
  moment the setpoint arrives (max and RMS, while armed and in the air);
- executor overruns: ticks and overruns of the GNC core between the first and last report;
- failsafes: every distinct failsafe (action, event) that health reported, with the first
  reason and how many times it was raised; WARN-level events are listed apart as warnings.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field


@dataclass
class FlightSummary:
    min_step_m: float = 0.2
    armed_at: float | None = None
    disarmed_at: float | None = None
    distance_m: float = 0.0
    max_altitude_m: float = 0.0
    max_tracking_error_m: float = 0.0
    _sq_error_sum: float = 0.0
    tracking_samples: int = 0
    first_stats: tuple[int, int] | None = None  # (ticks_total, overruns_total)
    last_stats: tuple[int, int] | None = None
    load_max_percent: float = 0.0
    failsafes: dict[tuple[str, str], list] = field(default_factory=dict)  # (action, event) -> [first reason, count]
    _last_failsafe: tuple[str, str] | None = None
    _position: tuple[float, float, float] | None = None
    _anchor: tuple[float, float, float] | None = None
    _armed: bool = False
    _in_air: bool = False

    def on_status(self, t: float, armed: bool, in_air: bool) -> None:
        if armed and not self._armed and self.armed_at is None:
            self.armed_at = t
        if not armed and self._armed:
            self.disarmed_at = t
        self._armed, self._in_air = armed, in_air

    def on_position(self, x: float, y: float, z: float) -> None:
        p = (x, y, z)
        if not all(math.isfinite(v) for v in p):
            return
        self._position = p
        if not self._armed:
            self._anchor = p
            return
        self.max_altitude_m = max(self.max_altitude_m, z)
        if self._anchor is None:
            self._anchor = p
        step = math.dist(self._anchor, p)
        if step >= self.min_step_m:
            self.distance_m += step
            self._anchor = p

    def on_setpoint(self, x: float, y: float, z: float) -> None:
        if not (self._armed and self._in_air) or self._position is None:
            return
        if not all(math.isfinite(v) for v in (x, y, z)):
            return
        error = math.dist((x, y, z), self._position)
        self.max_tracking_error_m = max(self.max_tracking_error_m, error)
        self._sq_error_sum += error * error
        self.tracking_samples += 1

    def on_executor_stats(self, ticks_total: int, overruns_total: int, load_max_percent: float) -> None:
        if self.first_stats is None:
            self.first_stats = (ticks_total, overruns_total)
        self.last_stats = (ticks_total, overruns_total)
        self.load_max_percent = max(self.load_max_percent, load_max_percent)

    def on_failsafe(self, action: str, reason: str) -> None:
        """Feed every health summary; a (action, event) counts again only after it changed."""
        if action.upper() in ("", "NONE"):
            self._last_failsafe = None
            return
        key = (action.upper(), reason.split(":", 1)[0].strip())
        if key == self._last_failsafe:
            return
        self._last_failsafe = key
        entry = self.failsafes.setdefault(key, [reason, 0])
        entry[1] += 1

    def acting_failsafes(self) -> str:
        """The failsafes that acted (hold, RTL, land, terminate: not warnings), for people; "" if none."""
        text = self._failsafe_text(False)
        return "" if text == "none" else f"failsafe {text}"

    def _failsafe_text(self, warnings: bool) -> str:
        chosen = [(k, v) for k, v in self.failsafes.items() if (k[0] == "WARN") == warnings]
        return "; ".join(f"{a} {reason}" + (f" (x{n})" if n > 1 else "") for (a, _), (reason, n) in chosen) or "none"

    @property
    def duration_s(self) -> float | None:
        if self.armed_at is None or self.disarmed_at is None:
            return None
        return self.disarmed_at - self.armed_at

    @property
    def rms_tracking_error_m(self) -> float:
        return math.sqrt(self._sq_error_sum / self.tracking_samples) if self.tracking_samples else 0.0

    @property
    def ticks(self) -> int:
        if self.first_stats is None or self.last_stats is None:
            return 0
        return self.last_stats[0] - self.first_stats[0]

    @property
    def overruns(self) -> int:
        if self.first_stats is None or self.last_stats is None:
            return 0
        return self.last_stats[1] - self.first_stats[1]

    def lines(self, outcome: str, paths: dict[str, str]) -> list[str]:
        duration = self.duration_s
        share = f" ({100.0 * self.overruns / self.ticks:.3f} % of {self.ticks} ticks, worst tick load " \
                f"{self.load_max_percent:.0f} %)" if self.ticks else " (no executor report received)"
        out = [
            f"flight     {outcome}",
            f"duration   {duration:.1f} s armed" if duration is not None else "duration   not armed",
            f"distance   {self.distance_m:.1f} m flown, max altitude {self.max_altitude_m:.1f} m",
            f"tracking   max {self.max_tracking_error_m:.2f} m, RMS {self.rms_tracking_error_m:.2f} m "
            f"({self.tracking_samples} setpoints)",
            f"overruns   {self.overruns}{share}",
            f"failsafes  {self._failsafe_text(False)}",
            f"warnings   {self._failsafe_text(True)}",
        ]
        out += [f"{k:<10} {v}" for k, v in paths.items()]
        return out


MISSION_STATES = {0: "NO_PLAN", 1: "READY", 2: "ACTIVE", 3: "PAUSED", 4: "COMPLETED", 5: "ABORTED"}
NAV_STATES = {0: "-", 1: "TAKEOFF", 2: "MISSION", 3: "HOLD", 4: "GOTO", 5: "RTL", 6: "LAND"}
FLIGHT_MODES = {0: "UNKNOWN", 1: "RATE", 2: "ATTITUDE", 3: "POSITION", 4: "AUTO", 5: "KILL"}
LANDED = {0: "undefined", 1: "on ground", 2: "in air", 3: "taking off", 4: "landing"}


def progress_line(elapsed: float, mission: tuple[int, int, int, float] | None, position: tuple[float, float, float] | None,
                  battery_percent: float | None, mode: str) -> str:
    """One line of live progress: time, mission state/item/progress, position, battery, mode.
    mission = (state, current_item, total_items, progress fraction)."""
    parts = [f"[{elapsed:6.1f} s]"]
    if mission is None:
        parts.append("mission -")
    else:
        state, item, total, progress = mission
        parts.append(f"{MISSION_STATES.get(state, str(state)):<9} item {min(item + 1, total):>2}/{total:<2} "
                     f"{100 * progress:5.1f} %")
    if position is not None:
        parts.append(f"E {position[0]:6.1f} N {position[1]:6.1f} U {position[2]:5.1f} m")
    if battery_percent is not None and math.isfinite(battery_percent):
        parts.append(f"batt {100 * battery_percent:3.0f} %")
    parts.append(mode)
    return "  ".join(parts)
