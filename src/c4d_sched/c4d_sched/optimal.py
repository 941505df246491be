"""Exact phase / offset assignment with OR-Tools CP-SAT: the yardstick GCD+ is measured against.

Two models, each solved within a time limit; the result says whether the answer is proven
(status OPTIMAL / INFEASIBLE) or only the best found (FEASIBLE, with the solver's bound).

1. Executive (`solve_executive`): a cyclic executive with unit tasks of divider d_i (ticks)
   and budget C_i chooses an integer phase φ_i ∈ [0, d_i) (task i runs at ticks k ≡ φ_i mod d_i);
   minimise Z = max over the ticks k of one hyperperiod H = lcm(d_i) of Σ_{i due at k} C_i —
   the worst per-tick budget sum, i.e. what overruns a tick. One-hot booleans x_{i,p}
   (φ_i = p), one linear constraint per tick. Equal-period chains are one unit (the caller
   merges them); precedence is kept as the difference constraints of precedence.py
   (φ_c − φ_p ≥ L); fixed phases stay fixed. Without precedence or fixed phases one phase is
   pinned to 0 (shifting every phase by one tick permutes the ticks: same Z).
2. FIFO zero interference (`solve_fifo`): tasks/messages (T_i, C_i) on one non-preemptive FIFO
   resource choose offsets O_i ∈ [0, T_i). Thesis Theorem 2.3.1 / Definition 3.1: with
   g = gcd(T_i, T_j) and Δ_ij = (O_j − O_i) mod g, no job of either ever waits for the other iff
   Δ_ij ∈ [C_i, g − C_j]; modelled as O_j − O_i = g·k_ij + r_ij, r_ij ∈ [C_i, g − C_j]. Step 1
   decides this (zero interference found, or proven impossible). Step 2, when it is impossible
   or undecided, minimises D = the largest pairwise overlap max(C_i − Δ_ij, C_j − Δ_ji)
   (Definition 3.1: how far one task's execution runs into the other's release). With two
   tasks that is exactly the worst start delay; with more, FIFO queueing can add up overlaps,
   so callers report the exact FIFO delay of the offsets found (fifo.evaluate) beside D.
   O_0 = 0 (a common shift changes no Δ).
Why CP-SAT: the thesis (§3.3.1.2) found CPLEX / OR-Tools could not solve > 9 tasks in days for
its formulation; these models stay small (one boolean per task phase, one constraint per tick
or per pair) and are warm-started with GCD+'s answer, so even an unproven run is never worse.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import StrEnum

from ortools.sat.python import cp_model

from .precedence import Constraint

MAX_TICKS = 200_000  # executive model: one constraint per tick of the hyperperiod


class SolverInputError(ValueError):
    """Unusable solver input (time limit, hyperperiod too large); one line."""


class SolveStatus(StrEnum):
    """OPTIMAL: proven optimum. FEASIBLE: best found when the time ran out (see the bound).
    INFEASIBLE: proven that no assignment meets the constraints. UNKNOWN: nothing found in time."""

    OPTIMAL = "optimal"
    FEASIBLE = "feasible"
    INFEASIBLE = "infeasible"
    UNKNOWN = "unknown"


_STATUS = {cp_model.OPTIMAL: SolveStatus.OPTIMAL, cp_model.FEASIBLE: SolveStatus.FEASIBLE,
           cp_model.INFEASIBLE: SolveStatus.INFEASIBLE}


@dataclass(frozen=True)
class ExecutiveSolution:
    """Phases (None when none found), the worst tick budget sum they give, the proven lower
    bound on it, and the solver's wall time."""

    status: SolveStatus
    phases: tuple[int, ...] | None
    objective: int | None
    bound: int
    wall_s: float

    @property
    def proven(self) -> bool:
        return self.status in (SolveStatus.OPTIMAL, SolveStatus.INFEASIBLE)


@dataclass(frozen=True)
class FifoSolution:
    """Offsets (None when none found); zero_interference True (found), False (proven
    impossible) or None (undecided in time); max_overlap D of the offsets and its lower bound."""

    status: SolveStatus
    offsets: tuple[int, ...] | None
    zero_interference: bool | None
    max_overlap: int | None
    bound: int
    wall_s: float


def check_time_limit(seconds: float) -> float:
    if isinstance(seconds, bool) or not isinstance(seconds, (int, float)) or not math.isfinite(seconds) or seconds <= 0:
        raise SolverInputError(f"solver time limit must be a positive number of seconds, got {seconds!r}")
    return float(seconds)


def _solver(time_limit_s: float, workers: int, seed: int) -> cp_model.CpSolver:
    solver = cp_model.CpSolver()
    solver.parameters.max_time_in_seconds = time_limit_s
    solver.parameters.num_workers = workers
    solver.parameters.random_seed = seed
    return solver


def tick_loads(dividers: Sequence[int], budgets: Sequence[int], phases: Sequence[int]) -> list[int]:
    """Budget sum of every tick of one hyperperiod (the executive objective is the max)."""
    hyper = math.lcm(*dividers)
    loads = [0] * hyper
    for d, c, p in zip(dividers, budgets, phases, strict=True):
        for k in range(p % d, hyper, d):
            loads[k] += c
    return loads


def solve_executive(dividers: Sequence[int], budgets: Sequence[int], constraints: Sequence[Constraint] = (),
                    fixed: Mapping[int, int] | None = None, time_limit_s: float = 2.0,
                    hint: Sequence[int] | None = None, workers: int = 1, seed: int = 0) -> ExecutiveSolution:
    """Phases minimising the worst per-tick budget sum (model 1 of the module docstring)."""
    check_time_limit(time_limit_s)
    fixed = dict(fixed or {})
    n = len(dividers)
    if n == 0 or len(budgets) != n or any(d <= 0 for d in dividers) or any(c < 0 for c in budgets):
        raise SolverInputError("need one positive divider and one budget >= 0 per task")
    hyper = math.lcm(*dividers)
    if hyper > MAX_TICKS:
        raise SolverInputError(f"hyperperiod of {hyper} ticks exceeds the exact model's limit of {MAX_TICKS}")
    start = time.monotonic()
    model = cp_model.CpModel()
    pinned = None
    if not constraints and not fixed:  # symmetry: pin the unit with the most phases
        pinned = max(range(n), key=lambda i: (dividers[i], -i))
        fixed[pinned] = 0
        if hint is not None:  # shift the warm start to match
            hint = [(h - hint[pinned]) % d for h, d in zip(hint, dividers, strict=True)]
    x: list[list[cp_model.IntVar] | None] = []
    for i, d in enumerate(dividers):
        if i in fixed:
            x.append(None)
            continue
        row = [model.new_bool_var(f"x{i}_{p}") for p in range(d)]
        model.add_exactly_one(row)
        x.append(row)
    def phase_terms(i: int, sign: int) -> tuple[list[cp_model.IntVar], list[int], int]:
        row = x[i]
        if row is None:
            return [], [], sign * (fixed[i] % dividers[i])
        return row, [sign * p for p in range(dividers[i])], 0

    for con in constraints:  # φ_c − φ_p ≥ L
        vc, wc, kc = phase_terms(con.consumer, 1)
        vp, wp, kp = phase_terms(con.producer, -1)
        if vc or vp:
            model.add(cp_model.LinearExpr.weighted_sum(vc + vp, wc + wp) >= con.lower - kc - kp)
        elif kc + kp < con.lower:
            model.add_bool_or([])  # two fixed phases that break the edge
    base = [0] * hyper
    for i, d in enumerate(dividers):
        if x[i] is None:
            for k in range(fixed[i] % d, hyper, d):
                base[k] += budgets[i]
    top = sum(budgets)
    z = model.new_int_var(max(max(base), -(-sum(c * (hyper // d) for c, d in zip(budgets, dividers, strict=True)) // hyper)),
                          top, "z")
    live = [(i, d, budgets[i], row) for i, (d, row) in enumerate(zip(dividers, x, strict=True)) if row is not None]
    for k in range(hyper):
        terms = [row[k % d] for _, d, _, row in live]
        weights = [c for _, _, c, _ in live]
        model.add(cp_model.LinearExpr.weighted_sum(terms, weights) + base[k] <= z)
    model.minimize(z)
    if hint is not None:
        for i, d, _, row in live:
            for p in range(d):
                model.add_hint(row[p], p == hint[i] % d)
    solver = _solver(time_limit_s, workers, seed)
    code = solver.solve(model)
    status = _STATUS.get(code, SolveStatus.UNKNOWN)
    wall = time.monotonic() - start
    if status is SolveStatus.INFEASIBLE:
        return ExecutiveSolution(status, None, None, 0, wall)
    bound = int(math.ceil(solver.best_objective_bound - 1e-9))
    phases: tuple[int, ...] | None = None
    objective: int | None = None
    if status is not SolveStatus.UNKNOWN:
        phases = tuple(int(fixed[i] % d) if row is None else next(p for p in range(d) if solver.boolean_value(row[p]))
                       for i, (d, row) in enumerate(zip(dividers, x, strict=True)))
        objective = max(tick_loads(dividers, budgets, phases))
    if hint is not None and _hint_ok(hint, dividers, constraints, fixed):
        hinted = max(tick_loads(dividers, budgets, hint))
        if objective is None or hinted < objective:  # the warm start was better than what the time allowed
            phases, objective = tuple(int(h) % d for h, d in zip(hint, dividers, strict=True)), hinted
            status = SolveStatus.FEASIBLE
    if phases is None or objective is None:
        return ExecutiveSolution(SolveStatus.UNKNOWN, None, None, bound, wall)
    if objective <= bound:
        status, bound = SolveStatus.OPTIMAL, objective
    return ExecutiveSolution(status, phases, objective, bound, wall)


def _hint_ok(hint: Sequence[int], dividers: Sequence[int], constraints: Sequence[Constraint],
             fixed: Mapping[int, int]) -> bool:
    """Whether a warm start meets the hard constraints (it may then stand in for the solver's answer)."""
    if len(hint) != len(dividers) or any(not 0 <= h < d for h, d in zip(hint, dividers, strict=True)):
        return False
    if any(hint[i] != p % dividers[i] for i, p in fixed.items()):
        return False
    return all(hint[c.consumer] - hint[c.producer] >= c.lower for c in constraints)


def solve_fifo(periods: Sequence[int], wcets: Sequence[int], time_limit_s: float = 2.0,
               hint: Sequence[int] | None = None, workers: int = 1, seed: int = 0) -> FifoSolution:
    """Zero-interference offsets, or a proof that none exist and the least max overlap (model 2)."""
    check_time_limit(time_limit_s)
    n = len(periods)
    if n == 0 or len(wcets) != n or any(not 0 < c <= t for c, t in zip(wcets, periods, strict=True)):
        raise SolverInputError("need periods T > 0 and wcets 0 < C <= T, one each per task")
    start = time.monotonic()
    deadline = start + time_limit_s
    decision = _fifo_model(periods, wcets, hint, allow_overlap=False)
    solver = _solver(time_limit_s / 2 if n > 1 else time_limit_s, workers, seed)
    code = solver.solve(decision[0])
    status = _STATUS.get(code, SolveStatus.UNKNOWN)
    if status in (SolveStatus.OPTIMAL, SolveStatus.FEASIBLE):
        zero_offsets = tuple(int(solver.value(o)) for o in decision[1])
        return FifoSolution(SolveStatus.OPTIMAL, zero_offsets, True, 0, 0, time.monotonic() - start)
    zero = False if status is SolveStatus.INFEASIBLE else None
    model, offs, overlap = _fifo_model(periods, wcets, hint, allow_overlap=True)
    assert overlap is not None
    solver = _solver(max(0.05, deadline - time.monotonic()), workers, seed)
    code = solver.solve(model)
    status = _STATUS.get(code, SolveStatus.UNKNOWN)
    wall = time.monotonic() - start
    floor = 1 if zero is False else 0
    found = status in (SolveStatus.OPTIMAL, SolveStatus.FEASIBLE)
    bound = max(floor, int(math.ceil(solver.best_objective_bound - 1e-9))) if found or status is SolveStatus.UNKNOWN else floor
    offsets: tuple[int, ...] | None = tuple(int(solver.value(o)) for o in offs) if found else None
    value = max_pair_overlap(periods, wcets, offsets) if offsets is not None else None
    if hint is not None and (value is None or max_pair_overlap(periods, wcets, hint) < value):
        offsets, value = tuple(int(o) % t for o, t in zip(hint, periods, strict=True)), max_pair_overlap(periods, wcets, hint)
        status = SolveStatus.FEASIBLE if value > bound else SolveStatus.OPTIMAL
    if offsets is None or value is None:
        return FifoSolution(status, None, zero, None, floor, wall)
    if status is SolveStatus.OPTIMAL:
        bound = value
    return FifoSolution(status, offsets, zero if value > 0 else True, value, bound, wall)


def _fifo_model(periods: Sequence[int], wcets: Sequence[int], hint: Sequence[int] | None,
                allow_overlap: bool) -> tuple[cp_model.CpModel, list[cp_model.IntVar], cp_model.IntVar | None]:
    model = cp_model.CpModel()
    n = len(periods)
    offs = [model.new_int_var(0, 0 if i == 0 else t - 1, f"o{i}") for i, t in enumerate(periods)]
    overlap = model.new_int_var(0, max(wcets), "overlap") if allow_overlap else None
    for i in range(n):
        for j in range(i + 1, n):
            g = math.gcd(periods[i], periods[j])
            ci, cj = wcets[i], wcets[j]
            if overlap is None and ci + cj > g:  # no Δ fits: infeasible outright
                model.add_bool_or([])
                continue
            lo_k, hi_k = (-(periods[i] - 1)) // g - 1, (periods[j] - 1) // g + 1
            k = model.new_int_var(lo_k, hi_k, f"k{i}_{j}")
            r = model.new_int_var(0 if overlap is not None else ci, g - 1 if overlap is not None else g - cj, f"r{i}_{j}")
            model.add(offs[j] - offs[i] == g * k + r)
            if overlap is not None:
                # Δ_ij = r, Δ_ji = (g − r) mod g: overlaps C_i − r and C_j − (g − r), both C when r = 0
                model.add(r >= ci - overlap)
                model.add(g - r >= cj - overlap)
                same = model.new_bool_var(f"z{i}_{j}")
                model.add(r == 0).only_enforce_if(same)
                model.add(r >= 1).only_enforce_if(~same)
                model.add(overlap >= cj).only_enforce_if(same)
    if overlap is not None:
        model.minimize(overlap)
    if hint is not None:
        shift = hint[0]
        for i, o in enumerate(offs):
            model.add_hint(o, (hint[i] - shift) % periods[i])
    return model, offs, overlap


def max_pair_overlap(periods: Sequence[int], wcets: Sequence[int], offsets: Sequence[int]) -> int:
    """max over pairs of Definition 3.1's overlaps (0 = zero interference)."""
    worst = 0
    for i in range(len(periods)):
        for j in range(i + 1, len(periods)):
            g = math.gcd(periods[i], periods[j])
            d_ij, d_ji = (offsets[j] - offsets[i]) % g, (offsets[i] - offsets[j]) % g
            worst = max(worst, wcets[i] - d_ij, wcets[j] - d_ji)
    return worst
