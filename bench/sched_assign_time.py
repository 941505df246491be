#!/usr/bin/env python3
"""Offset-assignment time of every method, side by side, and exact-evaluator throughput.

Thesis Table 3.2 protocol: 1000 filtered random sets at U = 70 %, n = 8 and n = 16; mean time
per set for each method (task-set construction excluded). `gcdplus` is the full method
(every order variant until one holds the certificate, exact evaluation of the candidates when
none does); `gcdplus[<order>]` is one run of Algorithm 1 with that processing order — the
figure comparable to the thesis' 54.8 µs / 151 µs (Python 3.9, i7-4710MQ).
Then the evaluator: evaluations per second and jobs per second over the same sets.

Usage: . ./env.sh && python bench/sched_assign_time.py [--sets 1000] [--seed 0]
"""

from __future__ import annotations

import argparse
import platform
import time

from c4d_sched import METHODS, assign, evaluate
from c4d_sched.gcdplus import ORDER_VARIANTS, run_order
from c4d_sched.generator import generate_tasksets


def mean_us(function, tasksets, repeat: int = 3) -> float:
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        for k, ts in enumerate(tasksets):
            function(ts, k)
        best = min(best, (time.perf_counter() - start) / len(tasksets) * 1e6)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    print(f"python {platform.python_version()} on {platform.machine()}, {args.sets} filtered sets at U = 70 %,"
          " best of 3 passes")
    sizes = (8, 16)
    sets = {n: generate_tasksets(n, 0.7, args.sets, seed=args.seed) for n in sizes}
    rows = [(f"gcdplus[{o}]", lambda ts, k, o=o: run_order(ts, o)) for o in ORDER_VARIANTS]
    rows += [(m, lambda ts, k, m=m: assign(ts, m, seed=k)) for m in METHODS]
    print(f"{'method':<48}" + "".join(f"{f'n = {n} (µs)':>16}" for n in sizes))
    for name, function in rows:
        print(f"{name:<48}" + "".join(f"{mean_us(function, sets[n]):>16.1f}" for n in sizes))
    print()
    for n in sizes:
        offsets = [assign(ts, "paparazzi").offsets for ts in sets[n]]
        start = time.perf_counter()
        jobs = sum(evaluate(ts, o).jobs for ts, o in zip(sets[n], offsets, strict=True))
        spent = time.perf_counter() - start
        print(f"exact FIFO evaluator, n = {n}: {len(offsets) / spent:,.0f} evaluations/s, "
              f"{jobs / spent / 1e6:.1f} M jobs/s, mean {jobs / len(offsets):,.0f} jobs per 2H + max O window")


if __name__ == "__main__":
    main()
