"""Baseline heuristics: the formulas of the thesis and their documented properties."""

import random

from c4d_sched import TaskSet, assign
from c4d_sched.baselines import can_ghn08, goossens, goossens_modified, paparazzi


def test_paparazzi_phase_rule():
    ts = TaskSet.from_pairs([(100, 1)] * 12)
    assert paparazzi(ts).offsets == (0, 10, 20, 30, 40, 50, 60, 70, 80, 90, 0, 10)


def test_modified_goossens_separation_is_gcd_plus_c_difference_over_two():
    ts = TaskSet.from_pairs([(8, 3), (12, 1)])  # gcd 4, C 3/1
    o = goossens_modified(ts, random.Random(1)).offsets
    assert (o[1] - o[0]) % 4 == 3  # (4 + 3 − 1) / 2
    o = goossens(ts, random.Random(1)).offsets
    assert (o[1] - o[0]) % 4 == 2  # 4 / 2


def test_goossens_is_seeded():
    ts = TaskSet.from_pairs([(10, 1), (15, 2), (25, 1), (30, 3)])
    assert assign(ts, "goossens", seed=3).offsets == assign(ts, "goossens", seed=3).offsets
    assert {assign(ts, "goossens", seed=s).offsets for s in range(10)} != {assign(ts, "goossens", seed=0).offsets}


def test_can_heuristic_puts_each_release_in_the_largest_gap():
    ts = TaskSet.from_pairs([(8, 1), (16, 1), (16, 1)])
    # t1 at 0 (releases 0, 8); t2 in the middle of the gap [0, 8) -> 4; t3 between 4 and 8 -> 6? No:
    # gaps after t2 (releases 0,4,8,12 minus t2 once: 0,4,8) are [0,4),[4,8),[8,16) -> 12.
    assert can_ghn08(ts).offsets == (0, 4, 12)


def test_every_method_returns_offsets_within_period():
    ts = TaskSet.from_pairs([(20, 2), (30, 3), (60, 5), (12, 1)])
    for method in ("gcdplus", "paparazzi", "goossens", "goossens_modified", "can_ghn08", "zero"):
        a = assign(ts, method)
        assert a.method == method
        assert all(0 <= o < t for o, t in zip(a.offsets, ts.periods, strict=True))
