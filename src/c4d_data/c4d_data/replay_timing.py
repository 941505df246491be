"""Replay timing and topic selection, free of ROS.

Why: replaying a recorded flight into the live tools must reproduce each topic's message
count exactly and its rate (within a few per cent): message k is due at wall time
w0 + (log_k - t0) / rate, where t0 is the log time of the first replayed instant (recording
start + start offset). Timing is absolute (no accumulated sleep error); a late publisher
catches up instead of drifting. Topic selection uses regular expressions like the recorder.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field


@dataclass
class ReplayOptions:
    rate: float = 1.0
    start_offset_s: float = 0.0
    loop: bool = False
    include: list[str] = field(default_factory=list)
    exclude: list[str] = field(default_factory=list)
    clock_hz: float = 0.0  # 0 = no /clock
    delay_s: float = 1.0  # wait for subscribers to match before the first message

    def validate(self) -> None:
        if not self.rate > 0:
            raise ValueError(f"rate must be > 0, not {self.rate}")
        if self.start_offset_s < 0:
            raise ValueError(f"start offset must be >= 0, not {self.start_offset_s}")
        if self.clock_hz < 0 or self.delay_s < 0:
            raise ValueError("clock rate and delay must be >= 0")
        for pattern in self.include + self.exclude:
            try:
                re.compile(pattern)
            except re.error as exc:
                raise ValueError(f"bad topic pattern {pattern!r}: {exc}") from None


def select_topics(names: list[str], include: list[str], exclude: list[str]) -> list[str]:
    """Topics matching any include pattern (all when none) and no exclude pattern, sorted."""
    inc = [re.compile(p) for p in include]
    exc = [re.compile(p) for p in exclude]
    return sorted(n for n in names if (not inc or any(r.search(n) for r in inc)) and not any(r.search(n) for r in exc))


class Clock:
    """Maps recording log time <-> wall time for one pass of the replay."""

    def __init__(self, first_log_ns: int, wall_start_ns: int, rate: float) -> None:
        self.first_log_ns = first_log_ns
        self.wall_start_ns = wall_start_ns
        self.rate = rate

    def due(self, log_ns: int) -> int:
        """Wall time (ns) at which a message logged at log_ns must be published."""
        return self.wall_start_ns + int((log_ns - self.first_log_ns) / self.rate)

    def log_time(self, wall_ns: int) -> int:
        """Recording time shown on /clock at wall time wall_ns."""
        return self.first_log_ns + int((wall_ns - self.wall_start_ns) * self.rate)
