"""GCD+ offset assignment (Ladeira et al., ECRTS 2022; thesis chapter 3, Algorithm 1).

What: choose offsets O_i for periodic tasks on one non-preemptive resource so that no job
ever waits. Time is cut into cycles of Ω = gcd(T_i); a task with subperiod T_S = T/Ω is
released once every T_S cycles. Tasks whose subperiods share a prime p go to section Ψ_p
(Ψ_1 holds the T_S = 1 tasks); two tasks of one section never meet if their first cycles are
incongruent modulo gcd(T_S,i, T_S,j) (Lemma 3.2.1), and when they must share a cycle the later
one gets an internal offset O_I after the earlier one ends. Sections are laid out one after
the other inside the cycle, by increasing p, and O = Ω·O_C + O_S + O_I (Eq. 3.8).
Lemma 3.2.2 certificate: C_i ≤ Ω for all i and Σ δ_p ≤ Ω ⇒ zero interference.

Ambiguities of the thesis, and how this module resolves them (docs/gcdplus.md has more):
1. Processing order. Algorithm 1 says decreasing C; the text's case study only works with
   increasing T then decreasing C. Every order in ORDER_VARIANTS is tried; the first whose
   certificate holds wins (zero interference is optimal); if none holds, each is run through
   the exact FIFO evaluator and the best (fewest deadline-missing tasks, then smallest max η/T,
   then smallest Σ η/T, then variant order) wins. The winner is reported.
2. Section choice for a T_S with several primes. Algorithm 1: "choose p with minimal v_k";
   text: "the section with the least increase in its duration". Key used: (increase of δ_p,
   v_k, p) — the text's criterion first (it is what the certificate sums), then Algorithm 1's.
3. Cycle ties: the smallest cycle index with the minimal v_k (Algorithm 1 line 18).
4. Section size δ_p = max(O_I + C) over its tasks (Algorithm 1 line 23), start O_S = sum of
   the sizes of sections with a smaller p (Ψ_1 first), as in Table 3.1.
5. When Σδ > Ω the raw offset can reach T_i; it is reduced modulo T_i (same steady state).
6. Precedence (§3.4): chains are placed first, in decreasing total C; a chain takes one
   section; each successor is put in the earliest (cycle, O_I) that starts ≥ X after its
   predecessor ends (unwrapped cycles, so its offset may exceed T: it then serves the same
   job index), minimising the section's growth first. Free tasks follow in the chosen order.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import NamedTuple

from .arith import gcd_all, prime_factors
from .model import Assignment, TaskSet

ORDER_VARIANTS: dict[str, Callable[[int, Sequence[int], Sequence[int]], tuple[float, ...]]] = {
    # name -> sort key of task i given periods T and wcets C (stable on the task index)
    "decreasing_wcet": lambda i, T, C: (-C[i], i),
    "increasing_period_decreasing_wcet": lambda i, T, C: (T[i], -C[i], i),
    "decreasing_utilisation": lambda i, T, C: (-C[i] / T[i], -C[i], i),
}


class Placement(NamedTuple):
    """Where GCD+ put one task (columns of thesis Table 3.1); a NamedTuple because GCD+ builds
    one per task on its hot path."""

    section: int  # p (1 for T_S = 1)
    cycle: int  # O_C (unwrapped for chain successors)
    internal: int  # O_I
    section_start: int  # O_S
    section_size: int  # Ψ_p.δ
    offset: int  # O_i


@dataclass(frozen=True)
class GcdPlusResult:
    """Full outcome of one GCD+ run: offsets, the per-task table, sections and certificate."""

    order: str
    omega: int
    placements: tuple[Placement, ...]
    sections: tuple[tuple[int, int, int], ...]  # (p, start O_S, size δ), by increasing p
    sum_delta: int
    max_wcet: int
    certificate: bool
    candidates: tuple[tuple[str, bool, str], ...] = ()  # (order, certificate, score) of all tried

    @property
    def offsets(self) -> tuple[int, ...]:
        return tuple(p.offset for p in self.placements)

    @property
    def certificate_reason(self) -> str:
        if self.certificate:
            return f"zero interference guaranteed: max C = {self.max_wcet} <= Ω = {self.omega} and Σδ = {self.sum_delta} <= Ω"
        if self.max_wcet > self.omega:
            return f"no zero-interference guarantee: max C = {self.max_wcet} > Ω = {self.omega}"
        return f"no zero-interference guarantee: Σδ = {self.sum_delta} > Ω = {self.omega}"


def _conflict_vector(
    subperiod: int, members: Sequence[int], ts: Sequence[int], cycle: Sequence[int], end: Sequence[int]
) -> list[int]:
    """v_k of Algorithm 1 over one period L of its pattern (L = lcm of the gcds, L | subperiod):
    the latest end time (O_I + C) of section members released in a cycle congruent to k."""
    if not members:
        return [0]
    gcd = math.gcd
    gs = [gcd(subperiod, ts[j]) for j in members]
    period = math.lcm(*gs)
    v = [0] * period
    for j, g in zip(members, gs, strict=True):
        x = end[j]
        if g == period:  # one slot per pattern period: no inner loop
            k = cycle[j] % g
            if v[k] < x:
                v[k] = x
            continue
        for k in range(cycle[j] % g, period, g):
            if v[k] < x:
                v[k] = x
    return v


class _Builder:
    """Mutable state of one GCD+ run (sections, cycles, internal offsets)."""

    def __init__(self, periods: Sequence[int], wcets: Sequence[int]) -> None:
        self.T, self.C = list(periods), list(wcets)
        self.omega = gcd_all(self.T)
        self.ts = [t // self.omega for t in self.T]
        n = len(self.T)
        self.section = [0] * n
        self.cycle = [0] * n  # O_C modulo T_S (used for conflicts)
        self.unwrapped = [0] * n  # O_C as placed (chain successors may exceed T_S)
        self.internal = [0] * n
        self.end = [0] * n  # O_I + C
        self.members: dict[int, list[int]] = {}
        self.delta: dict[int, int] = {}

    def sections_for(self, i: int) -> tuple[int, ...]:
        return (1,) if self.ts[i] == 1 else prime_factors(self.ts[i])

    def best_in_section(self, i: int, p: int) -> tuple[int, int, int]:
        """(increase of δ_p, v_k, k) of the best cycle for task i in section p."""
        v = _conflict_vector(self.ts[i], self.members.get(p, ()), self.ts, self.cycle, self.end)
        value = min(v)
        k = v.index(value)
        return max(0, value + self.C[i] - self.delta.get(p, 0)), value, k

    def commit(self, i: int, p: int, unwrapped_cycle: int, internal: int) -> None:
        self.section[i] = p
        self.unwrapped[i] = unwrapped_cycle
        self.cycle[i] = unwrapped_cycle % self.ts[i]
        self.internal[i] = internal
        self.end[i] = internal + self.C[i]
        self.members.setdefault(p, []).append(i)
        self.delta[p] = max(self.delta.get(p, 0), self.end[i])

    def place_free(self, i: int) -> None:
        primes = self.sections_for(i)
        if len(primes) == 1:  # the common case: no section choice to make
            p = primes[0]
            v = _conflict_vector(self.ts[i], self.members.get(p, ()), self.ts, self.cycle, self.end)
            value = min(v)
            self.commit(i, p, v.index(value), value)
            return
        best = None
        for p in primes:
            increase, value, k = self.best_in_section(i, p)
            key = (increase, value, p)
            if best is None or key < best[0]:
                best = (key, p, k, value)
        assert best is not None
        _, p, k, value = best
        self.commit(i, p, k, value)

    def place_successor(self, i: int, pred: int, separation: int) -> None:
        """Put chain task i in its predecessor's section, starting ≥ separation after it ends."""
        p, s, omega = self.section[pred], self.ts[i], self.omega
        v = _conflict_vector(s, self.members.get(p, ()), self.ts, self.cycle, self.end)
        earliest = omega * self.unwrapped[pred] + self.internal[pred] + self.C[pred] + separation
        first_cycle = earliest // omega
        best = None
        for k in range(first_cycle, first_cycle + s):
            internal = max(v[k % len(v)], earliest - omega * k)
            increase = max(0, internal + self.C[i] - self.delta.get(p, 0))
            key = (increase, omega * k + internal)
            if best is None or key < best[0]:
                best = (key, k, internal)
        assert best is not None
        _, k, internal = best
        self.commit(i, p, k, internal)

    def result(self, order: str) -> GcdPlusResult:
        starts, start = {}, 0
        for p in sorted(self.delta):
            starts[p] = start
            start += self.delta[p]
        placements = []
        for i in range(len(self.T)):
            p = self.section[i]
            raw = self.omega * self.unwrapped[i] + starts[p] + self.internal[i]
            chained_late = self.unwrapped[i] >= self.ts[i]
            offset = raw if chained_late else raw % self.T[i]
            placements.append(Placement(p, self.unwrapped[i], self.internal[i], starts[p], self.delta[p], offset))
        sum_delta, max_wcet = sum(self.delta.values()), max(self.C)
        return GcdPlusResult(
            order=order,
            omega=self.omega,
            placements=tuple(placements),
            sections=tuple((p, starts[p], self.delta[p]) for p in sorted(self.delta)),
            sum_delta=sum_delta,
            max_wcet=max_wcet,
            certificate=max_wcet <= self.omega and sum_delta <= self.omega,
        )


def run_order(taskset: TaskSet, order: str) -> GcdPlusResult:
    """One GCD+ run with a given processing order (precedence chains placed first)."""
    T, C = taskset.periods, taskset.wcets
    key = ORDER_VARIANTS[order]
    builder = _Builder(T, C)
    chained: set[int] = set()
    chains = sorted(
        ([taskset.index(name) for name in chain.tasks], chain.separation) for chain in taskset.chains
    )
    chains.sort(key=lambda item: -sum(C[i] for i in item[0]))
    for members, separation in chains:
        builder.place_free(members[0])
        for pred, succ in zip(members, members[1:], strict=False):
            builder.place_successor(succ, pred, separation)
        chained.update(members)
    for i in sorted((i for i in range(len(T)) if i not in chained), key=lambda i: key(i, T, C)):
        builder.place_free(i)
    return builder.result(order)


def _score(taskset: TaskSet, result: GcdPlusResult) -> tuple[tuple[float, ...], str]:
    from .fifo import evaluate  # local: fifo imports numpy, keep GCD+ import-light

    evaluation = evaluate(taskset, result.offsets)
    ratios = [m.max_delay / m.period for m in evaluation.tasks]
    key = (evaluation.tasks_missing_deadlines, max(ratios), sum(ratios))
    return key, f"missing={key[0]} max η/T={key[1]:.4f} Σ η/T={key[2]:.4f}"


def gcd_plus(taskset: TaskSet, orders: Sequence[str] | None = None) -> Assignment:
    """GCD+ with the order ambiguity resolved by evaluation (see module docstring)."""
    names = list(orders) if orders else list(ORDER_VARIANTS)
    for name in names:
        if name not in ORDER_VARIANTS:
            raise ValueError(f"unknown GCD+ order '{name}' (known: {', '.join(ORDER_VARIANTS)})")
    tried: list[tuple[str, bool, str]] = []
    results: list[GcdPlusResult] = []
    for name in names:
        result = run_order(taskset, name)
        if result.certificate:
            tried.append((name, True, "certificate"))
            winner = _with_candidates(result, tried)
            return Assignment("gcdplus", winner.offsets, winner, f"order {name} (certificate holds)")
        results.append(result)
    from .fifo import EvaluationTooLarge  # local: fifo imports numpy, keep GCD+ import-light

    scored = []
    try:
        for position, result in enumerate(results):
            key, text = _score(taskset, result)
            tried.append((result.order, False, text))
            scored.append((key, position, result))
    except EvaluationTooLarge as too_large:
        # GCD+ itself never needs H; only the tie-break does. Keep the first order, say why.
        tried = [(r.order, False, "not evaluated") for r in results]
        winner = _with_candidates(results[0], tried)
        return Assignment("gcdplus", winner.offsets, winner,
                          f"order {results[0].order} (first order; exact evaluation skipped: {too_large})")
    _, _, best = min(scored, key=lambda item: (item[0], item[1]))
    winner = _with_candidates(best, tried)
    return Assignment("gcdplus", winner.offsets, winner, f"order {best.order} (best by exact evaluation)")


def _with_candidates(result: GcdPlusResult, tried: list[tuple[str, bool, str]]) -> GcdPlusResult:
    return GcdPlusResult(**{**result.__dict__, "candidates": tuple(tried)})
