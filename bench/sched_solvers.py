#!/usr/bin/env python3
"""Phase/offset solvers side by side: assign time and result of paparazzi, GCD+, the exact executive
model and the exact FIFO model (issue 22), in one run.

Cases: the core's task set (config/core.yaml, precedence included), the heavy-module set
(bench/heavy_module.py: core + 5 user tasks) and random thesis sets (n = 8, 16, 32 at U = 70 %,
tick = Ω). Per method: median and p95 wall time per set, and the worst per-tick budget sum
(executive) or the max pairwise overlap / zero-interference count (FIFO). The exact models run
with one CP-SAT worker and --time-limit per set, warm-started with GCD+. The platform-stall probe
reports what the machine itself imposed meanwhile. (GCD# has its own bench: bench/gcdsharp.py.)

Usage: . ./env.sh && flock /tmp/c4d_graph.lock python bench/sched_solvers.py [--sets 10] [--time-limit 2] [--repeats 20]
"""

from __future__ import annotations

import argparse
import platform
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "test" / "support"))
sys.path.insert(0, str(ROOT / "bench"))
from gnc_workload import core_executive_config  # noqa: E402
from heavy_module import USER_TASKS  # noqa: E402
from stall_probe import StallProbe, worst_line  # noqa: E402

from c4d_sched.arith import gcd_all  # noqa: E402
from c4d_sched.baselines import paparazzi  # noqa: E402
from c4d_sched.gcdplus import gcd_plus  # noqa: E402
from c4d_sched.generator import generate_tasksets  # noqa: E402
from c4d_sched.optimal import max_pair_overlap, solve_executive, solve_fifo, tick_loads  # noqa: E402
from c4d_sched.tickschedule import _best_gcdplus_for_ticks, schedule_from_config  # noqa: E402


def p95(values: list[float]) -> float:
    values = sorted(values)
    return values[round(0.95 * (len(values) - 1))]


def timed(function: Callable[[], object], repeats: int) -> tuple[list[float], object]:
    out, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = function()
        out.append((time.perf_counter() - start) * 1e3)
    return out, result


def executive_cases(limit: float, repeats: int) -> None:
    core = core_executive_config()
    heavy = {**core, "tasks": core["tasks"] + [{"name": n, "group": g, "rate_hz": r, "budget_us": c}
                                               for n, g, r, c in USER_TASKS]}
    print(f"executive schedules (tick 2000 µs, precedence of core.yaml kept; optimal: limit {limit:g} s, 1 worker)")
    print(f"{'case':<14}{'method':<11}{'median ms':>10}{'p95 ms':>9}{'worst tick µs':>14}  note")
    for name, config in (("core", core), ("heavy module", heavy)):
        for method in ("paparazzi", "gcdplus", "optimal"):
            cfg = {**config, "phase_method": method, "optimal_time_limit_s": limit}
            ms, s = timed(lambda cfg=cfg: schedule_from_config(cfg), repeats)
            note = f"{s.optimality}, bound {s.lower_bound_us} µs" if s.optimality else ""
            print(f"{name:<14}{method:<11}{statistics.median(ms):>10.2f}{p95(ms):>9.2f}{s.max_tick_load_us:>14}  {note}")


def random_cases(sets: int, limit: float) -> None:
    print(f"\nrandom thesis sets at U = 70 %, {sets} per size (tick = Ω for the executive objective; "
          f"exact models: limit {limit:g} s per set, 1 worker, GCD+ warm start)")
    print(f"{'n':>3} {'method':<18}{'median ms':>10}{'p95 ms':>9}  result")
    for n in (8, 16, 32):
        tasksets = generate_tasksets(n, 0.7, sets, seed=1)
        rows: dict[str, tuple[list[float], list[str]]] = {}

        def add(method: str, ms: float, result: str, rows: dict[str, tuple[list[float], list[str]]] = rows) -> None:
            rows.setdefault(method, ([], []))[0].append(ms)
            rows[method][1].append(result)

        proven = zero = zero_impossible = 0
        loads: dict[str, list[int]] = {"paparazzi": [], "gcdplus": [], "optimal executive": []}
        for ts in tasksets:
            omega = gcd_all(ts.periods)
            d = [t // omega for t in ts.periods]
            for method, run in (("paparazzi", lambda ts=ts: paparazzi(ts).offsets),
                                ("gcdplus", lambda ts=ts, omega=omega: _best_gcdplus_for_ticks(ts, omega).offsets)):
                start = time.perf_counter()
                offsets = run()
                add(method, (time.perf_counter() - start) * 1e3, "")
                loads[method].append(max(tick_loads(d, ts.wcets, [(o // omega) % x for o, x in zip(offsets, d, strict=True)])))
            hint = [(o // omega) % x for o, x in zip(_best_gcdplus_for_ticks(ts, omega).offsets, d, strict=True)]
            start = time.perf_counter()
            sol = solve_executive(d, ts.wcets, time_limit_s=limit, hint=hint)
            add("optimal executive", (time.perf_counter() - start) * 1e3, "")
            assert sol.objective is not None
            loads["optimal executive"].append(sol.objective)
            proven += sol.status.value == "optimal"
            fifo_gcd = gcd_plus(ts).offsets
            start = time.perf_counter()
            ff = solve_fifo(ts.periods, ts.wcets, time_limit_s=limit, hint=fifo_gcd)
            add("optimal FIFO", (time.perf_counter() - start) * 1e3, "")
            zero += ff.zero_interference is True
            zero_impossible += ff.zero_interference is False
            start = time.perf_counter()
            gcd_plus(ts)
            add("gcdplus (FIFO)", (time.perf_counter() - start) * 1e3, "")
            add("gcdplus ZI", 0.0, str(max_pair_overlap(ts.periods, ts.wcets, fifo_gcd) == 0))
        for method in ("paparazzi", "gcdplus", "optimal executive", "gcdplus (FIFO)", "optimal FIFO"):
            ms = rows[method][0]
            if method in loads:
                result = f"worst tick load median {statistics.median(loads[method]):.0f}"
                if method == "optimal executive":
                    result += f", {proven}/{sets} proven optimal"
            elif method == "optimal FIFO":
                result = f"zero interference {zero}/{sets}, proven impossible {zero_impossible}/{sets}"
            else:
                result = f"zero interference {rows['gcdplus ZI'][1].count('True')}/{sets}"
            print(f"{n:>3} {method:<18}{statistics.median(ms):>10.2f}{p95(ms):>9.2f}  {result}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", type=int, default=10)
    parser.add_argument("--time-limit", type=float, default=2.0)
    parser.add_argument("--repeats", type=int, default=20)
    args = parser.parse_args()
    if args.sets < 1 or args.time_limit <= 0 or args.repeats < 1:
        print("sched_solvers: error: need --sets >= 1, --time-limit > 0 and --repeats >= 1", file=sys.stderr)
        return 2
    print(f"python {platform.python_version()} on {platform.machine()}")
    probe = StallProbe()
    try:
        executive_cases(args.time_limit, args.repeats)
        random_cases(args.sets, args.time_limit)
    finally:
        stalls = probe.stop()
    print("\n" + worst_line(stalls))
    return 0


if __name__ == "__main__":
    sys.exit(main())
