"""Multi-rate precedence for a cyclic executive: semaphore precedence constraints (SPC).

What: an edge (producer, consumer, w_p, w_c, M0) is the Petri-net pattern of D3.3 §5.2.3.2
(Nguyen et al., DATE 2018): each producer job adds w_p tokens to a place, each consumer job
needs and removes w_c, the place starts with M0 tokens. Consumer job j (1-based inside a
hyperperiod of the pair, any integer outside it) therefore waits for producer job
    i(j) = ⌈(j·w_c − M0) / w_p⌉
(i ≤ 0: a job of an earlier hyperperiod; the D3.3 example, w_p = 3 every 3 ms, w_c = 5 every
5 ms, gives (2, 4, 5) for M0 = 0 and (1, 3, 5) for M0 = 2). Tokens must balance over the
pair's hyperperiod (w_p·n_p = w_c·n_c), else the place grows or starves forever.
How it constrains phases: producer job i runs at tick φ_p + (i−1)·d_p, consumer job j at
φ_c + (j−1)·d_c (φ ∈ [0, d), tick 0 starts every hyperperiod). "Consumer job after the producer
job it depends on, in the same or an earlier tick" is, for all j,
    φ_c − φ_p ≥ max_j [(i(j)−1)·d_p − (j−1)·d_c] + s,
with s = 0 when the in-tick order runs the producer first and s = 1 otherwise. Every edge is
one difference constraint; with the bounds 0 ≤ φ_v ≤ d_v − 1 (or a fixed phase) the system is
solved by longest paths (Bellman-Ford): a positive cycle is an infeasible precedence cycle
(reported with its tasks), the least solution is the earliest feasible phase vector.
Why here and ROS-free: both GCD+ (followed by `repair`) and the exact CP-SAT model
(optimal.py) consume the same `Constraint`s, and the tick schedule builder computes s.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass


class PrecedenceError(ValueError):
    """Invalid or unsatisfiable precedence; one line naming the tasks."""


@dataclass(frozen=True)
class Edge:
    """SPC edge: `consumer` jobs wait for `producer` jobs (w_p tokens produced, w_c consumed, M0 initial)."""

    producer: str
    consumer: str
    w_p: int = 1
    w_c: int = 1
    m0: int = 0

    def __str__(self) -> str:
        return f"{self.producer} -> {self.consumer} (w_p {self.w_p}, w_c {self.w_c}, M0 {self.m0})"


@dataclass(frozen=True)
class Constraint:
    """φ[consumer] − φ[producer] ≥ lower, on scheduling-unit indices (from one Edge)."""

    producer: int
    consumer: int
    lower: int
    edge: Edge


def balanced_weights(d_p: int, d_c: int) -> tuple[int, int]:
    """The smallest (w_p, w_c) that balance over the pair's hyperperiod: w_p/d_p = w_c/d_c."""
    g = math.gcd(d_p, d_c)
    return d_p // g, d_c // g


def dependencies(edge: Edge, jobs_p: int, jobs_c: int) -> list[int]:
    """Producer job i(j) each consumer job j = 1..jobs_c waits for (see module docstring);
    jobs_p, jobs_c are the job counts of one hyperperiod of the pair. Raises on imbalance."""
    check_edge(edge)
    if edge.w_p * jobs_p != edge.w_c * jobs_c:
        raise PrecedenceError(f"edge {edge}: tokens never balance ({jobs_p} x {edge.w_p} produced vs "
                              f"{jobs_c} x {edge.w_c} consumed per hyperperiod)")
    return [-((edge.m0 - j * edge.w_c) // edge.w_p) for j in range(1, jobs_c + 1)]  # ceil division


def check_edge(edge: Edge) -> None:
    """Weights positive integers, M0 an integer, producer ≠ consumer."""
    for what, value in (("w_p", edge.w_p), ("w_c", edge.w_c)):
        if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
            raise PrecedenceError(f"edge {edge.producer} -> {edge.consumer}: {what} must be a positive integer, got {value!r}")
    if isinstance(edge.m0, bool) or not isinstance(edge.m0, int):
        raise PrecedenceError(f"edge {edge.producer} -> {edge.consumer}: M0 must be an integer, got {edge.m0!r}")
    if edge.producer == edge.consumer:
        raise PrecedenceError(f"edge {edge.producer} -> {edge.consumer}: a task cannot precede itself")


def min_phase_difference(edge: Edge, d_p: int, d_c: int) -> int:
    """max_j [(i(j)−1)·d_p − (j−1)·d_c]: the least φ_c − φ_p with the producer first in the tick."""
    hyper = math.lcm(d_p, d_c)
    deps = dependencies(edge, hyper // d_p, hyper // d_c)
    return max((i - 1) * d_p - (j - 1) * d_c for j, i in enumerate(deps, start=1))


def build_constraints(edges: Sequence[Edge], index: Mapping[str, int], dividers: Sequence[int],
                      producer_first: Mapping[tuple[str, str], bool] | None = None) -> list[Constraint]:
    """One Constraint per edge on unit indices (`index` maps a task name to its unit);
    `producer_first[(p, c)]` says whether the in-tick order runs p before c (default: yes)."""
    out = []
    for edge in edges:
        for name in (edge.producer, edge.consumer):
            if name not in index:
                raise PrecedenceError(f"edge {edge}: unknown task '{name}'")
        p, c = index[edge.producer], index[edge.consumer]
        first = True if producer_first is None else producer_first.get((edge.producer, edge.consumer), True)
        lower = min_phase_difference(edge, dividers[p], dividers[c]) + (0 if first else 1)
        out.append(Constraint(p, c, lower, edge))
    return out


class PhaseSystem:
    """Difference constraints on phases: 0 ≤ φ_v ≤ d_v − 1 (or φ_v fixed) and the Constraints."""

    def __init__(self, names: Sequence[str], dividers: Sequence[int], constraints: Sequence[Constraint],
                 fixed: Mapping[int, int] | None = None) -> None:
        self.names, self.dividers = list(names), list(dividers)
        self.constraints = list(constraints)
        self.fixed = dict(fixed or {})
        self.upper = [self.fixed.get(v, d - 1) for v, d in enumerate(self.dividers)]
        self.lower = [self.fixed.get(v, 0) for v in range(len(self.dividers))]

    def least_solution(self, start: Sequence[int] | None = None) -> list[int]:
        """Smallest φ ≥ max(start, lower bounds) meeting every constraint (Bellman-Ford on the
        longest-path form); PrecedenceError when no φ ≥ start exists (bounds or a positive cycle)."""
        n = len(self.dividers)
        self._no_positive_cycle()
        phi = [max(lo, s) for lo, s in zip(self.lower, start if start is not None else self.lower, strict=True)]
        parent: list[int] = [-1] * n
        for _ in range(n + 1):  # no positive cycle: converges within n rounds
            changed = False
            for con in self.constraints:
                need = phi[con.producer] + con.lower
                if need > phi[con.consumer]:
                    phi[con.consumer] = need
                    parent[con.consumer] = con.producer
                    changed = True
            if not changed:
                break
        over = next((v for v in range(n) if phi[v] > self.upper[v]), None)
        if over is not None:
            raise PrecedenceError(f"precedence pushes task '{self.names[over]}' to phase {phi[over]}, beyond "
                                  f"{self.upper[over]} (its divider or fixed phase): {self._chain_text(parent, over)}")
        return phi

    def _no_positive_cycle(self) -> None:
        """PrecedenceError naming the tasks of a cycle whose jobs would wait for themselves."""
        n = len(self.dividers)
        phi, parent = [0] * n, [-1] * n
        changed_at = -1
        for _ in range(n + 1):
            changed_at = -1
            for con in self.constraints:
                if phi[con.producer] + con.lower > phi[con.consumer]:
                    phi[con.consumer] = phi[con.producer] + con.lower
                    parent[con.consumer] = con.producer
                    changed_at = con.consumer
            if changed_at < 0:
                return
        v = changed_at
        for _ in range(n):  # n steps back along the parents lands on the cycle
            v = parent[v]
        cycle, u = [v], parent[v]
        while u != v:
            cycle.append(u)
            u = parent[u]
        names = [self.names[x] for x in reversed(cycle)]
        raise PrecedenceError("infeasible precedence cycle (a job would wait for itself): "
                              + " -> ".join([*names, names[0]]))

    def _chain_text(self, parent: list[int], v: int) -> str:
        chain, u = [v], parent[v]
        while u >= 0 and u not in chain:
            chain.append(u)
            u = parent[u]
        return " -> ".join(self.names[x] for x in reversed(chain))

    def check(self) -> None:
        """PrecedenceError unless some phase vector satisfies everything."""
        self.least_solution()

    def satisfied(self, phases: Sequence[int]) -> bool:
        return all(lo <= p <= up for lo, p, up in zip(self.lower, phases, self.upper, strict=True)) and all(
            phases[c.consumer] - phases[c.producer] >= c.lower for c in self.constraints)

    def repair(self, phases: Sequence[int], budgets: Sequence[int] | None = None) -> list[int]:
        """`phases` if they already meet every constraint; else the least feasible φ ≥ phases, or
        failing that the least feasible φ at all, then (given `budgets`) `improve`d. Heuristics
        such as GCD+ ignore precedence; this is how their answers are made to respect it."""
        if self.satisfied(phases):
            return list(phases)
        try:
            fixed = self.least_solution(phases)
        except PrecedenceError:
            fixed = self.least_solution()
        return self.improve(fixed, budgets) if budgets is not None else fixed

    def interval(self, v: int, phases: Sequence[int]) -> tuple[int, int]:
        """Phases unit v may take with every other unit where it is, all constraints kept."""
        lo, hi = self.lower[v], self.upper[v]
        for con in self.constraints:
            if con.producer == con.consumer:
                continue
            if con.consumer == v:
                lo = max(lo, phases[con.producer] + con.lower)
            elif con.producer == v:
                hi = min(hi, phases[con.consumer] - con.lower)
        return lo, hi

    def improve(self, phases: Sequence[int], budgets: Sequence[int], rounds: int = 3) -> list[int]:
        """Coordinate descent on the worst per-tick budget sum from a feasible φ: each unit in turn
        (largest budget first) moves to the phase inside its `interval` whose ticks carry the least
        load; feasibility holds after every move. A GCD+-like greedy, not an optimum (optimal.py)."""
        phi = list(phases)
        hyper = math.lcm(*self.dividers)
        loads = [0] * hyper
        for d, c, p in zip(self.dividers, budgets, phi, strict=True):
            for k in range(p, hyper, d):
                loads[k] += c
        for _ in range(rounds):
            moved = False
            for v in sorted(range(len(phi)), key=lambda u: (-budgets[u], u)):
                d, c = self.dividers[v], budgets[v]
                lo, hi = self.interval(v, phi)
                if lo >= hi:
                    continue
                for k in range(phi[v], hyper, d):
                    loads[k] -= c
                best = min(range(lo, hi + 1), key=lambda p: (max(loads[p::d]), p != phi[v], p))
                for k in range(best, hyper, d):
                    loads[k] += c
                moved |= best != phi[v]
                phi[v] = best
            if not moved:
                break
        return phi


def in_tick_depth(names: Sequence[str], pairs: Sequence[tuple[str, str]]) -> dict[str, int]:
    """Longest-path depth of each task in the graph of (before, after) pairs, so that sorting by
    depth runs each `before` ahead of its `after` whenever possible; pairs closing a cycle are
    dropped (their consumer then waits a tick: s = 1 in the constraint)."""
    succ: dict[str, list[str]] = {n: [] for n in names}
    indeg = dict.fromkeys(names, 0)
    for a, b in pairs:
        succ[a].append(b)
        indeg[b] += 1
    depth = dict.fromkeys(names, 0)
    done: set[str] = set()
    while len(done) < len(names):
        ready = sorted(n for n in names if n not in done and indeg[n] == 0)
        if not ready:  # a cycle: break it at the smallest remaining name
            ready = [min(n for n in names if n not in done)]
        for n in ready:
            done.add(n)
            for m in succ[n]:
                if m not in done:
                    indeg[m] -= 1
                    depth[m] = max(depth[m], depth[n] + 1)
    return depth
