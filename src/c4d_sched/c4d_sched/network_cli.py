"""`c4d-sched network` — GCD# offsets for a switched network, verified by per-port simulation.

    c4d-sched network NETWORK.yaml [--cycle-load crossing|section] [--exact] [--json]
    c4d-sched network NETWORK.yaml --offsets 0,13,10,...|file        (verify given offsets only)
    c4d-sched network --orion-like SEED [--write FILE]                 (generated case, §4.5)

Kept out of cli.py (which only registers it) so the network tool stays one module. Bad input
raises NetworkError (a ValueError): cli.main prints it as one line and exits 2.
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

import yaml

from .gcdsharp import CYCLE_LOADS, gcdsharp
from .network_generator import orion_like
from .network_model import Network, NetworkError, load_network, network_to_dict, port_name
from .network_verify import Verification, verify


def add_network_parser(sub: Any) -> None:
    """Register the `network` subcommand on cli.py's subparsers."""
    p = sub.add_parser("network", help="GCD# offsets for flows in a switched network (thesis ch. 4)")
    p.add_argument("file", nargs="?", help="network YAML (see docs/gcdsharp.md)")
    p.add_argument("--orion-like", type=int, default=None, metavar="SEED",
                   help="use the generated Orion-like case (15 switches, 31 end systems, 100 flows)")
    p.add_argument("--write", default=None, metavar="FILE", help="write the network (with offsets) as YAML")
    p.add_argument("--cycle-load", default="crossing", choices=CYCLE_LOADS,
                   help="flows counted in a cycle's load: crossing flows (stated rule) or the whole section "
                        "(the worked example)")
    p.add_argument("--offsets", default=None, help="verify these offsets (comma-separated, or 'file') instead")
    p.add_argument("--exact", action="store_true", help="also solve the exact CP-SAT model (small networks)")
    p.add_argument("--time-limit", type=float, default=10.0, help="exact model time limit, s")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_network)


def _given_offsets(net: Network, text: str) -> tuple[int, ...]:
    if text == "file":
        if any(f.offset is None for f in net.flows):
            raise NetworkError("--offsets file: every flow needs an 'offset' in the file")
        return tuple(int(f.offset) for f in net.flows)  # type: ignore[arg-type]
    try:
        offsets = tuple(int(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise NetworkError(f"--offsets must be comma-separated integers or 'file', got '{text}'") from None
    if len(offsets) != len(net.flows):
        raise NetworkError(f"--offsets has {len(offsets)} values for {len(net.flows)} flows")
    return offsets


def _verification_dict(v: Verification) -> dict[str, Any]:
    return {"ok": v.ok, "ports": v.ports, "transmissions": v.transmissions,
            "overlapping_pairs": v.overlapping_pairs, "overlaps": [o.__dict__ for o in v.overlaps]}


def cmd_network(args: argparse.Namespace) -> int:
    if (args.file is None) == (args.orion_like is None):
        raise NetworkError("give a network FILE or --orion-like SEED (one of them)")
    if not args.time_limit > 0:
        raise NetworkError(f"--time-limit must be > 0, got {args.time_limit}")
    net = load_network(args.file) if args.file is not None else orion_like(args.orion_like)
    out: dict[str, Any] = {"unit": net.time_unit, "store_and_forward": net.store_and_forward,
                           "flows": [{"name": f.name, "period": f.period, "size": f.size, "wcet": f.wcet,
                                      "path": [port_name(p) for p in f.ports]} for f in net.flows]}
    if args.offsets is not None:
        offsets = _given_offsets(net, args.offsets)
        out["method"] = "given offsets"
    else:
        start = time.perf_counter()
        r = gcdsharp(net, args.cycle_load)
        spent = time.perf_counter() - start
        offsets = r.offsets
        out["method"] = f"gcdsharp (cycle load: {args.cycle_load})"
        out["gcdsharp"] = {"omega": r.omega, "sum_delta": r.sum_delta, "sum_delta_over_omega": r.sum_delta / r.omega,
                           "indicator": r.indicator, "max_end_to_end": r.max_end_to_end,
                           "assign_ms": spent * 1e3,
                           "sections": [{"p": p, "start": s, "size": d} for p, s, d in r.sections]}
        for row, pl in zip(out["flows"], r.placements, strict=True):
            row.update(section=pl.section, cycle=pl.cycle, internal_offset=pl.internal,
                       section_start=pl.section_start, conflict_free=pl.conflict_free)
    for row, o in zip(out["flows"], offsets, strict=True):
        row["offset"] = o
    out["verification"] = _verification_dict(verify(net, offsets))
    if args.exact:
        from .network_exact import exact_offsets

        e = exact_offsets(net, args.time_limit)
        out["exact"] = {"status": e.status, "offsets": e.offsets, "seconds": e.seconds,
                        "verified": None if e.offsets is None else verify(net, e.offsets).ok}
    if args.write:
        doc = network_to_dict(net)
        for f, o in zip(doc["flows"], offsets, strict=True):
            f["offset"] = o
        with open(args.write, "w") as fh:
            yaml.safe_dump(doc, fh, sort_keys=False, default_flow_style=None, width=200)
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        _print(out)
    return 0 if out["verification"]["ok"] else 1


def _print(d: dict[str, Any]) -> None:
    g = d.get("gcdsharp")
    print(f"method: {d['method']}   (unit: {d['unit']}, S&F = {d['store_and_forward']})")
    head = f"{'flow':<10}{'T':>10}{'C':>8}{'hops':>5}{'offset':>10}"
    if g:
        head += f"{'p':>4}{'O_C':>5}{'O_I':>8}{'O_S':>9}"
    print(head)
    for f in d["flows"]:
        line = f"{f['name']:<10}{f['period']:>10}{f['wcet']:>8}{len(f['path']):>5}{f['offset']:>10}"
        if g:
            line += f"{f['section']:>4}{f['cycle']:>5}{f['internal_offset']:>8}{f['section_start']:>9}"
            line += "" if f["conflict_free"] else "  (no conflict-free slot)"
        print(line)
    if g:
        sections = ", ".join(f"Ψ_{s['p']}: start {s['start']} size {s['size']}" for s in g["sections"])
        print(f"Ω = {g['omega']}; {sections}; Σδ = {g['sum_delta']} ({100 * g['sum_delta_over_omega']:.1f} % of Ω); "
              f"longest end-to-end {g['max_end_to_end']}")
        print(f"null-interference indicator (Σδ ≤ Ω, every flow conflict-free): {'HOLDS' if g['indicator'] else 'no'}"
              f"; assigned in {g['assign_ms']:.1f} ms")
    v = d["verification"]
    verdict = "no overlap" if v["ok"] else f"{v['overlapping_pairs']} overlapping (port, flow, flow) pair(s)"
    print(f"verifier (per-port simulation over the hyperperiod, {v['transmissions']} transmissions on "
          f"{v['ports']} ports): {verdict}")
    for o in v["overlaps"]:
        print(f"  overlap on {o['port']}: {o['flow_a']} at {o['start_a']} and {o['flow_b']} at {o['start_b']}")
    e = d.get("exact")
    if e:
        extra = f", offsets {','.join(map(str, e['offsets']))} (verified: {e['verified']})" if e["offsets"] else ""
        print(f"exact CP-SAT model: {e['status']} in {e['seconds']:.2f} s{extra}")
