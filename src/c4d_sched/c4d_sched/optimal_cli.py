"""`c4d-sched` subcommands of the exact solvers (issue 22):

    c4d-sched optimal FILE [--model executive|fifo] [--tick N] [--time-limit S] [--json]
    c4d-sched schedule CONFIG [--method gcdplus|optimal|paparazzi|zero] [--time-limit S] [--json]
    c4d-sched gap-study [--sizes 8,16,32] [--utilisations 0.5,...] [--sets N] [--time-limit S] [--out CSV]

`optimal` solves one task set (taskio format) exactly and prints it beside GCD+; `schedule`
builds a cyclic executive's tick schedule from a core config (or a bare `executive:` mapping),
precedence edges included; `gap-study` is the optimality-gap study of docs/gcdplus.md. Bad
input (unbalanced tokens, precedence cycles, time limits <= 0, ...) is one line and exit 2 via
cli.main, which catches every ValueError these raise.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import sys
import time
from pathlib import Path
from typing import Any

import yaml

from .arith import gcd_all
from .gcdplus import gcd_plus
from .model import TaskSetError
from .optimal import check_time_limit, max_pair_overlap, solve_executive, solve_fifo, tick_loads
from .taskio import load_taskset
from .tickschedule import PHASE_METHODS, ScheduleConfigError, _best_gcdplus_for_ticks, schedule_from_config


def _time_limit(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"time limit must be a number of seconds, got '{text}'") from None
    try:
        return check_time_limit(value)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def cmd_optimal(args: argparse.Namespace) -> int:
    ts = load_taskset(args.file)
    out: dict[str, Any] = {"model": args.model, "unit": ts.unit, "time_limit_s": args.time_limit}
    if args.model == "executive":
        tick = args.tick or gcd_all(ts.periods)
        if tick <= 0 or any(t % tick for t in ts.periods):
            raise TaskSetError(f"--tick {tick} must divide every period")
        dividers = [t // tick for t in ts.periods]
        gcd_phases = [(o // tick) % d for o, d in zip(_best_gcdplus_for_ticks(ts, tick).offsets, dividers, strict=True)]
        sol = solve_executive(dividers, ts.wcets, time_limit_s=args.time_limit, hint=gcd_phases)
        out.update(tick=tick, status=sol.status.value, worst_tick_load=sol.objective, bound=sol.bound,
                   solver_s=round(sol.wall_s, 4), gcdplus_worst_tick_load=max(tick_loads(dividers, ts.wcets, gcd_phases)),
                   tasks=[{"name": t.name, "divider": d, "budget": t.wcet, "phase": p, "gcdplus_phase": g}
                          for t, d, p, g in zip(ts.tasks, dividers, sol.phases or [None] * len(dividers), gcd_phases,
                                                strict=True)])
    else:
        gcd = gcd_plus(ts).offsets
        fifo = solve_fifo(ts.periods, ts.wcets, time_limit_s=args.time_limit, hint=gcd)
        out.update(status=fifo.status.value, zero_interference=fifo.zero_interference, max_overlap=fifo.max_overlap,
                   bound=fifo.bound, solver_s=round(fifo.wall_s, 4),
                   gcdplus_max_overlap=max_pair_overlap(ts.periods, ts.wcets, gcd),
                   tasks=[{"name": t.name, "period": t.period, "wcet": t.wcet, "offset": o, "gcdplus_offset": g}
                          for t, o, g in zip(ts.tasks, fifo.offsets or [None] * len(ts.tasks), gcd, strict=True)])
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    if args.model == "executive":
        print(f"executive, tick {out['tick']} {ts.unit}: worst tick budget sum {out['worst_tick_load']} "
              f"({out['status']}, lower bound {out['bound']}, {out['solver_s']} s); GCD+ {out['gcdplus_worst_tick_load']}")
        for row in out["tasks"]:
            print(f"  {row['name']:<20} d={row['divider']:<6} C={row['budget']:<8} phase {row['phase']} "
                  f"(GCD+ {row['gcdplus_phase']})")
    else:
        zero = {True: "zero interference", False: "zero interference proven impossible", None: "zero interference undecided"}
        print(f"FIFO: {zero[out['zero_interference']]}; max pairwise overlap {out['max_overlap']} ({out['status']}, "
              f"lower bound {out['bound']}, {out['solver_s']} s); GCD+ overlap {out['gcdplus_max_overlap']}")
        for row in out["tasks"]:
            print(f"  {row['name']:<20} T={row['period']:<8} C={row['wcet']:<6} offset {row['offset']} "
                  f"(GCD+ {row['gcdplus_offset']})")
    return 0


def cmd_schedule(args: argparse.Namespace) -> int:
    path = Path(args.file)
    try:
        doc = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ScheduleConfigError(f"{path}: {str(exc).splitlines()[0]}") from None
    executive = doc.get("executive", doc) if isinstance(doc, dict) else doc
    if isinstance(executive, dict) and args.time_limit is not None:
        executive = {**executive, "optimal_time_limit_s": args.time_limit}
    s = schedule_from_config(executive, args.method)
    out = {"method": s.method, "optimality": s.optimality, "max_tick_load_us": s.max_tick_load_us,
           "lower_bound_us": s.lower_bound_us, "solver_s": round(s.solver_s, 4), "warning": s.warning,
           "reason": s.certificate_reason, "tick_us": s.tick_us,
           "precedence": [dataclasses.asdict(e) for e in s.precedence],
           "tasks": [{"name": t.name, "group": t.group, "divider": t.divider, "phase": t.phase, "order": t.order,
                      "budget_us": t.budget_us} for t in s.tasks]}
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    if s.warning:
        print(f"warning: {s.warning}", file=sys.stderr)
    print(f"phases by {s.method}{' (' + s.optimality + ')' if s.optimality else ''}: max tick load {s.max_tick_load_us} µs "
          f"of {s.tick_us}; {s.certificate_reason}")
    for t in s.tasks:
        print(f"  {t.order:>2} {t.name:<20} {t.group:<11} divider {t.divider:<4} phase {t.phase:<4} budget {t.budget_us} µs")
    for e in s.precedence:
        print(f"  edge {e}")
    return 0


def cmd_gap_study(args: argparse.Namespace) -> int:
    from .optimal_study import run_study, summarise

    try:
        sizes = [int(x) for x in args.sizes.split(",")]
        utils = [float(x) for x in args.utilisations.split(",")]
    except ValueError:
        raise TaskSetError("--sizes and --utilisations must be comma-separated numbers") from None
    if not sizes or min(sizes) < 2 or not all(0 < u < 1 for u in utils) or args.sets < 1:
        raise TaskSetError("need sizes >= 2, utilisations in (0, 1) and --sets >= 1")
    start = time.monotonic()

    def progress(done: int, total: int) -> None:
        print(f"\rgap-study: {done}/{total} sets, {time.monotonic() - start:.0f} s", end="", file=sys.stderr, flush=True)

    rows = run_study(sizes, utils, args.sets, args.seed, args.time_limit, progress)
    print(file=sys.stderr)
    if args.out:
        with open(args.out, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=[fl.name for fl in dataclasses.fields(rows[0])])
            writer.writeheader()
            writer.writerows(dataclasses.asdict(r) for r in rows)
    print(f"{len(rows)} sets (n = {args.sizes}, U = {args.utilisations}, {args.sets} per point, seed {args.seed}), "
          f"time limit {args.time_limit:g} s per model, 1 CP-SAT worker, {time.monotonic() - start:.0f} s")
    print(f"{'n':>4} {'sets':>5} {'proven':>7} {'GCD+ opt':>9} {'Pap opt':>8} {'gap med':>8} {'gap p95':>8} {'gap max':>8} "
          f"{'ZI exist':>9} {'ZI none':>8} {'ZI ?':>5} {'GCD+ ZI':>8} {'missed':>7} {'exec s med/p95':>15} "
          f"{'FIFO s med/p95':>15}")
    for s in summarise(rows):
        print(f"{s['n']!s:>4} {s['sets']:>5} {s['exec_proven']:>7} {s['gcdplus_optimal']:>9} {s['paparazzi_optimal']:>8} "
              f"{s['gap_median']:>8.1%} {s['gap_p95']:>8.1%} {s['gap_max']:>8.1%} {s['zero_exists']:>9} "
              f"{s['zero_impossible']:>8} {s['zero_undecided']:>5} {s['gcdplus_zero']:>8} {s['zero_missed_by_gcdplus']:>7} "
              f"{s['exec_s_median']:>7.2f}/{s['exec_s_p95']:<7.2f} {s['fifo_s_median']:>7.2f}/{s['fifo_s_p95']:<7.2f}")
    return 0


def add_optimal_parsers(sub: Any) -> None:
    """Register the three subcommands on cli.py's subparsers."""
    p = sub.add_parser("optimal", help="exact offsets/phases (CP-SAT) for a task set, beside GCD+")
    p.add_argument("file")
    p.add_argument("--model", choices=("executive", "fifo"), default="executive")
    p.add_argument("--tick", type=int, default=None, help="executive tick (divides every period); default Ω")
    p.add_argument("--time-limit", type=_time_limit, default=2.0, help="solver time limit [s]")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_optimal)
    p = sub.add_parser("schedule", help="a cyclic executive's tick schedule from a core config (precedence included)")
    p.add_argument("file")
    p.add_argument("--method", choices=PHASE_METHODS, default=None, help="override the config's phase_method")
    p.add_argument("--time-limit", type=_time_limit, default=None, help="phase_method optimal: solver time limit [s]")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_schedule)
    p = sub.add_parser("gap-study", help="GCD+ vs the exact optimum on the thesis' random sets")
    p.add_argument("--sizes", default="8,16,32")
    p.add_argument("--utilisations", default="0.5,0.6,0.7,0.8,0.9,0.95")
    p.add_argument("--sets", type=int, default=5, help="random sets per (n, U) point")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--time-limit", type=_time_limit, default=2.0, help="per model and set [s]")
    p.add_argument("--out", default=None, help="CSV of every set")
    p.set_defaults(func=cmd_gap_study)
