"""A flight's summary figures (distance, altitude, tracking, timing, failsafes, battery, captures)
and its 10-s time-series bins, computed in one streaming pass.

Why one streaming accumulator: the same numbers appear in a flight's own report (its "Flight
summary" section) and in the fleet catalog (one database row per flight), so they must come from
one piece of code; and the catalog indexes thousands of files in parallel, so memory must not
grow with the length of a flight. `FlightSummarizer.add` takes decoded messages one at a time,
in log-time order; what it keeps is a few running sums, one record per 10-s bin and, for the
tracking error, the state samples since the last setpoint (at most `SETPOINT_GAP_S` of them).

Definitions (docs/data.md "Flight catalog" repeats them):
- distance: integral of |estimated velocity| over time (a path length that is not inflated by
  position noise while standing still); energy per km divides by it (None under 10 m).
- tracking error: |estimated position - guidance setpoint position|, the setpoint linearly
  interpolated between two consecutive setpoints (guidance/setpoint or guidance/offboard) less
  than `SETPOINT_GAP_S` apart; state samples outside such a pair (before the first setpoint,
  after the last, in a gap of the stream, or against a NaN position) do not count.
- failsafes: entries of vehicle/status failsafe_action into HOLD, RTL, LAND or TERMINATE (a
  change of action counts again; WARN is not a failsafe).
- battery used: first - last state of charge [%]; energy: integral of voltage * |current|
  (packs report discharge as negative current in ROS, positive elsewhere).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import asdict, dataclass, field
from typing import Any

from ..bag_reader import BagContents, BagError, Decoders, iter_messages

BIN_S = 10.0  # [s] width of a time-series bin
SETPOINT_GAP_S = 1.0  # [s] setpoints further apart than this do not bracket a tracking sample
MIN_DISTANCE_FOR_ENERGY_M = 10.0  # [m] energy per km is None below this distance
FAILSAFE_NAMES = {2: "HOLD", 3: "RTL", 4: "LAND", 5: "TERMINATE"}
STATE, STATUS, BATTERY, STATS, CAPTURES = ("/navigation/state", "/vehicle/status", "/sensors/battery",
                                           "/gnc/executor_stats", "/payload/captures")
SETPOINTS = ("/guidance/setpoint", "/guidance/offboard")
SUMMARY_TOPICS = (STATE, STATUS, BATTERY, STATS, CAPTURES, *SETPOINTS)
# topics without which a row would be mostly empty: a file with none of them is not a c4d flight
CORE_TOPICS = (STATE, STATUS, BATTERY, STATS, "/guidance/setpoint")


@dataclass
class FlightFigures:
    """One flight's summary (None = not recorded / not computable)."""

    duration_s: float
    messages: int
    distance_m: float | None = None
    max_altitude_m: float | None = None
    tracking_rms_m: float | None = None
    tracking_max_m: float | None = None
    tracking_samples: int = 0
    overruns: int | None = None
    ticks: int | None = None
    worst_tick_load_pct: float | None = None
    failsafes: int | None = None
    failsafe_actions: str = ""
    battery_used_pct: float | None = None
    energy_wh: float | None = None
    energy_wh_per_km: float | None = None
    captures: int | None = None

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass
class Bin:
    """Aggregates of one BIN_S-wide slice of the flight (t from the start of the recording)."""

    index: int
    altitude_max_m: float = -math.inf
    altitude_sum: float = 0.0
    speed_sum: float = 0.0
    states: int = 0
    tracking_sq_sum: float = 0.0
    tracking_samples: int = 0
    voltage_sum: float = 0.0
    power_sum: float = 0.0
    battery_samples: int = 0
    load_max_pct: float = -math.inf
    overruns: int = 0

    def row(self) -> dict[str, Any]:
        """Database/report values: means and RMS, None where the bin has no sample of a kind."""
        def mean(total: float, n: int) -> float | None:
            return total / n if n else None

        return {"bin": self.index, "t_start_s": self.index * BIN_S,
                "altitude_max_m": self.altitude_max_m if self.states else None,
                "altitude_mean_m": mean(self.altitude_sum, self.states),
                "speed_mean_m_s": mean(self.speed_sum, self.states),
                "tracking_rms_m": math.sqrt(self.tracking_sq_sum / self.tracking_samples) if self.tracking_samples else None,
                "voltage_mean_v": mean(self.voltage_sum, self.battery_samples),
                "power_mean_w": mean(self.power_sum, self.battery_samples),
                "load_max_pct": self.load_max_pct if self.load_max_pct > -math.inf else None,
                "overruns": self.overruns}


def _finite(*values: float) -> bool:
    return all(math.isfinite(v) for v in values)


@dataclass
class FlightSummarizer:
    """Streaming accumulator: add() every decoded message of SUMMARY_TOPICS in log-time order,
    then figures() / bins()."""

    start_ns: int
    bins_by_index: dict[int, Bin] = field(default_factory=dict)
    distance: float = 0.0
    states: int = 0
    last_state_t: float | None = None
    max_altitude: float = -math.inf
    setpoint: tuple[float, float, float, float] | None = None  # t, x, y, z of the last setpoint
    pending: list[tuple[float, float, float, float]] = field(default_factory=list)  # state samples since it
    track_sq: float = 0.0
    track_max: float = 0.0
    track_n: int = 0
    stats_seen: bool = False
    overruns: int = 0
    ticks: int = 0
    worst_load: float = -math.inf
    status_seen: bool = False
    failsafe: int = 0
    failsafe_list: list[str] = field(default_factory=list)
    first_charge: float | None = None
    last_charge: float | None = None
    battery_t: float | None = None
    energy_j: float = 0.0
    battery_seen: bool = False
    captures: int | None = None

    def _bin(self, t: float) -> Bin:
        k = int(t // BIN_S)
        b = self.bins_by_index.get(k)
        if b is None:
            b = self.bins_by_index[k] = Bin(k)
        return b

    def add(self, topic: str, log_time_ns: int, m: Any) -> None:
        t = (log_time_ns - self.start_ns) * 1e-9
        if topic == STATE:
            self._state(t, m)
        elif topic in SETPOINTS:
            self._setpoint(t, m.position.x, m.position.y, m.position.z)
        elif topic == STATUS:
            self.status_seen = True
            action = int(m.failsafe_action)
            if action != self.failsafe and action in FAILSAFE_NAMES:
                self.failsafe_list.append(FAILSAFE_NAMES[action])
            self.failsafe = action
        elif topic == BATTERY:
            self._battery(t, m)
        elif topic == STATS:
            self.stats_seen = True
            self.overruns += int(m.overruns)
            self.ticks += int(m.ticks)
            self.worst_load = max(self.worst_load, float(m.load_max_percent))
            b = self._bin(t)
            b.load_max_pct = max(b.load_max_pct, float(m.load_max_percent))
            b.overruns += int(m.overruns)
        elif topic == CAPTURES:
            self.captures = (self.captures or 0) + 1

    def _state(self, t: float, m: Any) -> None:
        p, v = m.position, m.velocity
        speed = math.sqrt(v.x * v.x + v.y * v.y + v.z * v.z)
        if self.last_state_t is not None and _finite(speed):
            dt = t - self.last_state_t
            if 0 < dt <= SETPOINT_GAP_S:
                self.distance += speed * dt
        self.last_state_t = t
        self.states += 1
        b = self._bin(t)
        if _finite(p.z, speed):
            self.max_altitude = max(self.max_altitude, p.z)
            b.altitude_max_m = max(b.altitude_max_m, p.z)
            b.altitude_sum += p.z
            b.speed_sum += speed
            b.states += 1
        if self.setpoint is not None:
            if t - self.setpoint[0] > SETPOINT_GAP_S:
                self.setpoint, self.pending = None, []
            else:
                self.pending.append((t, p.x, p.y, p.z))

    def _setpoint(self, t: float, x: float, y: float, z: float) -> None:
        previous = self.setpoint
        if previous is not None and t - previous[0] <= SETPOINT_GAP_S and _finite(x, y, z, *previous[1:]):
            t0, x0, y0, z0 = previous
            span = t - t0
            for ts, px, py, pz in self.pending:
                w = (ts - t0) / span if span > 0 else 1.0
                ex, ey, ez = px - (x0 + w * (x - x0)), py - (y0 + w * (y - y0)), pz - (z0 + w * (z - z0))
                if not _finite(ex, ey, ez):
                    continue
                sq = ex * ex + ey * ey + ez * ez
                self.track_sq += sq
                self.track_max = max(self.track_max, math.sqrt(sq))
                self.track_n += 1
                b = self._bin(ts)
                b.tracking_sq_sum += sq
                b.tracking_samples += 1
        self.setpoint = (t, x, y, z)
        self.pending = []

    def _battery(self, t: float, m: Any) -> None:
        self.battery_seen = True
        if _finite(m.percentage):
            self.first_charge = m.percentage if self.first_charge is None else self.first_charge
            self.last_charge = m.percentage
        if not _finite(m.voltage, m.current):
            return
        power = m.voltage * abs(m.current)
        if self.battery_t is not None and 0 < t - self.battery_t <= 5.0:
            self.energy_j += power * (t - self.battery_t)
        self.battery_t = t
        b = self._bin(t)
        b.voltage_sum += m.voltage
        b.power_sum += power
        b.battery_samples += 1

    def figures(self, contents: BagContents) -> FlightFigures:
        f = FlightFigures(duration_s=contents.duration_s, messages=contents.message_count)
        if self.states:
            f.distance_m = self.distance
            f.max_altitude_m = self.max_altitude if self.max_altitude > -math.inf else None
        if self.track_n:
            f.tracking_rms_m = math.sqrt(self.track_sq / self.track_n)
            f.tracking_max_m = self.track_max
            f.tracking_samples = self.track_n
        if self.stats_seen:
            f.overruns, f.ticks = self.overruns, self.ticks
            f.worst_tick_load_pct = self.worst_load
        if self.status_seen:
            f.failsafes = len(self.failsafe_list)
            f.failsafe_actions = ">".join(self.failsafe_list)
        if self.battery_seen:
            if self.first_charge is not None and self.last_charge is not None:
                f.battery_used_pct = 100.0 * (self.first_charge - self.last_charge)
            f.energy_wh = self.energy_j / 3600.0
            if f.distance_m is not None and f.distance_m >= MIN_DISTANCE_FOR_ENERGY_M:
                f.energy_wh_per_km = f.energy_wh / (f.distance_m / 1000.0)
        if CAPTURES in contents.topics:
            f.captures = self.captures or 0
        return f

    def bins(self) -> list[dict[str, Any]]:
        return [self.bins_by_index[k].row() for k in sorted(self.bins_by_index)]


def missing_topics(contents: BagContents) -> list[str]:
    """CORE_TOPICS the recording lacks (all of them: not a c4d flight)."""
    return [t for t in CORE_TOPICS if t not in contents.topics]


def summarize(contents: BagContents, topics: Iterable[str] = SUMMARY_TOPICS) -> tuple[FlightFigures, list[dict[str, Any]]]:
    """One streaming pass over a complete recording: (figures, bins). Raises BagError on damaged
    data. Incomplete recordings are refused (their messages would have to be sorted in memory):
    `repair` them first."""
    if not contents.complete:
        raise BagError(f"{contents.path}: incomplete recording ({contents.problem}); run `repair` on it first")
    summarizer = FlightSummarizer(contents.start_ns)
    decoders = Decoders()
    wanted = [t for t in topics if t in contents.topics]
    for topic, message in iter_messages(contents, wanted, log_time_order=True):
        summarizer.add(topic.name, message.log_time, decoders.decode(topic, message.data))
    return summarizer.figures(contents), summarizer.bins()


# label, unit, format of every figure: the report's summary table and the catalog's HTML index
FIGURE_LABELS: dict[str, tuple[str, str]] = {
    "duration_s": ("duration", "s"), "distance_m": ("distance flown", "m"), "max_altitude_m": ("max altitude", "m"),
    "tracking_rms_m": ("tracking error RMS", "m"), "tracking_max_m": ("tracking error max", "m"),
    "overruns": ("executive overruns", ""), "worst_tick_load_pct": ("worst tick load", "%"),
    "failsafes": ("failsafes", ""), "failsafe_actions": ("failsafe actions", ""),
    "battery_used_pct": ("battery used", "%"), "energy_wh": ("energy used", "Wh"),
    "energy_wh_per_km": ("energy per km", "Wh/km"), "captures": ("captures", ""),
}


def format_figure(value: Any) -> str:
    """How a figure reads in the report and the catalog page."""
    if value is None:
        return "—"
    if isinstance(value, float):
        return f"{value:.3f}" if abs(value) < 1e4 else f"{value:.0f}"
    return str(value)
