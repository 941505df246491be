"""Exact CP-SAT models: optimum proven and checked by brute force; zero interference found or proven impossible."""

import itertools
import random

import pytest

from c4d_sched.optimal import (
    SolverInputError,
    SolveStatus,
    max_pair_overlap,
    solve_executive,
    solve_fifo,
    tick_loads,
)
from c4d_sched.precedence import Edge, build_constraints
from c4d_sched.tickschedule import schedule_from_config


def brute_executive(dividers, budgets, ok=lambda phases: True):
    return min(max(tick_loads(dividers, budgets, ph)) for ph in itertools.product(*map(range, dividers)) if ok(ph))


@pytest.mark.parametrize("seed", range(12))
def test_executive_optimum_matches_brute_force(seed):
    rng = random.Random(seed)
    n = rng.randint(2, 5)
    dividers = [rng.choice([1, 2, 3, 4, 6]) for _ in range(n)]
    budgets = [rng.randint(1, 9) for _ in range(n)]
    sol = solve_executive(dividers, budgets, time_limit_s=10)
    assert sol.status is SolveStatus.OPTIMAL and sol.proven
    assert sol.objective == sol.bound == brute_executive(dividers, budgets)
    assert max(tick_loads(dividers, budgets, sol.phases)) == sol.objective


def test_executive_optimum_with_precedence_and_a_fixed_phase_matches_brute_force():
    dividers, budgets = [3, 5, 5, 15], [3, 3, 3, 3]
    cons = build_constraints([Edge("a", "b", 3, 5, 0)], {"a": 0, "b": 1}, dividers)
    fixed = {2: 4}

    def ok(ph):
        return ph[2] == 4 and all(ph[c.consumer] - ph[c.producer] >= c.lower for c in cons)

    sol = solve_executive(dividers, budgets, cons, fixed, time_limit_s=10)
    assert sol.status is SolveStatus.OPTIMAL and ok(sol.phases)
    assert sol.objective == brute_executive(dividers, budgets, ok)


def test_a_worse_hint_never_wins_and_a_better_hint_is_kept_when_time_is_short():
    dividers, budgets = [2, 2, 4, 4], [5, 5, 3, 3]
    sol = solve_executive(dividers, budgets, time_limit_s=5, hint=[0, 0, 0, 0])
    assert sol.objective == 8 and sol.status is SolveStatus.OPTIMAL


@pytest.mark.parametrize("seed", range(10))
def test_fifo_min_overlap_matches_brute_force(seed):
    rng = random.Random(100 + seed)
    n = rng.randint(2, 4)
    periods = [rng.choice([4, 6, 8, 12]) for _ in range(n)]
    wcets = [rng.randint(1, 3) for _ in range(n)]
    best = min(max_pair_overlap(periods, wcets, o) for o in itertools.product(*map(range, periods)))
    sol = solve_fifo(periods, wcets, time_limit_s=10)
    assert sol.status is SolveStatus.OPTIMAL and sol.max_overlap == sol.bound == best
    assert sol.zero_interference is (best == 0)


def test_zero_interference_found_on_the_worked_example():
    periods, wcets = [24, 16, 16, 16], [2, 1, 3, 3]  # thesis worked example (config/worked_example.yaml)
    sol = solve_fifo(periods, wcets, time_limit_s=10)
    assert sol.zero_interference is True and max_pair_overlap(periods, wcets, sol.offsets) == 0


def test_zero_interference_proven_impossible():
    # coprime subperiods 2 and 3 on Ω = 4: the two tasks must share a cycle of 4 yet need 3 + 2 units
    sol = solve_fifo([8, 12], [3, 2], time_limit_s=10)
    assert sol.zero_interference is False and sol.status is SolveStatus.OPTIMAL and sol.max_overlap == 1
    # three tasks whose pairs all fit but not together: 3 on a period of 6 with C = 2 each
    sol = solve_fifo([6, 6, 6, 6], [2, 2, 2, 1], time_limit_s=10)
    assert sol.zero_interference is False and sol.max_overlap >= 1


@pytest.mark.parametrize("limit", [0, -1.0, float("nan"), float("inf"), True])
def test_bad_time_limits(limit):
    with pytest.raises(SolverInputError, match="time limit must be a positive number"):
        solve_executive([1, 2], [1, 1], time_limit_s=limit)
    with pytest.raises(SolverInputError, match="time limit must be a positive number"):
        solve_fifo([4, 4], [1, 1], time_limit_s=limit)


EXEC = {"tick_hz": 1000, "tasks": [{"name": "a", "divider": 4, "budget_us": 500},
                                   {"name": "b", "divider": 4, "budget_us": 500},
                                   {"name": "c", "divider": 2, "budget_us": 400}]}


def test_optimal_schedule_reports_status_and_bound():
    s = schedule_from_config({**EXEC, "phase_method": "optimal"})
    assert s.method == "optimal" and s.optimality == "optimal" and s.lower_bound_us == s.max_tick_load_us == 500
    assert not s.warning


def test_optimal_falls_back_to_gcdplus_with_a_warning():
    # dividers 97, 101 and 103: a hyperperiod of ~10^6 ticks, beyond the exact model
    config = {"tick_hz": 1000, "phase_method": "optimal", "tasks": [
        {"name": n, "divider": d, "budget_us": 100} for n, d in (("a", 97), ("b", 101), ("c", 103))]}
    s = schedule_from_config(config)
    assert s.method == "gcdplus" and s.optimality == "" and "phase_method optimal: hyperperiod" in s.warning


@pytest.mark.parametrize("value", [0, -2, "x", True])
def test_bad_optimal_time_limit_in_the_config(value):
    from c4d_sched.tickschedule import ScheduleConfigError

    with pytest.raises(ScheduleConfigError, match="optimal_time_limit_s must be a positive number"):
        schedule_from_config({**EXEC, "phase_method": "optimal", "optimal_time_limit_s": value})
