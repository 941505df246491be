"""Paparazzi telemetry case study (thesis §3.3.2, Table 3.3) reproduced."""

from pathlib import Path

from c4d_sched import assign, evaluate, run_order
from c4d_sched.taskio import load_taskset

CASE = Path(__file__).resolve().parents[1] / "config" / "paparazzi_telemetry.yaml"


def test_case_units():
    ts = load_taskset(CASE)
    assert ts.periods[0] == 2 * 57600 and ts.wcets[0] == (17 + 8) * 10
    assert ts.periods[-1] == 1152 and min(ts.periods) == 1152


def test_gcdplus_reproduces_the_case_study():
    ts = load_taskset(CASE)
    a = assign(ts, "gcdplus")
    e = evaluate(ts, a.offsets)
    assert e.schedulable
    assert all(t.delay_over_period < 0.10 for t in e.tasks)  # every delay < 10 % of the period
    assert all(t.delay_over_max_other_wcet <= 0.20 for t in e.tasks)  # <= 20 % of the longest other
    assert a.detail.order == "increasing_period_decreasing_wcet"


def test_literal_algorithm_order_does_not_reproduce_it():
    ts = load_taskset(CASE)
    e = evaluate(ts, run_order(ts, "decreasing_wcet").offsets)
    assert max(t.delay_over_period for t in e.tasks) >= 0.10


def test_paparazzi_heuristic_misses_a_deadline():
    ts = load_taskset(CASE)
    assert not evaluate(ts, assign(ts, "paparazzi").offsets).schedulable
