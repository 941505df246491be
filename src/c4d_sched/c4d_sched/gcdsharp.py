"""GCD# offset assignment for time-triggered flows in a switched network (thesis chapter 4).

What: initial offsets O_i for strictly periodic flows on fixed paths of output ports so that,
with a constant store-and-forward delay SF per hop (Def. 4.13), no frame ever waits in an
output queue (minimal latency condition, Def. 4.8). A frame of flow i sent at O_i is on the
wire of its h-th port during [O_i + h·SF, O_i + h·SF + C_i). Like GCD+ (gcdplus.py): cycles of
Ω = gcd(T_i), sections Ψ_p by the primes of the subperiod T_S = T/Ω, a cycle O_C per flow, an
internal offset O_I, section starts O_S, and O = Ω·O_C + O_S + O_I (Eq. 3.8). What changes
(§4.4): only flows that share an output port can collide, and a shared port is reached at
different hop counts, so the other flow's position is shifted by (its hop − our hop)·SF.

Steps and the ambiguities resolved (docs/gcdsharp.md has the discussion):
1. Sections (§4.4.1): flows with a single candidate (T_S = 1 → Ψ_1, or T_S = p^n) are placed
   first; the others in decreasing C (ties: input order): the lowest prime when none of their
   candidate sections is occupied, else the occupied candidate with the lowest score (Eq. 4.1,
   exact fractions; ties: lower p). The score sums over the flows that can collide with the
   candidate (crossing flows, or all section flows with cycle_load="section").
2. Cycles (§4.4.2), per section in decreasing C (ties: input order): v_k = Σ C_j of the placed
   section flows with O_C,j ≡ k (mod gcd(T_S,i, T_S,j)); the stated rule counts only crossing
   flows (default, cycle_load="crossing"); the worked example counts every flow of the section
   (cycle_load="section" reproduces its offsets 0, 13, 10, 3, 23, 10). The lowest k with v_k = 0
   wins; with none free, every k is tried and the one with the smallest internal offset wins
   (ties: smaller v_k, then smaller k) — the text's treatment of S_6.
3. Internal offset (§4.4.3): the smallest O_I ≥ 0 such that i's frame does not overlap, on a
   shared port, the frame of any placed crossing flow j of the same section, j shifted by
   (h_j − h_i)·SF (Eq. 4.2 with the correction). Checked exactly modulo g = Ω·gcd(T_S,i, T_S,j)
   and for every cycle of j (its distance Ω·(O_C,j − O_C,i) included) rather than only for
   congruent cycles: identical to the text while frames stay inside their cycle, and still
   exact when a late hop spills into the next cycle.
4. Section sizes (§4.4.4), sections ordered by p: for i in Ψ_a and j in a later Ψ_b,
   w(i, j) = O_I,i + C_i + (h_i − h_j)·SF − O_I,j if they cross and share a cycle
   (O_C,i ≡ O_C,j mod gcd(T_S,i, T_S,j)), else O_I,i + C_i (the text's table, which omits
   −O_I,j and the cycle test: both only drop pairs or slack that cannot collide);
   O_S(b) = max over every earlier a (not only the adjacent one: a far-late frame of Ψ_a can
   otherwise reach a flow of Ψ_c) of O_S(a) + max w; the total Σδ also covers the wrap to the
   next cycle (later section → earlier section, j one cycle later). δ_p = O_S(next) − O_S(p).
   On the worked example this gives the text's δ_2 = 3, δ_3 = 6.
5. O = Ω·O_C + O_S + O_I, reduced modulo T (same steady state) when Σδ > Ω pushes it past T.
Σδ ≤ Ω (and every O_I found conflict-free) is the text's null-interference indicator; the
independent per-port simulation in network_verify.py is the judge.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

from .arith import gcd_all, prime_factors
from .network_model import Network

CYCLE_LOADS = ("crossing", "section")


@dataclass(frozen=True)
class FlowPlacement:
    """Where GCD# put one flow (the thesis' per-flow table)."""

    section: int  # p
    cycle: int  # O_C
    internal: int  # O_I
    section_start: int  # O_S
    offset: int  # O_i
    conflict_free: bool  # an O_I without overlap with the section's placed crossing flows existed


@dataclass(frozen=True)
class GcdSharpResult:
    """Outcome of one GCD# run: offsets, per-flow placements, sections and the indicator."""

    omega: int
    store_and_forward: int
    cycle_load: str
    order: tuple[int, ...]  # cycle/internal-offset assignment order (flow indices)
    placements: tuple[FlowPlacement, ...]
    sections: tuple[tuple[int, int, int], ...]  # (p, O_S, δ_p) by increasing p
    sum_delta: int
    max_end_to_end: int

    @property
    def offsets(self) -> tuple[int, ...]:
        return tuple(p.offset for p in self.placements)

    @property
    def indicator(self) -> bool:
        """The text's null-interference indicator: Σδ ≤ Ω and every flow found a free slot."""
        return self.sum_delta <= self.omega and all(p.conflict_free for p in self.placements)


def _subperiods(net: Network) -> tuple[int, list[int]]:
    omega = gcd_all(net.periods)
    return omega, [t // omega for t in net.periods]


def _internal(i: int, k: int, placed: list[int], cyc: list[int], intl: list[int], net: Network,
              omega: int, ts: list[int], wcet: list[int]) -> int | None:
    """Smallest O_I ≥ 0 for flow i in cycle k with no overlap on a shared port with any placed
    crossing flow of the section (exact, modulo the pair's g); None if none exists."""
    sf, ci = net.store_and_forward, wcet[i]
    cons: list[tuple[int, int, int]] = []
    for j in placed:
        c = net.crossing(i, j)
        if c is None:
            continue
        g = omega * math.gcd(ts[i], ts[j])
        if g < ci + wcet[j]:
            return None  # the two frames cannot both fit in g: no offset avoids the overlap
        cons.append((omega * (cyc[j] - k) + intl[j] + (c.hop_b - c.hop_a) * sf, wcet[j], g))
    o, limit = 0, omega * ts[i]
    moved = True
    while moved:
        moved = False
        for s, cj, g in cons:
            d = (s - o) % g  # j's frame starts d after ours (modulo g)
            if d < ci:
                o += d + cj  # j starts inside our frame: start after it ends
            elif d > g - cj:
                o += d - g + cj  # j's previous copy still runs at o: start after it ends
            else:
                continue
            moved = True
            if o >= limit:
                return None
    return o


def gcdsharp(net: Network, cycle_load: str = "crossing") -> GcdSharpResult:
    """Run GCD# on a validated network (see the module docstring for the steps)."""
    if cycle_load not in CYCLE_LOADS:
        raise ValueError(f"cycle_load must be one of {CYCLE_LOADS}, got {cycle_load!r}")
    n = len(net.flows)
    omega, ts = _subperiods(net)
    wcet = list(net.wcets)
    sf = net.store_and_forward

    def counted(i: int, j: int) -> bool:
        return cycle_load == "section" or net.crossing(i, j) is not None

    # 1. sections
    options = [prime_factors(t) or (1,) for t in ts]
    members: dict[int, list[int]] = {}
    section = [0] * n
    single = [i for i in range(n) if len(options[i]) == 1]
    multi = sorted((i for i in range(n) if len(options[i]) > 1), key=lambda i: (-wcet[i], i))
    for i in single:
        section[i] = options[i][0]
        members.setdefault(section[i], []).append(i)
    for i in multi:
        occupied = [p for p in options[i] if members.get(p)]
        if not occupied:
            p = options[i][0]
        else:
            def score(p: int, i: int = i) -> Fraction:
                total = sum((Fraction(1, math.gcd(ts[i], ts[j])) for j in members[p] if counted(i, j)), Fraction(0))
                return min(Fraction(1), total)
            p = min(occupied, key=lambda q: (score(q), q))
        section[i] = p
        members.setdefault(p, []).append(i)

    # 2.-3. cycles and internal offsets
    order = sorted(range(n), key=lambda i: (-wcet[i], i))
    cyc, intl, free = [0] * n, [0] * n, [True] * n
    placed: dict[int, list[int]] = {p: [] for p in members}
    for i in order:
        peers = placed[section[i]]
        v = [0] * ts[i]
        for j in peers:
            if counted(i, j):
                g = math.gcd(ts[i], ts[j])
                for k in range(cyc[j] % g, ts[i], g):
                    v[k] += wcet[j]
        zero = [k for k in range(ts[i]) if v[k] == 0]
        choice: tuple[int, int | None] | None = None
        if zero:
            o = _internal(i, zero[0], peers, cyc, intl, net, omega, ts, wcet)
            if o is not None:
                choice = (zero[0], o)
        if choice is None:
            best: tuple[float, int, int] | None = None
            for k in range(ts[i]):
                o = _internal(i, k, peers, cyc, intl, net, omega, ts, wcet)
                key = (math.inf if o is None else o, v[k], k)
                if best is None or key < best:
                    best = key
            assert best is not None
            choice = (best[2], None if best[0] == math.inf else int(best[0]))
        cyc[i] = choice[0]
        intl[i] = choice[1] if choice[1] is not None else 0
        free[i] = choice[1] is not None
        peers.append(i)

    # 4. section starts and sizes
    secs = sorted(members)
    extent = {p: max(intl[i] + wcet[i] for i in members[p]) for p in secs}

    def sep(a: int, b: int, shift: int = 0) -> int:
        """Least distance from the start of Ψ_a to the start of a later Ψ_b (text's w table);
        shift = 1 when Ψ_b's flows are those of the next cycle (wrap)."""
        worst = extent[a]
        for i in members[a]:
            for j in members[b]:
                c = net.crossing(i, j)
                if c is not None and (cyc[j] - cyc[i] - shift) % math.gcd(ts[i], ts[j]) == 0:
                    worst = max(worst, intl[i] + wcet[i] + (c.hop_a - c.hop_b) * sf - intl[j])
        return worst

    start: dict[int, int] = {}
    for x, b in enumerate(secs):
        start[b] = 0 if x == 0 else max(start[a] + sep(a, b) for a in secs[:x])
    total = start[secs[-1]] + extent[secs[-1]]
    if len(secs) > 1:
        for xa, a in enumerate(secs):
            for b in secs[: xa + 1]:
                if a != b:
                    total = max(total, start[a] + sep(a, b, 1) - start[b])
    sections = tuple((p, start[p], (start[secs[x + 1]] if x + 1 < len(secs) else total) - start[p])
                     for x, p in enumerate(secs))

    # 5. offsets
    placements = tuple(
        FlowPlacement(section[i], cyc[i], intl[i], start[section[i]],
                      (omega * cyc[i] + start[section[i]] + intl[i]) % net.flows[i].period, free[i])
        for i in range(n))
    return GcdSharpResult(omega, sf, cycle_load, tuple(order), placements, sections, total,
                          max(net.end_to_end(i) for i in range(n)))
