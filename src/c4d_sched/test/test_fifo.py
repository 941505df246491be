"""Exact FIFO evaluator against an independent job-by-job simulation and hand examples."""

import random

import pytest

from c4d_sched import TaskSet, evaluate, overlap
from c4d_sched.arith import lcm_all
from c4d_sched.fifo import EvaluationTooLarge, fifo_delays


def reference(periods, wcets, offsets):
    """Plain event loop: jobs by (release, task index), one server, no preemption."""
    hyper = lcm_all(periods)
    horizon = 2 * hyper + max(offsets)
    jobs = sorted((r, i) for i, (t, o) in enumerate(zip(periods, offsets, strict=True)) for r in range(o, horizon, t))
    free_at, eta, misses = 0, [0] * len(periods), [0] * len(periods)
    for release, i in jobs:
        start = max(free_at, release)
        free_at = start + wcets[i]
        eta[i] = max(eta[i], start - release)
        misses[i] += (start - release + wcets[i]) > periods[i]
    return eta, misses


def test_matches_reference_on_random_sets():
    rng = random.Random(5)
    for _ in range(300):
        n = rng.randint(1, 6)
        periods = [rng.choice([4, 6, 8, 10, 12, 15, 20, 24, 30]) for _ in range(n)]
        wcets = [rng.randint(1, max(1, t // 2)) for t in periods]
        offsets = [rng.randrange(t) for t in periods]
        eta, misses, *_ = fifo_delays(periods, wcets, offsets)
        assert (list(eta), list(misses)) == reference(periods, wcets, offsets)


def test_simultaneous_release_served_in_task_order():
    ts = TaskSet.from_pairs([(4, 2), (4, 1)])
    e = evaluate(ts, (0, 0))
    assert [t.max_delay for t in e.tasks] == [0, 2]
    e = evaluate(TaskSet.from_pairs([(4, 1), (4, 2)]), (0, 0))
    assert [t.max_delay for t in e.tasks] == [0, 1]


def test_metrics_and_deadline_misses():
    ts = TaskSet.from_pairs([(4, 3), (4, 2)])  # U = 1.25: the second task falls behind
    e = evaluate(ts, (0, 0))
    second = e.tasks[1]
    assert second.deadline_misses > 0 and not e.schedulable
    first = e.tasks[0]
    assert first.max_delay > 0
    assert first.delay_over_period == first.max_delay / 4
    assert first.delay_over_max_other_wcet == first.max_delay / 2
    assert first.response_over_wcet == (first.max_delay + 3) / 3
    assert e.horizon == 2 * 4 + 0 and e.jobs == 4


def test_figure_3_2_pair_never_overlaps():
    assert overlap(14, 2, 1, 21, 1, 4) == (0, 0)
    assert evaluate(TaskSet.from_pairs([(14, 2), (21, 1)]), (1, 4)).zero_interference
    assert overlap(14, 2, 1, 21, 1, 2) == (1, 0)  # Δ = 1 < C_i = 2


def test_large_hyperperiod_is_fast_and_guarded():
    ts = TaskSet.from_pairs([(1000, 10), (1001, 10), (999, 10)])  # H ≈ 10^9
    with pytest.raises(EvaluationTooLarge):
        evaluate(ts, (0, 0, 0), max_jobs=1_000_000)
    ts = TaskSet.from_pairs([(2000, 100), (3000, 200), (5000, 300), (7000, 100)])  # H = 210000
    assert evaluate(ts, (0, 100, 300, 600)).jobs > 0
