"""Node liveness from message arrivals and the ROS graph, not fooled by the monitor's own stalls.

What: each watched node proves it is alive by a periodic topic; `heard(name, t)` records an
arrival, `silent(t)` (called at the monitor's tick) lists the nodes silent for longer than
`timeout_s`. `classify(silent, present)` then tells a DEAD node (silent and gone from the ROS
graph) from a STALLED one (silent but still in the graph: its process runs, its publishing does
not — e.g. blocked in a DDS call); `GraphPresence` holds the graph's node names, sampled by the
node at most once a second (the query walks the discovery cache: not worth the 10 Hz tick).

Why the difference matters: a dead restartable node is restarted by the supervisor within a few
seconds, a stalled one usually resumes by itself; neither is a reason to land at once, and the
policy gives each its own rule. Note that DDS keeps a participant whose process was killed
(SIGKILL) in the graph until its lease expires (Fast DDS default: 20 s); until then such a node
counts as stalled. A node that exits cleanly leaves the graph at once.

Why the stall rule: on a loaded machine the monitor itself can be descheduled for hundreds of
milliseconds. When it resumes, its timer may fire before the messages queued meanwhile are
delivered, and every node would look silent for the length of the stall — a false "dead node"
and a needless landing. Time the monitor did not run (a tick gap beyond `period_s` plus half a
period) is therefore not counted as anybody's silence: a node is dead only after staying silent
for `timeout_s` of the monitor's running time. A node that really died is still detected, at
worst one stall later.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable
from dataclasses import dataclass


class LivenessMonitor:
    """`optional` names (e.g. the offboard gateway, not in every graph) are judged only once they
    have been heard: a graph without them is not a graph with a dead node."""

    def __init__(self, names: Iterable[str], timeout_s: float, period_s: float, start: float,
                 optional: Iterable[str] = ()) -> None:
        if timeout_s <= 0 or period_s <= 0:
            raise ValueError("timeout_s and period_s must be > 0")
        self.timeout_s = timeout_s
        self.period_s = period_s
        self.last_seen = {name: start for name in names}  # never heard yet: silent since start
        self.unheard = set(optional) & set(self.last_seen)  # not judged until heard once
        self.last_check = start
        self.stalled_s = 0.0  # monitor stall time discounted so far (for diagnostics)

    def heard(self, name: str, t: float) -> None:
        if name in self.last_seen:
            self.last_seen[name] = max(self.last_seen[name], t)
            self.unheard.discard(name)

    def silent(self, t: float) -> list[str]:
        """Names silent for more than timeout_s of monitor running time, sorted."""
        stall = (t - self.last_check) - self.period_s
        if stall > self.period_s / 2:
            self.stalled_s += stall
            for name, seen in self.last_seen.items():
                self.last_seen[name] = min(t, seen + stall)
        self.last_check = t
        return sorted(n for n, seen in self.last_seen.items() if t - seen > self.timeout_s and n not in self.unheard)


@dataclass(frozen=True)
class Silence:
    """The silent watched nodes, split by their presence in the ROS graph (each sorted)."""

    dead: tuple[str, ...] = ()  # silent and absent from the graph (or the graph not sampled yet)
    stalled: tuple[str, ...] = ()  # silent but still present in the graph


def classify(silent: Iterable[str], present: Collection[str] | None) -> Silence:
    """Silent + absent = dead, silent + present = stalled; `present` None (no graph sample yet) counts as absent."""
    names = sorted(silent)
    if present is None:
        return Silence(tuple(names))
    return Silence(tuple(n for n in names if n not in present), tuple(n for n in names if n in present))


class GraphPresence:
    """The node names last seen in the ROS graph and when; `due(t)` says a new sample is wanted
    (at most one per `period_s`), `update(t, names)` stores it. None until the first sample."""

    def __init__(self, period_s: float) -> None:
        if period_s <= 0:
            raise ValueError("period_s must be > 0")
        self.period_s = period_s
        self.names: frozenset[str] | None = None
        self.sampled_at: float | None = None

    def due(self, t: float) -> bool:
        return self.sampled_at is None or t - self.sampled_at >= self.period_s

    def update(self, t: float, names: Iterable[str]) -> None:
        self.names, self.sampled_at = frozenset(names), t

    def present(self, name: str) -> bool | None:
        """Whether `name` was in the graph at the last sample (None: not sampled yet)."""
        return None if self.names is None else name in self.names
