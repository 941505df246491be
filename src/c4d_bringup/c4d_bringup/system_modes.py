"""System modes: which managed nodes are ACTIVE in each mission phase, and the lifecycle transitions
that get the graph there (ROS-free; docs/lifecycle.md).

The system YAML's optional `modes:` section names, per phase, the nodes that are active (`active:
[...]`) or the ones that are not (`inactive: [...]`); a phase not listed has every node active, as
has a YAML without the section (the graph before system modes). Every managed node is configured
at start whatever the phase; a phase change only activates and deactivates.

    modes:
      preflight: {inactive: [payload]}         # on the ground, disarmed
      flight: {}                               # armed, in the air (or taking off)
      landing: {inactive: [payload]}           # armed, landing (landed state LANDING or a land/RTL)
      maintenance: {active: [sim, perception, navigation, core, health, bridge, recorder]}

`maintenance` is never entered from the vehicle status: `c4d up --phase maintenance` pins it (the
operator's bench session). The phase of a vehicle status is `phase_of`; `plan` orders the
transitions (configure in start order, deactivate in reverse start order, activate in start order).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

PHASES = ("preflight", "flight", "landing", "maintenance")
STATUS_PHASES = ("preflight", "flight", "landing")  # the ones the vehicle status selects
# lifecycle_msgs/State primary state ids (kept here so this module needs no ROS)
UNCONFIGURED, INACTIVE, ACTIVE, FINALIZED = 1, 2, 3, 4
STATE_LABELS = {0: "unknown", UNCONFIGURED: "unconfigured", INACTIVE: "inactive", ACTIVE: "active", FINALIZED: "finalized"}
# VehicleStatus numbering (c4d_interfaces/msg/VehicleStatus)
LANDED_LANDING = 4
NAV_RTL, NAV_LAND = 5, 6


class ModesError(ValueError):
    """A modes section that cannot be used (one line, says where)."""


@dataclass(frozen=True)
class ModeTable:
    """Phase -> the managed nodes active in it (the rest of `nodes` inactive)."""

    nodes: tuple[str, ...]  # managed nodes in start order
    active: Mapping[str, frozenset[str]]

    def active_in(self, phase: str) -> frozenset[str]:
        return self.active.get(phase, frozenset(self.nodes))

    def describe(self) -> str:
        parts = []
        for phase in PHASES:
            off = [n for n in self.nodes if n not in self.active_in(phase)]
            parts.append(f"{phase}: all active" if not off else f"{phase}: {', '.join(off)} inactive")
        return "; ".join(parts)


def parse_modes(doc: Any, nodes: Sequence[str], where: str) -> ModeTable:
    """The `modes:` section (None: every node active in every phase); ModesError names the first problem."""
    if doc is None:
        return ModeTable(tuple(nodes), {})
    if not isinstance(doc, dict):
        raise ModesError(f"{where}: modes must be a mapping of phase -> {{active: [...]}} or {{inactive: [...]}}")
    known = set(nodes)
    table: dict[str, frozenset[str]] = {}
    for phase, entry in doc.items():
        if phase not in PHASES:
            raise ModesError(f"{where}: modes: unknown phase {phase!r} (phases: {', '.join(PHASES)})")
        entry = {} if entry is None else entry
        if not isinstance(entry, dict) or set(entry) - {"active", "inactive"} or len(entry) > 1:
            raise ModesError(f"{where}: modes.{phase}: give either 'active: [nodes]' or 'inactive: [nodes]'")
        if not entry:
            table[phase] = frozenset(nodes)
            continue
        key, listed = next(iter(entry.items()))
        if not isinstance(listed, list) or not all(isinstance(n, str) for n in listed):
            raise ModesError(f"{where}: modes.{phase}.{key} must be a list of node names")
        unknown = [n for n in listed if n not in known]
        if unknown:
            raise ModesError(f"{where}: modes.{phase}.{key}: unknown node {unknown[0]!r} (managed nodes: {', '.join(nodes)})")
        table[phase] = frozenset(listed) if key == "active" else frozenset(known - set(listed))
    return ModeTable(tuple(nodes), table)


def phase_of(armed: bool, landed_state: int, nav_state: int) -> str:
    """The mission phase a vehicle status says: preflight while disarmed, landing while armed and
    landing (landed state LANDING, or a land / return-to-launch in progress), flight otherwise."""
    if not armed:
        return "preflight"
    if landed_state == LANDED_LANDING or nav_state in (NAV_LAND, NAV_RTL):
        return "landing"
    return "flight"


@dataclass(frozen=True)
class Step:
    node: str
    transition: str  # configure | activate | deactivate

    def __str__(self) -> str:
        return f"{self.transition} {self.node}"


def plan(states: Mapping[str, int], want_active: Iterable[str], order: Sequence[str]) -> list[Step]:
    """Transitions from `states` (node -> primary state id) to: every node of `order` configured, those of
    `want_active` active, the rest inactive. Deactivations first (reverse start order: consumers before
    producers), then configure and activate in start order. Unknown / finalized nodes are left alone."""
    want = set(want_active)
    steps = [Step(n, "deactivate") for n in reversed(order) if states.get(n) == ACTIVE and n not in want]
    for n in order:
        state = states.get(n)
        if state == UNCONFIGURED:
            steps.append(Step(n, "configure"))
            state = INACTIVE
        if state == INACTIVE and n in want:
            steps.append(Step(n, "activate"))
    return steps


LOG_LINE = re.compile(r"^\[(?P<level>[A-Z]+)\] \[[0-9.]+\] \[(?P<node>[^\]]+)\]: (?P<text>.*)$")


def failure_reason(log_text: str, node: str) -> str | None:
    """The last `lifecycle: ... failed: ...` ERROR line node `node` logged (its reason), else its last ERROR line."""
    last_error = None
    for line in reversed(log_text.splitlines()):
        m = LOG_LINE.match(line.strip())
        if m is None or m["node"] != node or m["level"] not in ("ERROR", "FATAL"):
            continue
        if m["text"].startswith("lifecycle: ") and " failed: " in m["text"]:
            return m["text"].removeprefix("lifecycle: ")
        last_error = last_error or m["text"]
    return last_error


def read_reason(log_path: Path | None, node: str) -> str:
    """failure_reason of the node's log file, or a pointer to the file when there is none."""
    if log_path is None:
        return "no reason logged"
    try:
        text = log_path.read_text(errors="replace")[-200_000:]
    except OSError as exc:
        return f"no reason: cannot read {log_path}: {exc.strerror or exc}"
    return failure_reason(text, node) or f"no reason logged (see {log_path})"
