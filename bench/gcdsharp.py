#!/usr/bin/env python3
"""GCD# (thesis chapter 4): assign time, section sizes and verifier result on the worked example
and the Orion-like case, and GCD# against the exact CP-SAT model on small networks.

Thesis figures (§4.5, Python 3.9 on an i7-4710MQ): Orion, 100 flows, offsets in < 40 ms,
Σδ = 109 800 ns = 17.6 % of Ω = 625 000 ns, no overlap in the pairwise check.
Assign time is GCD# alone on a loaded network (validation and the crossing table are built by
the loader); medians and p95 over --repeats runs. The platform-stall probe reports what the
machine itself imposed meanwhile.

Usage: . ./env.sh && flock /tmp/c4d_graph.lock python bench/gcdsharp.py [--repeats 200] [--seeds 20] [--small 60]
"""

from __future__ import annotations

import argparse
import platform
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "test" / "support"))
from stall_probe import StallProbe, worst_line  # noqa: E402

from c4d_sched.gcdsharp import gcdsharp  # noqa: E402
from c4d_sched.network_exact import exact_offsets  # noqa: E402
from c4d_sched.network_generator import orion_like, small_network  # noqa: E402
from c4d_sched.network_model import Network, load_network  # noqa: E402
from c4d_sched.network_verify import verify  # noqa: E402


def p95(values: list[float]) -> float:
    values = sorted(values)
    return values[int(0.95 * (len(values) - 1))]


def timed(net: Network, repeats: int, cycle_load: str = "crossing") -> list[float]:
    out = []
    for _ in range(repeats):
        start = time.perf_counter()
        gcdsharp(net, cycle_load)
        out.append((time.perf_counter() - start) * 1e3)
    return out


def case_row(name: str, net: Network, repeats: int, cycle_load: str = "crossing") -> None:
    ms = timed(net, repeats, cycle_load)
    r = gcdsharp(net, cycle_load)
    v = verify(net, r.offsets)
    sections = " ".join(f"Ψ{p}:{d}" for p, _, d in r.sections)
    print(f"{name:<34}{len(net.flows):>6}{statistics.median(ms):>10.2f}{p95(ms):>9.2f}{r.sum_delta:>10}"
          f"{100 * r.sum_delta / r.omega:>8.1f}%  {'no overlap' if v.ok else f'{v.overlapping_pairs} OVERLAPS':<12}"
          f"{sections}")


def small_rows(flows: int, count: int, limit: float) -> None:
    """GCD# and the exact model on `count` small networks of `flows` flows."""
    print(f"small networks (3 switches, 6 end systems, {flows} flows, Ω = 20): GCD# vs exact CP-SAT "
          f"(limit {limit:g} s, 1 worker), {count} seeds")
    counts = {"both": 0, "exact only": 0, "infeasible": 0, "unknown": 0, "gcd# only": 0}
    t_gcd, t_exact = [], []
    for seed in range(count):
        net = small_network(seed, flows=flows)
        start = time.perf_counter()
        r = gcdsharp(net)
        t_gcd.append((time.perf_counter() - start) * 1e3)
        ok = verify(net, r.offsets).ok
        e = exact_offsets(net, limit)
        t_exact.append(e.seconds * 1e3)
        if e.offsets is not None and not verify(net, e.offsets).ok:
            raise SystemExit(f"seed {seed}: the exact model's offsets overlap (model bug)")
        key = ("both" if ok else "exact only") if e.status == "feasible" else (
            "gcd# only" if ok else ("infeasible" if e.status == "infeasible" else "unknown"))
        counts[key] += 1
    print(f"  zero interference found by both: {counts['both']}, by the exact model only: {counts['exact only']}, "
          f"proven impossible: {counts['infeasible']}, unknown at the limit: {counts['unknown']}, "
          f"GCD# only (exact model unknown): {counts['gcd# only']}")
    print(f"  time per network: GCD# median {statistics.median(t_gcd):.3f} ms (p95 {p95(t_gcd):.3f}), "
          f"CP-SAT median {statistics.median(t_exact):.1f} ms (p95 {p95(t_exact):.1f}), "
          f"ratio {statistics.median(t_exact) / statistics.median(t_gcd):.0f}x")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=200)
    parser.add_argument("--seeds", type=int, default=20, help="Orion-like seeds for the spread")
    parser.add_argument("--small", type=int, default=60, help="small networks for the exact comparison")
    parser.add_argument("--time-limit", type=float, default=10.0, help="CP-SAT limit per small network, s")
    args = parser.parse_args()
    if args.repeats < 5 or args.seeds < 1 or args.small < 1 or not args.time_limit > 0:
        parser.error("need --repeats >= 5, --seeds >= 1, --small >= 1, --time-limit > 0")
    probe = StallProbe()
    try:
        print(f"python {platform.python_version()} on {platform.machine()}; assign time over {args.repeats} runs")
        print(f"{'case':<34}{'flows':>6}{'med ms':>10}{'p95 ms':>9}{'Σδ':>10}{'Σδ/Ω':>9}  {'verifier':<12}sections δ_p")
        worked = load_network(ROOT / "examples" / "network_worked_example.yaml")
        case_row("worked example (stated rule)", worked, args.repeats)
        case_row("worked example (section load)", worked, args.repeats, "section")
        case_row("Orion-like seed 0", orion_like(0), args.repeats)
        fractions, medians, bad = [], [], 0
        for seed in range(args.seeds):
            net = orion_like(seed)
            r = gcdsharp(net)
            fractions.append(r.sum_delta / r.omega)
            medians.append(statistics.median(timed(net, max(5, args.repeats // 10))))
            bad += not verify(net, r.offsets).ok
        print(f"Orion-like seeds 0..{args.seeds - 1}: Σδ/Ω median {100 * statistics.median(fractions):.1f} %, "
              f"max {100 * max(fractions):.1f} %, < 20 % in {sum(f < 0.2 for f in fractions)}/{args.seeds}; "
              f"assign median of medians {statistics.median(medians):.2f} ms, max {max(medians):.2f} ms; "
              f"{bad} with overlaps")
        print()
        for flows in (7, 10):
            small_rows(flows, args.small, args.time_limit)
    finally:
        stalls = probe.stop()
    print(worst_line(stalls))
    return 0


if __name__ == "__main__":
    sys.exit(main())
