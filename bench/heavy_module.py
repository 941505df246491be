#!/usr/bin/env python3
"""'Heavy module' scenario (IMAV 2022 paper, conclusion): zero vs paparazzi vs GCD+ phases.

The GNC core's task set plus a computationally heavy user module (1.2 ms every 10 Hz) and
telemetry / logging tasks at several rates, all as real CPU work (busy loops of their budget)
on the real clock at 500 Hz (2 ms ticks). Each phase method gets the same task set; printed
side by side: the schedule's worst per-tick budget sum, and measured overruns, skipped ticks,
worst tick busy time and p99 release jitter. With zero phases every slow task is released
in the same tick and that tick cannot fit in 2 ms; GCD+ spreads them.

Usage: . ./env.sh && python bench/heavy_module.py [--seconds 20]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from gnc_workload import busy, core_executive_config, flying_core, refresh

from c4d_sched.executive import CyclicExecutive, MonotonicClock
from c4d_sched.tickschedule import schedule_from_config

USER_TASKS = [  # name, group, rate Hz, execution time µs (= budget)
    ("heavy_module", "default", 10, 1200),
    ("telemetry_fast", "telemetry", 50, 250),
    ("telemetry_slow", "telemetry", 20, 400),
    ("logger", "default", 10, 500),
    ("parameters", "default", 5, 150),
]


def run(method: str, seconds: float) -> dict:
    config = core_executive_config()
    config = {**config, "phase_method": method,
              "tasks": config["tasks"] + [{"name": n, "group": g, "rate_hz": r, "budget_us": c} for n, g, r, c in USER_TASKS]}
    schedule = schedule_from_config(config)
    tick_s = schedule.tick_us / 1e6
    core = flying_core(tick_s)
    gnc = core.task_functions()
    functions = {}
    for t in schedule.tasks:
        if t.name in gnc:
            functions[t.name] = lambda k, fn=gnc[t.name], dt=t.divider * tick_s: fn(dt)
        else:
            load = next((c for n, _, _, c in USER_TASKS if n == t.name), 0)
            functions[t.name] = lambda k, load=load: busy(load)
    busiest = [0]
    ex = CyclicExecutive(schedule, functions, MonotonicClock(), input_phase=lambda k: refresh(core, time.monotonic()),
                         latch=lambda k: core.latch(), report_period_s=3600, manage_gc=True)
    jitters = []
    original = ex.profiler.tick_done

    def record(jitter_ns, busy_ns, overrun, skipped):
        jitters.append(jitter_ns)
        busiest[0] = max(busiest[0], busy_ns)
        original(jitter_ns, busy_ns, overrun, skipped)

    ex.profiler.tick_done = record
    ex.run(max_ticks=int(seconds / tick_s))
    ex.release_gc()
    jitters.sort()
    return {"method": method, "budget_max": schedule.max_tick_load_us, "overruns": ex.profiler.overruns_total,
            "skipped": ex.profiler.skipped_total, "busiest": busiest[0] / 1000, "ticks": len(jitters),
            "p99": jitters[int(0.99 * (len(jitters) - 1))] / 1000, "certificate": schedule.certificate}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    args = parser.parse_args()
    print(f"500 Hz tick (2000 µs), GNC tasks + {len(USER_TASKS)} user tasks "
          f"({', '.join(f'{n} {c} µs @ {r} Hz' for n, _, r, c in USER_TASKS)}), {args.seconds:.0f} s per method")
    print(f"{'phases':<11}{'max tick budget µs':>19}{'ticks':>8}{'overruns':>10}{'skipped':>9}{'busiest tick µs':>17}"
          f"{'p99 jitter µs':>15}")
    for method in ("zero", "paparazzi", "gcdplus", "optimal"):
        r = run(method, args.seconds)
        print(f"{r['method']:<11}{r['budget_max']:>19}{r['ticks']:>8}{r['overruns']:>10}{r['skipped']:>9}"
              f"{r['busiest']:>17.0f}{r['p99']:>15.1f}", flush=True)


if __name__ == "__main__":
    main()
