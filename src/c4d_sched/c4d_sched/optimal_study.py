"""Optimality gap of GCD+ against the exact CP-SAT models on the thesis' random task sets.

What: for each random set (generator.py: Dirichlet utilisations, GM01 periods fitted to
Paparazzi, filtered Ω ≥ max C) seen as (a) a cyclic executive whose tick is Ω (dividers
T_i/Ω, budgets C_i) and (b) a FIFO link, it records GCD+'s and Paparazzi's worst per-tick
budget sum, the exact optimum (or best found + bound within the time limit), whether GCD+'s
offsets have zero interference (pairwise condition, exact), whether the exact model finds zero
interference or proves it impossible, and the solver times. `summarise` turns the rows into
the figures of docs/gcdplus.md (how often GCD+ is optimal, its gap, missed zero-interference
sets, solver time median / p95).
Why: the thesis could not run exact solvers beyond nine tasks (§3.3.1.2); this measures how far
the heuristic is from the optimum where the optimum is now reachable.
"""

from __future__ import annotations

import statistics
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from .arith import gcd_all
from .baselines import paparazzi
from .gcdplus import gcd_plus
from .generator import generate_tasksets
from .model import TaskSet
from .optimal import SolveStatus, max_pair_overlap, solve_executive, solve_fifo, tick_loads
from .tickschedule import _best_gcdplus_for_ticks


@dataclass(frozen=True)
class GapRow:
    """One random set's outcome (times in seconds, loads in the set's unit)."""

    n: int
    utilisation: float
    index: int
    gcdplus_load: int
    paparazzi_load: int
    optimal_load: int
    optimal_status: str
    optimal_bound: int
    executive_s: float
    gcdplus_zero: bool
    fifo_zero: bool | None  # True found, False proven impossible, None undecided
    fifo_status: str
    fifo_overlap: int | None
    gcdplus_overlap: int
    fifo_s: float


def study_set(ts: TaskSet, n: int, u: float, index: int, time_limit_s: float, workers: int = 1) -> GapRow:
    """Both models on one set (see module docstring)."""
    omega = gcd_all(ts.periods)
    dividers = [t // omega for t in ts.periods]
    gcd_exec = _best_gcdplus_for_ticks(ts, omega)
    gcd_phases = [(o // omega) % d for o, d in zip(gcd_exec.offsets, dividers, strict=True)]
    pap_phases = [(o // omega) % d for o, d in zip(paparazzi(ts).offsets, dividers, strict=True)]
    gcd_load = max(tick_loads(dividers, ts.wcets, gcd_phases))
    pap_load = max(tick_loads(dividers, ts.wcets, pap_phases))
    best_hint = gcd_phases if gcd_load <= pap_load else pap_phases
    ex = solve_executive(dividers, ts.wcets, time_limit_s=time_limit_s, hint=best_hint, workers=workers)
    assert ex.objective is not None  # the hint is always feasible
    fifo_gcd = gcd_plus(ts).offsets
    gcd_overlap = max_pair_overlap(ts.periods, ts.wcets, fifo_gcd)
    ff = solve_fifo(ts.periods, ts.wcets, time_limit_s=time_limit_s, hint=fifo_gcd, workers=workers)
    return GapRow(n, u, index, gcd_load, pap_load, ex.objective, ex.status.value, ex.bound, ex.wall_s,
                  gcd_overlap == 0, ff.zero_interference, ff.status.value, ff.max_overlap, gcd_overlap, ff.wall_s)


def run_study(sizes: Sequence[int], utilisations: Sequence[float], sets: int, seed: int, time_limit_s: float,
              progress: Callable[[int, int], None] | None = None) -> list[GapRow]:
    rows: list[GapRow] = []
    total, done = len(sizes) * len(utilisations) * sets, 0
    for n in sizes:
        for u in utilisations:
            for index, ts in enumerate(generate_tasksets(n, u, sets, seed=seed)):
                rows.append(study_set(ts, n, u, index, time_limit_s))
                done += 1
                if progress:
                    progress(done, total)
    return rows


def percentile(values: Sequence[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(q * (len(ordered) - 1)))] if ordered else float("nan")


def summarise(rows: Sequence[GapRow]) -> list[dict[str, Any]]:
    """Per set size and overall: GCD+ optimal share, gap distribution (proven optimum or, when the
    time ran out, the bound), zero-interference sets GCD+ misses, solver time median / p95."""
    out: list[dict[str, Any]] = []
    for n in [*sorted({r.n for r in rows}), 0]:
        group = [r for r in rows if n in (0, r.n)]
        proven = [r for r in group if r.optimal_status == SolveStatus.OPTIMAL.value]
        gaps = [r.gcdplus_load / r.optimal_load - 1 for r in proven]
        out.append({
            "n": n or "all", "sets": len(group), "exec_proven": len(proven),
            "gcdplus_optimal": sum(1 for r in proven if r.gcdplus_load == r.optimal_load),
            "paparazzi_optimal": sum(1 for r in proven if r.paparazzi_load == r.optimal_load),
            "gap_median": statistics.median(gaps) if gaps else float("nan"),
            "gap_p95": percentile(gaps, 0.95), "gap_max": max(gaps, default=float("nan")),
            "unproven_gap_to_bound_max": max((r.gcdplus_load / max(1, r.optimal_bound) - 1 for r in group
                                              if r.optimal_status != SolveStatus.OPTIMAL.value), default=0.0),
            "zero_exists": sum(1 for r in group if r.fifo_zero is True),
            "zero_impossible": sum(1 for r in group if r.fifo_zero is False),
            "zero_undecided": sum(1 for r in group if r.fifo_zero is None),
            "gcdplus_zero": sum(1 for r in group if r.gcdplus_zero),
            "zero_missed_by_gcdplus": sum(1 for r in group if r.fifo_zero is True and not r.gcdplus_zero),
            "exec_s_median": statistics.median(r.executive_s for r in group),
            "exec_s_p95": percentile([r.executive_s for r in group], 0.95),
            "fifo_s_median": statistics.median(r.fifo_s for r in group),
            "fifo_s_p95": percentile([r.fifo_s for r in group], 0.95),
        })
    return out
