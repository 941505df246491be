"""GNC core stalls from its executor statistics: long ticks, skipped ticks, or no statistics at all.

What: the core publishes `gnc/executor_stats` once a second (one window each). `on_stats(t,
window)` judges a window: a stall when its worst tick took longer than `worst_tick_ms`
(load_max_percent / 100 x the tick period) or more than `skipped_ticks` ticks were skipped.
`check(t, core_present)` (called at the monitor's tick) adds the "stalled, not dead" rule
applied to the core: statistics silent for `stats_timeout_s` while the core node is still in
the ROS graph mean its executive (or its publishing) is stuck; a core gone from the graph is
node liveness' business (node_dead). It returns a `CoreStallReport`: the current stall with
the measured numbers for people ("worst tick 332 ms, 165 skipped ticks"), and whether stalls
have repeated (`repeat_count` within `repeat_window_s`; each second of silent statistics
counts as one).

Why two levels: one stall of a few tens of milliseconds is survivable (the vehicle coasts on
its last motor outputs for a few ticks) and is only reported; a core that keeps stalling cannot
be trusted to fly the mission, which the policy answers (core_stall_repeated). Silence is
counted in the monitor's own running time (liveness.LivenessMonitor), and only after the first
statistics were heard: a core still starting up is not a stalled one.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

from .liveness import LivenessMonitor
from .policy import CoreStallLimits

STATS_PERIOD_S = 1.0  # the core's statistics window; a silent one counts as one stall per period
CORE = "core"


@dataclass(frozen=True)
class StatsWindow:
    """What stall detection needs of one ExecutorStats message."""

    tick_rate_hz: float  # [Hz]
    load_max_percent: float  # [%] worst tick busy time / tick period
    skipped_ticks: int  # in this window

    @property
    def worst_tick_ms(self) -> float:
        """The window's worst tick [ms] (NaN when the rate is unknown)."""
        if not (math.isfinite(self.tick_rate_hz) and self.tick_rate_hz > 0 and math.isfinite(self.load_max_percent)):
            return math.nan
        return self.load_max_percent / 100.0 * 1000.0 / self.tick_rate_hz


@dataclass(frozen=True)
class CoreStallReport:
    """`stall`: detail of the stall going on now ("" if none); `repeated`: detail when stalls repeat ("" if not)."""

    stall: str = ""
    repeated: str = ""


class CoreStallMonitor:
    def __init__(self, limits: CoreStallLimits, period_s: float, start: float) -> None:
        self.limits = limits
        self.silence = LivenessMonitor([CORE], limits.stats_timeout_s, period_s, start)
        self.heard = False  # statistics heard at least once
        self.window_stall = ""  # detail of the latest window if it was a stall
        self.stalls: deque[float] = deque()  # times of the stalls within repeat_window_s

    def on_stats(self, t: float, window: StatsWindow) -> None:
        self.heard = True
        self.silence.heard(CORE, t)
        worst = window.worst_tick_ms
        if worst > self.limits.worst_tick_ms or window.skipped_ticks > self.limits.skipped_ticks:
            self.window_stall = f"worst tick {worst:.0f} ms, {window.skipped_ticks} skipped ticks"
            self.stalls.append(t)
        else:
            self.window_stall = ""

    def check(self, t: float, core_present: bool | None) -> CoreStallReport:
        """The stall state at the monitor's tick `t`; `core_present`: the core node is in the ROS graph."""
        stall = self.window_stall
        silent = self.silence.silent(t)  # every tick: keeps the monitor-stall discount current
        if self.heard and silent:
            stall = ""  # the latest window is old news; a core gone from the graph is node_dead's
            if core_present:
                quiet_s = t - self.silence.last_seen[CORE]
                stall = f"no executor statistics for {quiet_s:.1f} s (core still in the ROS graph)"
                if not self.stalls or t - self.stalls[-1] >= STATS_PERIOD_S:
                    self.stalls.append(t)
        while self.stalls and t - self.stalls[0] > self.limits.repeat_window_s:
            self.stalls.popleft()
        repeated = ""
        if len(self.stalls) >= self.limits.repeat_count:
            repeated = f"{len(self.stalls)} stalls within {self.limits.repeat_window_s:g} s" + (f"; {stall}" if stall else "")
        return CoreStallReport(stall, repeated)
