"""Registry of offset-assignment methods by name: one call signature for CLI, experiments and
the cyclic executive (`assign(taskset, method, seed)` → Assignment)."""

from __future__ import annotations

import random
from collections.abc import Callable

from .baselines import can_ghn08, goossens, goossens_modified, paparazzi, zero_offsets
from .gcdplus import gcd_plus
from .model import Assignment, TaskSet

METHODS: dict[str, Callable[[TaskSet, random.Random], Assignment]] = {
    "gcdplus": lambda ts, rng: gcd_plus(ts),
    "paparazzi": paparazzi,
    "goossens": goossens,
    "goossens_modified": goossens_modified,
    "can_ghn08": can_ghn08,
    "zero": zero_offsets,
}


def assign(taskset: TaskSet, method: str = "gcdplus", seed: int = 0) -> Assignment:
    """Offsets for `taskset` by `method` (one of METHODS); `seed` drives the random ones."""
    try:
        function = METHODS[method]
    except KeyError:
        raise ValueError(f"unknown method '{method}' (known: {', '.join(METHODS)})") from None
    return function(taskset, random.Random(seed))
