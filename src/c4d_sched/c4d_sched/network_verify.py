"""Independent no-overlap verifier for offsets in a switched network (thesis §4.5 check).

What: simulates, on every output port, every transmission of every flow over the port's
hyperperiod — frame k of flow i on its h-th port occupies [O_i + k·T_i + h·SF,
O_i + k·T_i + h·SF + c) with c its transmission time on that port's own link rate — and
reports every pair of transmissions that overlap (on the circle of the port's hyperperiod).
No overlap means no frame ever waits in a queue: the minimal latency condition (Def. 4.8)
holds for the constant-S&F model. Why independent: it uses only the network and the offsets
(none of GCD#'s cycles, sections or internal offsets), so it can judge GCD#, the exact model
or hand-written offsets alike, and a planted overlap makes it fail.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from .arith import lcm_all
from .network_model import Network, NetworkError, Port, port_name

MAX_TRANSMISSIONS = 5_000_000


@dataclass(frozen=True)
class Overlap:
    """Two transmissions on one port that overlap (times within the port's hyperperiod)."""

    port: str
    flow_a: str
    start_a: int
    flow_b: str
    start_b: int


@dataclass(frozen=True)
class Verification:
    """Result of simulating all ports: counts and the first overlaps found."""

    ports: int
    transmissions: int
    overlapping_pairs: int  # distinct (port, flow, flow) pairs with at least one overlap
    overlaps: tuple[Overlap, ...]  # one example per overlapping pair, at most `keep`

    @property
    def ok(self) -> bool:
        return self.overlapping_pairs == 0


def verify(net: Network, offsets: Sequence[int], keep: int = 20) -> Verification:
    """Simulate every port over its hyperperiod; NetworkError if it would take more than
    MAX_TRANSMISSIONS transmissions or the offsets do not match the flows."""
    if len(offsets) != len(net.flows):
        raise NetworkError(f"{len(offsets)} offsets for {len(net.flows)} flows")
    if any(o < 0 for o in offsets):
        raise NetworkError("offsets must be >= 0")
    users: dict[Port, list[tuple[int, int, int]]] = {}  # port -> (flow, hop, transmission time)
    for i, f in enumerate(net.flows):
        for h, (p, c) in enumerate(zip(f.ports, f.tx, strict=True)):
            users.setdefault(p, []).append((i, h, c))
    horizon = {p: lcm_all(net.flows[i].period for i, _, _ in u) for p, u in users.items()}
    count = sum(horizon[p] // net.flows[i].period for p, u in users.items() for i, _, _ in u)
    if count > MAX_TRANSMISSIONS:
        raise NetworkError(f"verification needs {count:,} transmissions (> {MAX_TRANSMISSIONS:,}): "
                           "the ports' hyperperiods are too long")
    sf = net.store_and_forward
    found: dict[tuple[str, int, int], Overlap] = {}
    for p, u in users.items():
        hp = horizon[p]
        frames: list[tuple[int, int, int]] = []  # (start mod hp, end, flow)
        for i, h, c in u:
            t = net.flows[i].period
            first = (offsets[i] + h * sf) % t
            frames += [(s, s + c, i) for s in range(first, hp, t)]
        frames.sort()
        m = len(frames)
        for x, (s, e, i) in enumerate(frames):
            y, lap = x + 1, 0
            while True:  # later frames (wrapping once around the circle) starting before our end
                if y == m:
                    y, lap = 0, hp
                    if m == 1:
                        break
                s2, _, j = frames[y]
                if s2 + lap >= e or (lap and y >= x):
                    break
                key = (port_name(p), min(i, j), max(i, j))
                if key not in found:
                    a, b = (i, j) if i <= j else (j, i)
                    sa, sb = (s, s2) if i <= j else (s2, s)
                    found[key] = Overlap(key[0], net.flows[a].name, sa, net.flows[b].name, sb)
                y += 1
    overlaps = tuple(found[k] for k in sorted(found)[:keep])
    return Verification(len(users), count, len(found), overlaps)

