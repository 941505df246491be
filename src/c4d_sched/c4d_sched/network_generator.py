"""Seeded random switched networks: the Orion-like case of thesis §4.5 and small cases for the
exact comparison.

What: a tree of switches — with core = 0, switch k ≥ 2 links to a uniformly drawn earlier switch
that still has fewer than `max_switch_degree` switch neighbours; with core = c > 0 the first c
switches form such a tree (the backbone) and every other switch is an edge switch linked to a
uniformly drawn backbone switch — end systems spread over the edge switches (all switches when
core = 0; shuffled round robin, so each serves ⌊E/S⌋ or ⌈E/S⌉ of them), and unicast flows
between two distinct end systems drawn uniformly, routed on the unique tree path (a tree cannot
make paths fork and merge again, §4.1 consideration 3). Periods are Ω·m with m drawn uniformly
from `subperiods`; sizes uniform in [min_size, max_size] bytes, and flow 0 gets max_size so the
largest frame — hence the default S&F (thesis: "equal to the maximum transmission time") — is
fixed. Why: the thesis' Orion data ([Zha+20], Realistic Test Case) are not in the seeds; this
generator matches its published shape (15 switches, 31 end systems, 100 TT flows, 1 Gb/s,
Ω = 625 µs, largest frame 1527 B → S&F = 12 216 ns) and is documented in docs/gcdsharp.md.
"""

from __future__ import annotations

import random
from collections.abc import Sequence

from .network_model import Network, network_from_dict

ORION_SUBPERIODS = (2, 4, 8, 16, 3, 6, 12, 24, 5, 10, 20, 40)
ORION_CORE = 2


def _tree_path(parent: dict[str, str | None], a: str, b: str) -> list[str]:
    """Switch path from a to b in the tree given by parent links."""
    up_a = [a]
    while parent[up_a[-1]] is not None:
        up_a.append(parent[up_a[-1]])  # type: ignore[arg-type]
    up_b = [b]
    while parent[up_b[-1]] is not None:
        up_b.append(parent[up_b[-1]])  # type: ignore[arg-type]
    common = set(up_a) & set(up_b)
    top = next(x for x in up_a if x in common)
    return up_a[: up_a.index(top) + 1] + list(reversed(up_b[: up_b.index(top)]))


def generate_network(seed: int, switches: int, end_systems: int, flows: int, omega: int,
                     subperiods: Sequence[int], min_size: int, max_size: int, rate: float = 1e9,
                     time_unit: str = "ns", max_switch_degree: int = 4,
                     core: int = 0) -> Network:
    """A validated random tree network (see the module docstring)."""
    if switches < 1 or end_systems < 2 or flows < 1 or omega < 1 or not subperiods or min_size < 1 \
            or max_size < min_size or max_switch_degree < 2:
        raise ValueError("generate_network: needs switches >= 1, end_systems >= 2, flows >= 1, omega >= 1, "
                         "subperiods, 1 <= min_size <= max_size and max_switch_degree >= 2")
    rng = random.Random(seed)
    sw = [f"SW{k + 1}" for k in range(switches)]
    es = [f"ES{k + 1}" for k in range(end_systems)]
    parent: dict[str, str | None] = {sw[0]: None}
    degree = {s: 0 for s in sw}
    links: list[list[str]] = []
    core = core or switches
    for x, s in enumerate(sw[1:], start=1):
        up = rng.choice([t for t in sw[:min(x, core)] if degree[t] < max_switch_degree or x >= core])
        parent[s] = up
        degree[up] += 1
        degree[s] += 1
        links.append([up, s])
    order = sw[core:] if core < switches else sw[:]
    rng.shuffle(order)
    home = {e: order[k % len(order)] for k, e in enumerate(es)}
    links += [[e, home[e]] for e in es]
    flow_docs = []
    for k in range(flows):
        src, dst = rng.sample(es, 2)
        path = [src, *_tree_path(parent, home[src], home[dst]), dst]
        size = max_size if k == 0 else rng.randint(min_size, max_size)
        flow_docs.append({"name": f"tt{k + 1}", "period": omega * rng.choice(list(subperiods)), "size": size,
                          "path": path})
    return network_from_dict({"time_unit": time_unit, "rate": rate, "end_systems": es, "switches": sw,
                              "links": links, "flows": flow_docs})


def orion_like(seed: int = 0) -> Network:
    """The Orion-like case: 15 switches (2 backbone, 13 edge), 31 end systems, 100 flows,
    1 Gb/s, Ω = 625 µs, frames 64–1527 B (S&F = 12 216 ns), subperiods ORION_SUBPERIODS."""
    return generate_network(seed, 15, 31, 100, 625_000, ORION_SUBPERIODS, 64, 1527, core=ORION_CORE)


def small_network(seed: int, flows: int = 6) -> Network:
    """A small case for the exact comparison: 3 switches, 6 end systems, Ω = 20 (µs at 8 Mb/s:
    a byte is a µs), subperiods 1–6, frames 1–6 bytes, so zero interference is sometimes out of
    reach and sometimes only found by a search."""
    return generate_network(seed, 3, 6, flows, 20, (1, 2, 3, 4, 6), 1, 6, rate=8e6, time_unit="us")

