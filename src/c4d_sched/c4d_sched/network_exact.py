"""Exact zero-interference offset model for small switched networks (OR-Tools CP-SAT).

What: integer offsets O_i ∈ [0, T_i) such that no two frames overlap on any shared output port
in the constant-S&F model: for every crossing pair (i, j) with hop indices h_i, h_j at their
first shared port and g = gcd(T_i, T_j),
    (O_j + h_j·SF − O_i − h_i·SF) mod g ∈ [c_i, g − c_j]
with c the largest transmission time of each flow on the shared ports (the hop difference is
the same on every shared port, §4.1 consideration 3). The mod is linearised with one integer
k_ij per pair. The answer is a zero-interference assignment, a proof that none exists, or
"unknown" at the time limit. Why: GCD# is a heuristic; on small networks this says how often
it misses a feasible configuration (bench/gcdsharp.py, docs/gcdsharp.md). The solver's offsets
are checked by network_verify, not trusted.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

from ortools.sat.python import cp_model

from .network_model import Network


@dataclass(frozen=True)
class ExactResult:
    """Status ('feasible', 'infeasible' or 'unknown'), offsets if feasible, wall time (s)."""

    status: str
    offsets: tuple[int, ...] | None
    seconds: float


def exact_offsets(net: Network, time_limit_s: float = 10.0, workers: int = 1, seed: int = 0) -> ExactResult:
    """Solve the zero-interference model (see the module docstring)."""
    if not time_limit_s > 0:
        raise ValueError(f"time limit must be > 0 s, got {time_limit_s}")
    start = time.perf_counter()
    model = cp_model.CpModel()
    o = [model.new_int_var(0, f.period - 1, f"O_{f.name}") for f in net.flows]
    sf = net.store_and_forward
    for (a, b), c in net.crossings.items():
        fa, fb = net.flows[a], net.flows[b]
        ca = max(fa.tx[c.hop_a + k] for k in range(len(c.ports)))
        cb = max(fb.tx[c.hop_b + k] for k in range(len(c.ports)))
        g = math.gcd(fa.period, fb.period)
        if ca + cb > g:
            return ExactResult("infeasible", None, time.perf_counter() - start)
        shift = (c.hop_b - c.hop_a) * sf
        lo = -fa.period - abs(shift) - g
        hi = fb.period + abs(shift) + g
        k = model.new_int_var(lo // g - 1, hi // g + 1, f"k_{a}_{b}")
        diff = o[b] - o[a] + shift - g * k
        model.add(diff >= ca)
        model.add(diff <= g - cb)
    solver = cp_model.CpSolver()
    solver.parameters.max_time_in_seconds = time_limit_s
    solver.parameters.num_workers = workers
    solver.parameters.random_seed = seed
    status = solver.solve(model)
    spent = time.perf_counter() - start
    if status in (cp_model.OPTIMAL, cp_model.FEASIBLE):
        return ExactResult("feasible", tuple(int(solver.value(x)) for x in o), spent)
    if status == cp_model.INFEASIBLE:
        return ExactResult("infeasible", None, spent)
    return ExactResult("unknown", None, spent)
