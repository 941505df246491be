"""Switched-network model for GCD# (thesis chapter 4, §4.1–4.2): end systems, switches,
bidirectional links with a bit rate, and strictly periodic flows routed on fixed paths.

What: a validated, immutable `Network` built from a YAML file or a dict. A flow's path is a
sequence of physical nodes (end system, switches..., end system) or of output ports "A->B";
both become the sequence of output ports the thesis reasons on (Def. 4.10/4.12), each with the
frame's transmission time on that port's link. Why here: GCD#, the verifier and the exact model
share this one validated view, so a bad file fails once, with one line, before any algorithm.

YAML (integer times in `time_unit`; sizes in bytes; rates in bit/s):
    time_unit: ns               # ns | us | ms | s
    rate: 1.0e9                 # default link rate (bit/s)
    store_and_forward: 12216    # optional, default: the largest transmission time (thesis §4.5)
    end_systems: [E1, E2]
    switches: [SW1]
    links:
      - [E1, SW1]               # or {between: [E1, SW1], rate: 1.0e8}
      - [E2, SW1]
    flows:
      - {name: f1, period: 625000, size: 1527, path: [E1, SW1, E2]}   # optional: offset
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import Any

import yaml

TICKS_PER_SECOND = {"ns": 10**9, "us": 10**6, "ms": 10**3, "s": 1}
_TOP_KEYS = {"time_unit", "rate", "store_and_forward", "end_systems", "switches", "links", "flows"}
_FLOW_KEYS = {"name", "period", "size", "path", "offset"}

Port = tuple[str, str]  # output port of node [0] towards node [1] (thesis: E_i E_j with an arrow)


class NetworkError(ValueError):
    """Invalid network description (reported by the CLI as one line, exit code 2)."""


def port_name(port: Port) -> str:
    return f"{port[0]}->{port[1]}"


@dataclass(frozen=True)
class NetFlow:
    """A strictly periodic flow S_i (Def. 4.11): period T_i, frame size (bytes), path of output
    ports, per-hop transmission time, and an optional given offset."""

    name: str
    period: int
    size: int
    ports: tuple[Port, ...]
    tx: tuple[int, ...]  # transmission time of one frame on each port of the path
    offset: int | None = None

    @property
    def wcet(self) -> int:
        """C_i used by GCD#: the longest transmission time along the path (equal on one rate)."""
        return max(self.tx)


@dataclass(frozen=True)
class Crossing:
    """Two flows sharing output ports: the shared ports (a contiguous run in both paths, §4.1
    consideration 3) and the hop index of the first shared port in each path."""

    ports: tuple[Port, ...]
    hop_a: int
    hop_b: int


@dataclass(frozen=True)
class Network:
    """A validated switched network: nodes, link rates, flows and the S&F delay (Def. 4.13)."""

    time_unit: str
    end_systems: tuple[str, ...]
    switches: tuple[str, ...]
    rates: Mapping[frozenset[str], Fraction]  # link {A, B} -> bit/s
    flows: tuple[NetFlow, ...]
    store_and_forward: int
    crossings: Mapping[tuple[int, int], Crossing] = field(default_factory=dict)  # (a, b), a < b

    @property
    def periods(self) -> tuple[int, ...]:
        return tuple(f.period for f in self.flows)

    @property
    def wcets(self) -> tuple[int, ...]:
        return tuple(f.wcet for f in self.flows)

    def crossing(self, a: int, b: int) -> Crossing | None:
        """The crossing of flows a and b seen from a (hop_a is a's hop), or None."""
        if a < b:
            return self.crossings.get((a, b))
        c = self.crossings.get((b, a))
        return None if c is None else Crossing(c.ports, c.hop_b, c.hop_a)

    def end_to_end(self, i: int) -> int:
        """Minimal latency of flow i: S&F per hop after the first, plus the last transmission."""
        f = self.flows[i]
        return (len(f.ports) - 1) * self.store_and_forward + f.tx[-1]


def transmission_time(size_bytes: int, rate: Fraction, ticks_per_second: int) -> int:
    """Ticks to send size_bytes at rate bit/s, rounded up (integer time keeps every check exact)."""
    return math.ceil(Fraction(size_bytes * 8 * ticks_per_second) / rate)


def _rate(value: Any, what: str) -> Fraction:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0 or math.isinf(value):
        raise NetworkError(f"{what} must be a positive number of bit/s, got {value!r}")
    return Fraction(value)


def _pos_int(value: Any, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
        raise NetworkError(f"{what} must be a positive integer, got {value!r}")
    return value


def _names(doc: Mapping[str, Any], key: str) -> tuple[str, ...]:
    items = doc.get(key)
    if not isinstance(items, list) or not items:
        raise NetworkError(f"'{key}' must be a non-empty list of names")
    for n in items:
        if not isinstance(n, str) or not n or "->" in n:
            raise NetworkError(f"'{key}': names must be non-empty strings without '->', got {n!r}")
    return tuple(items)


def _path_nodes(flow: str, path: Any) -> list[str]:
    """Physical node sequence of a path given as nodes or as chained output ports 'A->B'."""
    if not isinstance(path, list) or len(path) < 1 or not all(isinstance(x, str) for x in path):
        raise NetworkError(f"flow '{flow}': path must be a list of node names or of ports 'A->B'")
    if not any("->" in x for x in path):
        return list(path)
    nodes: list[str] = []
    for x in path:
        a, sep, b = x.partition("->")
        if not sep or not a or not b:
            raise NetworkError(f"flow '{flow}': path mixes nodes and ports or has a malformed port '{x}'")
        if nodes and nodes[-1] != a:
            raise NetworkError(f"flow '{flow}': port '{x}' does not start where the previous port ends ({nodes[-1]})")
        nodes += [a, b] if not nodes else [b]
    return nodes


def _crossings(flows: Sequence[NetFlow]) -> dict[tuple[int, int], Crossing]:
    """Shared ports of every crossing pair; rejects paths that fork and merge again."""
    by_port: dict[Port, list[tuple[int, int]]] = {}
    for i, f in enumerate(flows):
        for h, p in enumerate(f.ports):
            by_port.setdefault(p, []).append((i, h))
    shared: dict[tuple[int, int], list[tuple[int, int, Port]]] = {}
    for p, users in by_port.items():
        for x in range(len(users)):
            for y in range(x + 1, len(users)):
                (a, ha), (b, hb) = users[x], users[y]
                shared.setdefault((a, b), []).append((ha, hb, p))
    out: dict[tuple[int, int], Crossing] = {}
    for (a, b), hops in shared.items():
        hops.sort()
        ha0, hb0, _ = hops[0]
        for k, (ha, hb, _p) in enumerate(hops):
            if ha != ha0 + k or hb != hb0 + k:
                names = ", ".join(port_name(p) for _, _, p in hops)
                raise NetworkError(
                    f"flows '{flows[a].name}' and '{flows[b].name}' share output ports {names} that are not one "
                    "contiguous run of both paths: paths that fork and merge again are outside GCD#'s model "
                    "(thesis §4.1, consideration 3)")
        out[(a, b)] = Crossing(tuple(p for _, _, p in hops), ha0, hb0)
    return out


def network_from_dict(doc: Any) -> Network:
    """Validated Network from a parsed YAML document (see the module docstring)."""
    if not isinstance(doc, dict):
        raise NetworkError(f"a network file must be a YAML mapping, got {type(doc).__name__}")
    unknown = set(doc) - _TOP_KEYS
    if unknown:
        raise NetworkError(f"unknown key(s) {sorted(unknown)}; known: {sorted(_TOP_KEYS)}")
    unit = doc.get("time_unit", "ns")
    if unit not in TICKS_PER_SECOND:
        raise NetworkError(f"time_unit must be one of {list(TICKS_PER_SECOND)}, got {unit!r}")
    ends, switches = _names(doc, "end_systems"), _names(doc, "switches")
    every = ends + switches
    if len(set(every)) != len(every):
        dup = sorted({n for n in every if every.count(n) > 1})
        raise NetworkError(f"node name(s) {dup} declared twice")
    default_rate = _rate(doc["rate"], "'rate'") if "rate" in doc else None
    rates: dict[frozenset[str], Fraction] = {}
    links = doc.get("links")
    if not isinstance(links, list) or not links:
        raise NetworkError("'links' must be a non-empty list of [A, B] or {between: [A, B], rate: R}")
    for k, item in enumerate(links):
        pair, rate = (item.get("between"), item.get("rate", default_rate)) if isinstance(item, dict) else (item, default_rate)
        if not isinstance(pair, list) or len(pair) != 2 or pair[0] == pair[1]:
            raise NetworkError(f"link #{k + 1}: needs two different node names, got {pair!r}")
        for n in pair:
            if n not in every:
                raise NetworkError(f"link #{k + 1}: unknown node '{n}'")
        if pair[0] in ends and pair[1] in ends:
            raise NetworkError(f"link #{k + 1}: end systems '{pair[0]}' and '{pair[1]}' linked directly "
                               "(an end system connects to a switch, thesis §4.1)")
        if rate is None:
            raise NetworkError(f"link #{k + 1} ({pair[0]}-{pair[1]}): no rate and no default 'rate'")
        key = frozenset(pair)
        if key in rates:
            raise NetworkError(f"link {pair[0]}-{pair[1]} declared twice")
        rates[key] = _rate(rate, f"link #{k + 1} rate") if not isinstance(rate, Fraction) else rate
    items = doc.get("flows")
    if not isinstance(items, list) or not items:
        raise NetworkError("'flows' must be a non-empty list")
    tps = TICKS_PER_SECOND[unit]
    flows: list[NetFlow] = []
    seen: set[str] = set()
    for k, item in enumerate(items):
        if not isinstance(item, dict):
            raise NetworkError(f"flow #{k + 1} must be a mapping")
        name = str(item.get("name", f"f{k + 1}"))
        bad = set(item) - _FLOW_KEYS
        if bad:
            raise NetworkError(f"flow '{name}': unknown key(s) {sorted(bad)}; known: {sorted(_FLOW_KEYS)}")
        if name in seen:
            raise NetworkError(f"flow name '{name}' used twice")
        seen.add(name)
        period = _pos_int(item.get("period"), f"flow '{name}': period")
        size = _pos_int(item.get("size"), f"flow '{name}': size (bytes)")
        nodes = _path_nodes(name, item.get("path"))
        for n in nodes:
            if n not in every:
                raise NetworkError(f"flow '{name}': path goes through unknown node '{n}'")
        if len(nodes) < 3 or nodes[0] not in ends or nodes[-1] not in ends or any(n in ends for n in nodes[1:-1]):
            raise NetworkError(f"flow '{name}': a path goes from an end system through switches to another end "
                               f"system, got {'-'.join(nodes)}")
        if len(set(nodes)) != len(nodes):
            raise NetworkError(f"flow '{name}': path visits a node twice ({'-'.join(nodes)})")
        ports = tuple(zip(nodes[:-1], nodes[1:], strict=True))
        for a, b in ports:
            if frozenset((a, b)) not in rates:
                raise NetworkError(f"flow '{name}': output port {a}->{b} has no link {a}-{b}")
        tx = tuple(transmission_time(size, rates[frozenset(p)], tps) for p in ports)
        if max(tx) > period:
            raise NetworkError(f"flow '{name}': transmission time {max(tx)} {unit} exceeds its period {period}")
        offset = item.get("offset")
        if offset is not None and (isinstance(offset, bool) or not isinstance(offset, int) or offset < 0):
            raise NetworkError(f"flow '{name}': offset must be an integer >= 0, got {offset!r}")
        flows.append(NetFlow(name, period, size, ports, tx, offset))
    largest = max(max(f.tx) for f in flows)
    sf = doc.get("store_and_forward")
    if sf is None:
        sf = largest
    sf = _pos_int(sf, "store_and_forward")
    if sf < largest:
        raise NetworkError(f"store_and_forward {sf} {unit} is below the largest transmission time {largest} "
                           "(Def. 4.13: a switch stores the whole frame before forwarding it)")
    return Network(unit, ends, switches, rates, tuple(flows), sf, _crossings(flows))


def _yaml_problem(exc: yaml.YAMLError) -> str:
    """One line for a PyYAML error: where the parser noticed it and what it was."""
    mark = getattr(exc, "problem_mark", None)
    where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
    return f"YAML syntax error{where}: {getattr(exc, 'problem', None) or 'syntax error'}"


def load_network(path: str | Path) -> Network:
    """Read and validate a network YAML file; NetworkError (one line) on any problem.
    (c4d_sched imports no other c4d package, hence its own reading rather than c4d_common's.)"""
    p = Path(path)
    try:
        return network_from_dict(yaml.safe_load(p.read_text()))
    except OSError as exc:
        raise NetworkError(f"cannot read {p}: {exc.strerror}") from None
    except yaml.YAMLError as exc:
        raise NetworkError(f"{p}: {_yaml_problem(exc)}") from None


def network_to_dict(net: Network) -> dict[str, Any]:
    """The YAML document of a network (used by the generator to write its cases)."""
    def rate(r: Fraction) -> int | float:
        return int(r) if r.denominator == 1 else float(r)

    return {
        "time_unit": net.time_unit,
        "store_and_forward": net.store_and_forward,
        "end_systems": list(net.end_systems),
        "switches": list(net.switches),
        "links": [{"between": sorted(k), "rate": rate(r)} for k, r in net.rates.items()],
        "flows": [{"name": f.name, "period": f.period, "size": f.size,
                   "path": [f.ports[0][0]] + [b for _, b in f.ports],
                   **({"offset": f.offset} if f.offset is not None else {})} for f in net.flows],
    }
