"""SPC multi-rate precedence (D3.3 §5.2.3.2): job dependencies, phase constraints, the schedule keeps them."""

import itertools

import pytest

from c4d_sched.precedence import Edge, PhaseSystem, PrecedenceError, build_constraints, dependencies, min_phase_difference
from c4d_sched.tickschedule import ScheduleConfigError, TaskSpec, build_schedule, schedule_from_config


def test_d33_example_dependencies():
    # F1 every 3 ms adds 3 tokens, F2 every 5 ms needs 5: over the 15 ms LCM, 5 F1 jobs and 3 F2 jobs
    assert dependencies(Edge("F1", "F2", 3, 5, 0), 5, 3) == [2, 4, 5]
    assert dependencies(Edge("F1", "F2", 3, 5, 2), 5, 3) == [1, 3, 5]


def test_tokens_that_never_balance_are_refused():
    with pytest.raises(PrecedenceError, match="tokens never balance"):
        dependencies(Edge("F1", "F2", 3, 4, 0), 5, 3)
    with pytest.raises(PrecedenceError, match="w_c must be a positive integer"):
        dependencies(Edge("F1", "F2", 3, 0, 0), 5, 3)


def job_ticks(divider, phase, count):
    return [phase + (i - 1) * divider for i in range(1, count + 1)]


@pytest.mark.parametrize("m0", [-2, 0, 2, 5])
def test_constraint_is_exactly_the_job_level_condition(m0):
    """φ_c − φ_p ≥ L holds iff every consumer job's tick is at or after its producer job's tick
    (checked job by job over three hyperperiods for every phase pair)."""
    edge, d_p, d_c = Edge("p", "c", 3, 5, m0), 3, 5
    low = min_phase_difference(edge, d_p, d_c)
    deps = dependencies(edge, 5, 3)
    for phi_p, phi_c in itertools.product(range(d_p), range(d_c)):
        ok = all(phi_p + (deps[(j - 1) % 3] + 5 * ((j - 1) // 3) - 1) * d_p <= phi_c + (j - 1) * d_c
                 for j in range(1, 10))
        assert ok == (phi_c - phi_p >= low), (phi_p, phi_c)


def test_infeasible_cycle_is_named():
    edges = [Edge("a", "b", 1, 1, 0), Edge("b", "a", 1, 1, 0)]
    cons = build_constraints(edges, {"a": 0, "b": 1}, [4, 4], {("a", "b"): True, ("b", "a"): False})
    with pytest.raises(PrecedenceError, match="infeasible precedence cycle .*a -> b -> a|b -> a -> b"):
        PhaseSystem(["a", "b"], [4, 4], cons).check()
    # one initial token on the back edge makes the cycle live
    edges[1] = Edge("b", "a", 1, 1, 1)
    cons = build_constraints(edges, {"a": 0, "b": 1}, [4, 4], {("a", "b"): True, ("b", "a"): False})
    PhaseSystem(["a", "b"], [4, 4], cons).check()


CONFIG = {
    "tick_hz": 1000,
    "tasks": [
        {"name": "f1", "group": "control", "divider": 3, "budget_us": 300},
        {"name": "f2", "group": "control", "divider": 5, "budget_us": 300},
        {"name": "other", "group": "estimation", "divider": 5, "budget_us": 300},
        {"name": "slow", "group": "telemetry", "divider": 15, "budget_us": 300},
    ],
    "precedence": [{"producer": "f1", "consumer": "f2", "w_p": 3, "w_c": 5, "m0": 0}],
}


@pytest.mark.parametrize("method", ["gcdplus", "optimal", "paparazzi", "zero"])
def test_every_method_meets_the_edge_job_by_job(method):
    schedule = schedule_from_config({**CONFIG, "phase_method": method})
    by = {t.name: t for t in schedule.tasks}
    f1, f2 = by["f1"], by["f2"]
    assert f1.order < f2.order  # same group: the producer runs first in a shared tick
    ticks_1, ticks_2 = job_ticks(3, f1.phase, 10), job_ticks(5, f2.phase, 6)
    for j, i in enumerate(dependencies(Edge("f1", "f2", 3, 5, 0), 5, 3) * 2, start=1):
        i += 5 * ((j - 1) // 3)
        assert ticks_1[i - 1] <= ticks_2[j - 1], (method, f1.phase, f2.phase)


def test_edge_against_group_order_waits_a_tick():
    config = {**CONFIG, "precedence": [{"producer": "f2", "consumer": "other", "m0": 0}]}  # control -> estimation
    schedule = schedule_from_config({**config, "phase_method": "optimal"})
    by = {t.name: t for t in schedule.tasks}
    assert by["other"].order < by["f2"].order and by["other"].phase >= by["f2"].phase + 1


BAD = [
    ([{"producer": "f1", "consumer": "f2", "w_p": 3, "w_c": 4}], "tokens never balance"),
    ([{"producer": "f1", "consumer": "nope"}], "unknown task 'nope'"),
    ([{"producer": "f1", "consumer": "f2", "m0": "x"}], "M0 must be an integer"),
    ([{"producer": "f1", "consumer": "f1"}], "cannot precede itself"),
    ([{"producer": "f2", "consumer": "other"}, {"producer": "other", "consumer": "f2"}], "infeasible precedence cycle"),
    ([{"producer": "f1", "consumer": "f2", "m0": -9}], "precedence pushes task 'f2'"),
    ("f1->f2", "must be a list"),
]


@pytest.mark.parametrize(("edges", "message"), BAD)
def test_bad_precedence_is_one_line(edges, message):
    with pytest.raises(ScheduleConfigError, match=message) as err:
        schedule_from_config({**CONFIG, "precedence": edges})
    assert "\n" not in str(err.value)


def test_gcdplus_repair_keeps_the_edge_and_the_load_low():
    """Phase-pinning edges: GCD+'s phases are repaired, then spread again inside the feasible intervals."""
    specs = [TaskSpec("a", "control", 2, 500), TaskSpec("b", "control", 1, 200), TaskSpec("c", "telemetry", 4, 900),
             TaskSpec("d", "default", 4, 900)]
    edges = [Edge("a", "b", 2, 1, 0)]  # b at every tick waits for a's job of its synchronous window: φ_a = 0
    s = build_schedule(1000, "gcdplus", specs, (), edges)
    by = {t.name: t for t in s.tasks}
    assert by["a"].phase == 0 and by["c"].phase != by["d"].phase and s.max_tick_load_us == 1100
