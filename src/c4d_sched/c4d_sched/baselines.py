"""Baseline offset-assignment heuristics compared with GCD+ in the thesis (§3.3.1).

- zero: every offset 0 (synchronous release, the critical instant).
- paparazzi [Hat+22]: O_i = ((i−1) mod 10)·T_i/10 in the caller's task order (the phase rule
  of Paparazzi's generated telemetry); T_i/10 is floored to stay an integer.
- goossens [Goo03]: task pairs by decreasing gcd(T_i, T_j); for each pair with one or no
  offset set, the unset one gets O_set + gcd/2 (a random O in [0, T) first when neither is
  set; seeded RNG). goossens_modified: O_new = O_set + (gcd + C_set − C_new)/2, which centres
  the gap between the two executions. Divisions are floored; offsets are taken mod T.
- can_ghn08 [GHN08]: tasks by increasing period; each is released in the middle of the
  largest gap between releases already placed in [0, T_max) (circular), the first at 0.
All functions take a TaskSet (and an RNG for the random ones) and return an Assignment.
"""

from __future__ import annotations

import math
import random
from bisect import insort

from .model import Assignment, TaskSet


def zero_offsets(taskset: TaskSet, rng: random.Random | None = None) -> Assignment:
    return Assignment("zero", tuple(0 for _ in taskset.tasks))


def paparazzi(taskset: TaskSet, rng: random.Random | None = None) -> Assignment:
    offsets = tuple((i % 10) * t.period // 10 for i, t in enumerate(taskset.tasks))
    return Assignment("paparazzi", offsets)


def _goossens(taskset: TaskSet, rng: random.Random, modified: bool) -> tuple[int, ...]:
    T, C = taskset.periods, taskset.wcets
    n = len(T)
    pairs = sorted(
        ((math.gcd(T[i], T[j]), i, j) for i in range(n) for j in range(i + 1, n)),
        key=lambda item: (-item[0], item[1], item[2]),
    )
    offsets: list[int | None] = [None] * n
    for g, i, j in pairs:
        if offsets[i] is not None and offsets[j] is not None:
            continue
        if offsets[i] is None and offsets[j] is None:
            offsets[i] = rng.randrange(T[i])
        known, new = (i, j) if offsets[i] is not None else (j, i)
        shift = (g + C[known] - C[new]) // 2 if modified else g // 2
        anchor = offsets[known]
        assert anchor is not None  # one of the pair was placed above
        offsets[new] = (anchor + shift) % T[new]
    return tuple(o if o is not None else rng.randrange(T[k]) for k, o in enumerate(offsets))


def goossens(taskset: TaskSet, rng: random.Random | None = None) -> Assignment:
    return Assignment("goossens", _goossens(taskset, rng or random.Random(0), modified=False))


def goossens_modified(taskset: TaskSet, rng: random.Random | None = None) -> Assignment:
    return Assignment("goossens_modified", _goossens(taskset, rng or random.Random(0), modified=True))


def can_ghn08(taskset: TaskSet, rng: random.Random | None = None) -> Assignment:
    T = taskset.periods
    horizon = max(T)
    releases: list[int] = []  # sorted release instants in [0, T_max) of tasks placed so far
    offsets = [0] * len(T)
    for i in sorted(range(len(T)), key=lambda k: (T[k], k)):
        if releases:
            best_gap, best_start = -1, 0
            for a, b in zip(releases, releases[1:] + [releases[0] + horizon], strict=True):
                if b - a > best_gap:
                    best_gap, best_start = b - a, a
            offset = (best_start + best_gap // 2) % horizon % T[i]
        else:
            offset = 0
        offsets[i] = offset
        for release in range(offset, horizon, T[i]):
            insort(releases, release)
    return Assignment("can_ghn08", tuple(offsets))
