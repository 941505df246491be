"""How steadily the GNC core's actuator commands reach the simulated vehicle.

What: the gap between consecutive `control/actuators` messages as the sim takes them, measured on
the commands' own stamps (the core stamps each tick's command with its tick time), so the figure
is the stream the ESCs really saw — a tick the core never ran, a message DDS lost or delivered
late all widen it — and not the sim's own scheduling. Kept per report window and since start:
worst gap, the 99.9th percentile (0.1 ms bins up to 100 ms) and how many gaps exceeded 20 ms.
Why: the core must never starve the motors whatever other nodes do (issue 13); the ESC stops the
motors after 0.2 s without a command, long before that the vehicle has already sagged. Tests and
bench/interference.py read this from the simulator, not from the core's opinion of itself.
"""

from __future__ import annotations

from dataclasses import dataclass

BIN_S = 1e-4
MAX_BINNED_S = 0.1
LONG_GAP_S = 0.020


@dataclass(frozen=True)
class LinkReport:
    messages_total: int
    window_max_gap_ms: float
    max_gap_ms: float
    p999_gap_ms: float
    long_gaps_total: int  # gaps > 20 ms since start


class ActuatorLinkMonitor:
    """Histogram of command-to-command gaps (see the module docstring)."""

    def __init__(self) -> None:
        self.bins = [0] * (int(MAX_BINNED_S / BIN_S) + 1)  # last bin: everything longer
        self.last_stamp: float | None = None
        self.messages = 0
        self.window_max = 0.0
        self.max_gap = 0.0
        self.long_gaps = 0

    def on_command(self, stamp_s: float) -> None:
        """A command stamped `stamp_s` [s] was taken; stamps going backwards (a restarted core) restart the gap."""
        self.messages += 1
        last, self.last_stamp = self.last_stamp, stamp_s
        if last is None or stamp_s <= last:
            return
        gap = stamp_s - last
        self.bins[min(int(gap / BIN_S), len(self.bins) - 1)] += 1
        self.window_max = max(self.window_max, gap)
        self.max_gap = max(self.max_gap, gap)
        if gap > LONG_GAP_S:
            self.long_gaps += 1

    def percentile_s(self, q: float) -> float:
        """Upper edge of the bin holding the q-quantile of the gaps (0 without gaps; inf past the last bin)."""
        total = sum(self.bins)
        if total == 0:
            return 0.0
        rank, seen = q * total, 0
        for i, count in enumerate(self.bins):
            seen += count
            if seen >= rank:
                return (i + 1) * BIN_S if i < len(self.bins) - 1 else self.max_gap
        return self.max_gap

    def report(self) -> LinkReport:
        """Figures so far; starts a new window."""
        report = LinkReport(self.messages, self.window_max * 1e3, self.max_gap * 1e3, self.percentile_s(0.999) * 1e3,
                            self.long_gaps)
        self.window_max = 0.0
        return report
