"""`c4d-sched` — offset assignment, evaluation and experiments from the command line.

    c4d-sched assign FILE [--method gcdplus] [--cycle N] [--json]
    c4d-sched evaluate FILE [--offsets 4,3,0,8] [--json]     (offsets default to the file's)
    c4d-sched experiment [--sizes 8,16] [--utilisations 0.5,...] [--sets 1000] [--out DIR]
    c4d-sched network NETWORK.yaml [--cycle-load crossing|section] [--exact]   (GCD#, see network_cli)

FILE is a YAML or CSV task set (see c4d_sched.taskio). Bad input: one line on stderr, exit 2.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any, NoReturn

from .fifo import EvaluationTooLarge, cycle_loads, evaluate
from .gcdplus import GcdPlusResult
from .methods import METHODS, assign
from .model import Assignment, TaskSet, TaskSetError
from .network_cli import add_network_parser
from .optimal_cli import add_optimal_parsers
from .taskio import load_taskset


class UsageError(Exception):
    """Bad command-line input (reported as one line, exit code 2)."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line instead of usage + message
        raise UsageError(message)


def _int_list(text: str, what: str) -> list[int]:
    try:
        return [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise UsageError(f"{what} must be comma-separated integers, got '{text}'") from None


def _float_list(text: str, what: str) -> list[float]:
    try:
        return [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise UsageError(f"{what} must be comma-separated numbers, got '{text}'") from None


def _load_summary(ts: TaskSet, offsets: tuple[int, ...], cycle: int | None) -> dict[str, Any]:
    try:
        length, loads = cycle_loads(ts.periods, ts.wcets, offsets, cycle)
    except EvaluationTooLarge as exc:  # the assignment stands; only its per-cycle table is out of reach
        return {"skipped": str(exc)}
    return {"cycle": length, "max_cycle_load": int(loads.max()), "cycles": len(loads),
            "overloaded_cycles": int((loads > length).sum())}


def _assignment_dict(ts: TaskSet, a: Assignment, cycle: int | None) -> dict[str, Any]:
    out: dict[str, Any] = {"method": a.method, "note": a.note, "unit": ts.unit, "utilisation": round(ts.utilisation, 6),
                 "tasks": [{"name": t.name, "period": t.period, "wcet": t.wcet, "offset": o}
                           for t, o in zip(ts.tasks, a.offsets, strict=True)]}
    detail = a.detail
    if isinstance(detail, GcdPlusResult):
        for row, p in zip(out["tasks"], detail.placements, strict=True):
            row.update(section=p.section, cycle=p.cycle, internal_offset=p.internal,
                       section_start=p.section_start, section_size=p.section_size)
        out["gcdplus"] = {
            "omega": detail.omega, "order": detail.order, "sum_delta": detail.sum_delta,
            "sections": [{"p": p, "start": s, "size": d} for p, s, d in detail.sections],
            "delta_per_section": {str(p): d for p, _, d in detail.sections},
            "certificate": detail.certificate, "certificate_reason": detail.certificate_reason,
            "candidates": [{"order": o, "certificate": c, "score": s} for o, c, s in detail.candidates],
        }
    out["load"] = _load_summary(ts, a.offsets, cycle)
    return out


def _print_assignment(d: dict[str, Any]) -> None:
    g = d.get("gcdplus")
    head = f"{'task':<24}{'T':>10}{'C':>8}{'offset':>10}"
    if g:
        head += f"{'p':>5}{'O_C':>6}{'O_I':>8}{'δ_p':>8}{'O_S':>8}"
    print(f"method: {d['method']}{' — ' + d['note'] if d['note'] else ''}   (unit: {d['unit']}, U = {d['utilisation']:.3f})")
    print(head)
    for t in d["tasks"]:
        line = f"{t['name']:<24}{t['period']:>10}{t['wcet']:>8}{t['offset']:>10}"
        if g:
            line += f"{t['section']:>5}{t['cycle']:>6}{t['internal_offset']:>8}{t['section_size']:>8}{t['section_start']:>8}"
        print(line)
    if g:
        sections = ", ".join(f"Ψ_{s['p']}: start {s['start']} size {s['size']}" for s in g["sections"])
        print(f"Ω = {g['omega']}; sections {sections}; Σδ = {g['sum_delta']}")
        print(f"certificate (Lemma 3.2.2): {'HOLDS' if g['certificate'] else 'does not hold'} — {g['certificate_reason']}")
    load = d["load"]
    if "skipped" in load:
        print(f"per-cycle load: not computed — {load['skipped']}")
        return
    print(f"per-cycle load (cycle = {load['cycle']}): max {load['max_cycle_load']} over {load['cycles']} cycles, "
          f"{load['overloaded_cycles']} cycle(s) above the cycle length")


def _evaluation_dict(ts: TaskSet, offsets: tuple[int, ...], method: str) -> dict[str, Any]:
    e = evaluate(ts, offsets)
    return {"method": method, "hyperperiod": e.hyperperiod, "horizon": e.horizon, "jobs": e.jobs,
            "schedulable": e.schedulable, "zero_interference": e.zero_interference,
            "tasks": [t.__dict__ for t in e.tasks]}


def _print_evaluation(d: dict[str, Any]) -> None:
    print(f"method: {d['method']}   H = {d['hyperperiod']}, window [0, {d['horizon']}), {d['jobs']} jobs")
    print(f"{'task':<24}{'T':>10}{'C':>8}{'O':>10}{'η':>9}{'η/T':>8}{'η/maxC':>8}{'(η+C)/C':>9}{'misses':>8}")
    for t in d["tasks"]:
        print(f"{t['name']:<24}{t['period']:>10}{t['wcet']:>8}{t['offset']:>10}{t['max_delay']:>9}"
              f"{t['delay_over_period']:>8.3f}{t['delay_over_max_other_wcet']:>8.3f}{t['response_over_wcet']:>9.3f}"
              f"{t['deadline_misses']:>8}")
    verdict = "zero interference" if d["zero_interference"] else ("schedulable" if d["schedulable"] else "DEADLINE MISSES")
    print(f"result: {verdict}")


def cmd_assign(args: argparse.Namespace) -> int:
    ts = load_taskset(args.file)
    a = assign(ts, args.method, args.seed)
    d = _assignment_dict(ts, a, args.cycle)
    if args.evaluate:
        d["evaluation"] = _evaluation_dict(ts, a.offsets, a.method)
    if args.json:
        print(json.dumps(d, indent=2))
    else:
        _print_assignment(d)
        if args.evaluate:
            print()
            _print_evaluation(d["evaluation"])
    return 0


def cmd_evaluate(args: argparse.Namespace) -> int:
    ts = load_taskset(args.file)
    if args.offsets is not None:
        offsets = tuple(_int_list(args.offsets, "--offsets"))
        if len(offsets) != len(ts.tasks):
            raise UsageError(f"--offsets has {len(offsets)} values for {len(ts.tasks)} tasks")
        if any(o < 0 for o in offsets):
            raise UsageError("--offsets must be >= 0")
    else:
        if any(t.offset is None for t in ts.tasks):
            raise UsageError("give --offsets, or an 'offset' for every task in the file")
        offsets = tuple(int(t.offset) for t in ts.tasks)  # type: ignore[arg-type]
    d = _evaluation_dict(ts, offsets, "given offsets")
    d["load"] = _load_summary(ts, offsets, args.cycle)
    if args.json:
        print(json.dumps(d, indent=2))
    else:
        _print_evaluation(d)
    return 0


def cmd_experiment(args: argparse.Namespace) -> int:
    from .experiment import plot, ratios_to_best_baseline, run_experiment, write_csv

    sizes = _int_list(args.sizes, "--sizes")
    utils = _float_list(args.utilisations, "--utilisations")
    methods = args.methods.split(",")
    for m in methods:
        if m not in METHODS:
            raise UsageError(f"unknown method '{m}' (known: {', '.join(METHODS)})")
    if not sizes or min(sizes) < 2 or not utils or not all(0 < u < 1 for u in utils) or args.sets < 1:
        raise UsageError("need sizes >= 2, utilisations in (0, 1) and --sets >= 1")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    start = time.monotonic()

    def progress(done: int, total: int) -> None:
        print(f"\rexperiment: {done}/{total} points, {time.monotonic() - start:.0f} s", end="", file=sys.stderr, flush=True)

    rows = run_experiment(sizes, utils, args.sets, args.seed, methods, args.min_prime_share, args.workers, progress)
    print(file=sys.stderr)
    write_csv(rows, out / "schedulability.csv")
    plot(rows, out / "schedulability.png")
    print(f"{'n':>3} {'U':>5} " + " ".join(f"{m:>17}" for m in methods) + "   GCD+/best baseline")
    for n in sizes:
        for u in utils:
            at = {r.method: r for r in rows if r.n == n and r.utilisation == u}
            line = f"{n:>3} {u:>5.2f} " + " ".join(f"{at[m].schedulable:>17}" for m in methods)
            ratio = [r for r in ratios_to_best_baseline(rows) if r[0] == n and r[1] == u]
            if ratio:
                line += f"   {ratio[0][5]:.2f}x vs {ratio[0][3]}"
            print(line)
    print(f"wrote {out / 'schedulability.csv'} and {out / 'schedulability.png'} in {time.monotonic() - start:.0f} s")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="c4d-sched", description="GCD+ offset assignment, baselines and exact FIFO evaluation")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    p = sub.add_parser("assign", help="assign offsets to a task set")
    p.add_argument("file")
    p.add_argument("--method", default="gcdplus", choices=list(METHODS))
    p.add_argument("--seed", type=int, default=0, help="seed for the randomised baselines")
    p.add_argument("--cycle", type=int, default=None, help="cycle (tick) length for the load table; default Ω")
    p.add_argument("--evaluate", action="store_true", help="also run the exact FIFO evaluation")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_assign)
    p = sub.add_parser("evaluate", help="evaluate given offsets exactly (FIFO, 2H + max O)")
    p.add_argument("file")
    p.add_argument("--offsets", default=None, help="comma-separated offsets in task order")
    p.add_argument("--cycle", type=int, default=None)
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_evaluate)
    p = sub.add_parser("experiment", help="schedulability vs utilisation for random task sets")
    p.add_argument("--sizes", default="8,16")
    p.add_argument("--utilisations", default="0.5,0.55,0.6,0.65,0.7,0.75,0.8,0.85,0.9,0.95")
    p.add_argument("--sets", type=int, default=1000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--methods", default=",".join(METHODS))
    p.add_argument("--min-prime-share", type=float, default=0.10,
                   help="GM01 model: keep primes dividing at least this share of Paparazzi periods")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--out", default="sched-experiment")
    p.set_defaults(func=cmd_experiment)
    add_network_parser(sub)
    add_optimal_parsers(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    try:
        args = build_parser().parse_args(argv)
        return int(args.func(args))
    except (UsageError, TaskSetError, EvaluationTooLarge, ValueError) as exc:
        print(f"c4d-sched: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
