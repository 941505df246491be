"""Random task sets as in the thesis (§3.3.1.1): Dirichlet-Rescale utilisations, GM01 periods.

Utilisations: n values summing to U, uniformly distributed on the (capped) simplex — the
distribution Dirichlet-Rescale [GBD20] targets. With the thesis' bounds (0 ≤ u_i ≤ 1, U ≤ 1)
no bound can bind and DRS returns exactly a flat-Dirichlet sample scaled by U, which is what
`utilisations` draws (vectorised). With a binding per-task cap (u_max < U) it keeps the flat
Dirichlet samples that respect the cap (rejection), which is exactly uniform on the capped
simplex; the `drs` package itself is deprecated by its author for non-uniformity.

Periods (GM01, Goossens & Macq 2001): period = Π p^e_p with each exponent e_p drawn from a
per-prime distribution — a finite set of periods with a bounded hyperperiod. The distribution
is fitted to Paparazzi's telemetry periods (conf/telemetry/default_rotorcraft.xml, every
<message period> of every mode, 85 entries, in milliseconds): for each prime, the observed
frequency of each exponent. `fit_exponents` recomputes it from PAPARAZZI_ROTORCRAFT_PERIODS_MS.
Primes present in fewer than `min_share` (default 10 %) of the periods (7: 7 %, 17: 6 %,
11 and 31: 4 %, 13 and 41: 1 %) are left out of the default model, as GM01 intends, to keep
hyperperiods (and exact simulation) tractable: the full fit gives 16-task sets with a mean of
~10^5 jobs per 2H window and tails above 10^6, the default ~5·10^3. `min_share=0` keeps all.

Then C_i = round(u_i·T_i) (round half to even, like Python's round), and sets are filtered as
in the thesis: no C_i = 0, and Ω = gcd(T) ≥ max C_i. Everything is seeded (numpy Generator).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .arith import prime_factors
from .model import Task, TaskSet

# Every <message period="..."> of conf/telemetry/default_rotorcraft.xml (Paparazzi, all modes,
# commented-out lines excluded), in milliseconds.
PAPARAZZI_ROTORCRAFT_PERIODS_MS: tuple[int, ...] = (
    1100, 1200, 250, 2100, 5100, 1600, 1300, 1000, 250, 250, 4100, 3100, 3000, 2500, 5100,
    50, 500, 500, 500, 1000, 200,
    1200, 500, 2100, 50, 50, 50, 100,
    1200, 500, 2100, 75, 75, 100,
    1200, 500, 2100, 2200, 500, 5000, 80, 100,
    1200, 500, 2100, 20,
    1200, 500, 900, 100, 50,
    1200, 500, 900, 30, 30,
    1200, 500, 900, 50, 50, 50, 5100,
    900, 62, 62, 400, 800, 1200, 1600, 5100, 50, 30, 200,
    900, 20,
    1200, 900, 500,
    1100, 1200, 2100, 50, 100, 5100,
)


@dataclass(frozen=True)
class PeriodModel:
    """GM01 period distribution: for each prime, the probability of each exponent 0, 1, 2, …"""

    name: str
    exponents: tuple[tuple[int, tuple[float, ...]], ...]

    @property
    def max_hyperperiod(self) -> int:
        bound = 1
        for p, probs in self.exponents:
            bound *= p ** (len(probs) - 1)
        return bound

    def sample(self, rng: np.random.Generator, size: int | tuple[int, ...]) -> np.ndarray:
        periods = np.ones(size, dtype=np.int64)
        for p, probs in self.exponents:
            exps = rng.choice(len(probs), size=size, p=np.asarray(probs))
            periods *= np.power(p, exps, dtype=np.int64)
        return periods


def fit_exponents(periods: Sequence[int]) -> dict[int, dict[int, int]]:
    """Observed exponent counts per prime over `periods`: {p: {exponent: count}}."""
    counts: dict[int, Counter[int]] = {}
    factorisations = []
    for t in periods:
        f: Counter[int] = Counter()
        for p in prime_factors(t):
            x = t
            while x % p == 0:
                f[p] += 1
                x //= p
        factorisations.append(f)
        for p in f:
            counts.setdefault(p, Counter())
    for f in factorisations:
        for p in counts:
            counts[p][f.get(p, 0)] += 1
    return {p: dict(sorted(c.items())) for p, c in sorted(counts.items())}


def paparazzi_period_model(min_share: float = 0.10) -> PeriodModel:
    """The GM01 model fitted to Paparazzi's rotorcraft telemetry periods (ms), dropping primes
    that divide fewer than `min_share` of the periods."""
    fitted = fit_exponents(PAPARAZZI_ROTORCRAFT_PERIODS_MS)
    total = len(PAPARAZZI_ROTORCRAFT_PERIODS_MS)
    rows = []
    for p, counts in fitted.items():
        share = 1 - counts.get(0, 0) / total
        if share < min_share:
            continue
        top = max(counts)
        rows.append((p, tuple(counts.get(e, 0) / total for e in range(top + 1))))
    name = "paparazzi-ms" if min_share <= 0 else f"paparazzi-ms-primes>={min_share:.0%}"
    return PeriodModel(name, tuple(rows))


def utilisations(
    rng: np.random.Generator, n: int, total: float, size: int, u_max: float | None = None
) -> np.ndarray:
    """`size` vectors of n utilisations summing to `total`, uniform on the (capped) simplex."""
    if not 0 < total <= n * (u_max if u_max is not None else 1.0):
        raise ValueError(f"total utilisation {total} is not reachable by {n} tasks")
    if u_max is None or u_max >= total:
        return rng.dirichlet(np.ones(n), size=size) * total
    kept: list[np.ndarray] = []
    have, draws = 0, 0
    while have < size:
        if draws > 1000 * max(size, 1000):
            raise ValueError(f"cap u_max = {u_max} with U = {total} and n = {n} is too tight to sample")
        batch = rng.dirichlet(np.ones(n), size=max(size, 1000)) * total
        ok = batch[(batch <= u_max).all(axis=1)]
        kept.append(ok)
        have += len(ok)
        draws += len(batch)
    return np.concatenate(kept)[:size]


def generate_tasksets(
    n: int,
    total_utilisation: float,
    count: int,
    seed: int = 0,
    model: PeriodModel | None = None,
    filtered: bool = True,
    u_max: float | None = None,
    batch: int = 20000,
    max_draws: int = 50_000_000,
) -> list[TaskSet]:
    """`count` random task sets of n tasks at total utilisation U (see module docstring)."""
    model = model or paparazzi_period_model()
    rng = np.random.default_rng(seed)
    sets: list[TaskSet] = []
    draws = 0
    while len(sets) < count:
        if draws >= max_draws:
            raise RuntimeError(f"only {len(sets)} of {count} sets passed the filter after {draws} draws")
        periods = model.sample(rng, (batch, n))
        u = utilisations(rng, n, total_utilisation, batch, u_max)
        wcets = np.rint(u * periods).astype(np.int64)
        ok = (wcets.min(axis=1) > 0) & (wcets <= periods).all(axis=1)
        if filtered:
            ok &= np.gcd.reduce(periods, axis=1) >= wcets.max(axis=1)
        draws += batch
        for row in np.nonzero(ok)[0][: count - len(sets)]:
            pairs = zip(periods[row].tolist(), wcets[row].tolist(), strict=True)
            tasks = tuple(Task(f"t{i + 1}", t, c) for i, (t, c) in enumerate(pairs))
            sets.append(TaskSet(tasks, unit="ms"))
    return sets
