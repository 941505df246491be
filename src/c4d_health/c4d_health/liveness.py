"""Node liveness from message arrivals, not fooled by the monitor's own stalls.

What: each watched node proves it is alive by a periodic topic; `heard(name, t)` records an
arrival, `dead(t)` (called at the monitor's tick) lists the nodes silent for longer than
`timeout_s`.

Why the stall rule: on a loaded machine the monitor itself can be descheduled for hundreds of
milliseconds. When it resumes, its timer may fire before the messages queued meanwhile are
delivered, and every node would look silent for the length of the stall — a false "dead node"
and a needless landing. Time the monitor did not run (a tick gap beyond `period_s` plus half a
period) is therefore not counted as anybody's silence: a node is dead only after staying silent
for `timeout_s` of the monitor's running time. A node that really died is still detected, at
worst one stall later.
"""

from __future__ import annotations

from collections.abc import Iterable


class LivenessMonitor:
    def __init__(self, names: Iterable[str], timeout_s: float, period_s: float, start: float) -> None:
        if timeout_s <= 0 or period_s <= 0:
            raise ValueError("timeout_s and period_s must be > 0")
        self.timeout_s = timeout_s
        self.period_s = period_s
        self.last_seen = {name: start for name in names}  # never heard yet: silent since start
        self.last_check = start
        self.stalled_s = 0.0  # monitor stall time discounted so far (for diagnostics)

    def heard(self, name: str, t: float) -> None:
        if name in self.last_seen:
            self.last_seen[name] = max(self.last_seen[name], t)

    def dead(self, t: float) -> list[str]:
        """Names silent for more than timeout_s of monitor running time, sorted."""
        stall = (t - self.last_check) - self.period_s
        if stall > self.period_s / 2:
            self.stalled_s += stall
            for name, seen in self.last_seen.items():
                self.last_seen[name] = min(t, seen + stall)
        self.last_check = t
        return sorted(n for n, seen in self.last_seen.items() if t - seen > self.timeout_s)
