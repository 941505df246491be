"""Schedulability-versus-utilisation experiment of the thesis (Figs 3.10/3.11), all methods.

For each task count n and total utilisation U: generate `sets` filtered random task sets
(generator.py), assign offsets with every method, evaluate each assignment exactly
(fifo.py) and count the sets with no deadline miss. Also records the per-task delay metrics
(η/T quartiles) and the mean time each method took to assign offsets. Points run in parallel
worker processes; results are deterministic for a given seed whatever the worker count.
"""

from __future__ import annotations

import csv
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from .fifo import evaluate
from .generator import generate_tasksets, paparazzi_period_model
from .methods import METHODS, assign

DEFAULT_UTILISATIONS = (0.5, 0.55, 0.6, 0.65, 0.7, 0.75, 0.8, 0.85, 0.9, 0.95)
BASELINES = ("paparazzi", "goossens", "goossens_modified", "can_ghn08", "zero")


@dataclass(frozen=True)
class Row:
    n: int
    utilisation: float
    method: str
    sets: int
    schedulable: int
    zero_interference: int
    delay_over_period_median: float
    delay_over_period_p75: float
    delay_over_period_max: float
    assign_time_us: float


def run_point(n: int, utilisation: float, sets: int, seed: int, methods: Sequence[str], min_share: float) -> list[Row]:
    """One (n, U) point: all methods on the same generated sets."""
    model = paparazzi_period_model(min_share)
    point_seed = seed * 1_000_003 + n * 1009 + round(utilisation * 1000)
    tasksets = generate_tasksets(n, utilisation, sets, seed=point_seed, model=model)
    rows = []
    for method in methods:
        schedulable = zero = 0
        ratios: list[float] = []
        spent = 0.0
        for k, ts in enumerate(tasksets):
            start = time.perf_counter()
            assignment = assign(ts, method, seed=point_seed + k)
            spent += time.perf_counter() - start
            result = evaluate(ts, assignment.offsets)
            schedulable += result.schedulable
            zero += result.zero_interference
            ratios.extend(t.delay_over_period for t in result.tasks)
        r = np.asarray(ratios)
        rows.append(
            Row(n, utilisation, method, sets, schedulable, zero, float(np.median(r)),
                float(np.percentile(r, 75)), float(r.max()), spent / sets * 1e6)
        )
    return rows


def run_experiment(
    sizes: Sequence[int] = (8, 16),
    utilisations_: Sequence[float] = DEFAULT_UTILISATIONS,
    sets: int = 1000,
    seed: int = 0,
    methods: Sequence[str] = tuple(METHODS),
    min_share: float = 0.10,
    workers: int = 2,
    progress: Callable[[int, int], None] | None = None,
) -> list[Row]:
    points = [(n, u) for n in sizes for u in utilisations_]
    rows: list[Row] = []
    with ProcessPoolExecutor(max_workers=max(1, workers)) as pool:
        futures = [pool.submit(run_point, n, u, sets, seed, tuple(methods), min_share) for n, u in points]
        for done, future in enumerate(futures, start=1):
            rows.extend(future.result())
            if progress:
                progress(done, len(points))
    return rows


def ratios_to_best_baseline(rows: Sequence[Row]) -> list[tuple[int, float, int, str, int, float]]:
    """(n, U, GCD+ schedulable, best baseline, its schedulable, ratio) per point."""
    out = []
    points = sorted({(r.n, r.utilisation) for r in rows})
    for n, u in points:
        at = {r.method: r for r in rows if r.n == n and r.utilisation == u}
        if "gcdplus" not in at:
            continue
        baselines = [at[m] for m in BASELINES if m in at]
        if not baselines:
            continue
        best = max(baselines, key=lambda r: r.schedulable)
        ratio = at["gcdplus"].schedulable / best.schedulable if best.schedulable else float("inf")
        out.append((n, u, at["gcdplus"].schedulable, best.method, best.schedulable, ratio))
    return out


def write_csv(rows: Sequence[Row], path: Path) -> None:
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(asdict(rows[0])))
        writer.writeheader()
        for row in rows:
            writer.writerow(asdict(row))


def plot(rows: Sequence[Row], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sizes = sorted({r.n for r in rows})
    fig, axes = plt.subplots(1, len(sizes), figsize=(6 * len(sizes), 4.5), squeeze=False)
    for ax, n in zip(axes[0], sizes, strict=True):
        for method in dict.fromkeys(r.method for r in rows):
            points = sorted((r.utilisation, r.schedulable / r.sets) for r in rows if r.n == n and r.method == method)
            ax.plot([100 * u for u, _ in points], [100 * s for _, s in points], marker="o",
                    linewidth=2.5 if method == "gcdplus" else 1.2, label=method)
        ax.set_title(f"{n} tasks, {rows[0].sets} filtered sets per point")
        ax.set_xlabel("total utilisation U (%)")
        ax.set_ylabel("schedulable sets under FIFO (%)")
        ax.grid(alpha=0.3)
        ax.legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
