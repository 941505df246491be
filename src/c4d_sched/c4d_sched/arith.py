"""Integer arithmetic used by the schedulers: gcd/lcm of sets, cached prime factorisation.

Why separate: GCD+ factorises every subperiod and the generator every period; caching the
trial division keeps repeated experiments fast without a dependency on a number-theory library.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from functools import lru_cache, reduce


def gcd_all(values: Iterable[int]) -> int:
    """Greatest common divisor of all values (Ω when given the periods)."""
    return reduce(math.gcd, values)


def lcm_all(values: Iterable[int]) -> int:
    """Least common multiple of all values (the hyperperiod H when given the periods)."""
    return reduce(math.lcm, values)


@lru_cache(maxsize=65536)
def prime_factors(n: int) -> tuple[int, ...]:
    """Distinct prime factors of n ≥ 2 in increasing order (trial division, cached)."""
    if n < 2:
        return ()
    factors = []
    d = 2
    while d * d <= n:
        if n % d == 0:
            factors.append(d)
            while n % d == 0:
                n //= d
        d += 1 if d == 2 else 2
    if n > 1:
        factors.append(n)
    return tuple(factors)
