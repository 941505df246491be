"""Static schedule of a cyclic executive: tasks from YAML → dividers, phases and in-tick order.

What: every task runs every `divider` ticks (rate = tick rate / divider) at tick indices
k ≡ phase (mod divider). Phases are explicit or `auto`: then GCD+ (or the `paparazzi` / `zero`
methods kept for comparison) chooses offsets O_i in µs for periods T_i = divider·tick and
WCETs C_i = budget, and phase = ⌊O_i / tick⌋ mod divider; `optimal` solves for the phases that
minimise the worst per-tick budget sum exactly (CP-SAT, optimal.py, within
`optimal_time_limit_s`, warm-started with GCD+; no answer in time → GCD+ and a `warning`).
Inside a tick, due tasks run in the fixed group order input → estimation → guidance → control
→ actuators → telemetry → default, then by precedence depth (producers first), then by O_i mod
tick, then by chain position and name. Equal-divider `chains` (e.g. estimate → control → mix)
are scheduled as one task (budget = sum) so they always share a tick. `precedence` lists
multi-rate SPC edges (precedence.py): every method's phases meet them (heuristics through
`PhaseSystem.repair`, the exact model as constraints); an unsatisfiable set is a config error.
Why: the same phasing science as for links (thesis ch. 3) makes per-tick load smooth, which is
what keeps a 500 Hz executive free of overruns when slow, heavy tasks are added.

YAML (the `executive:` mapping of a core config):
    tick_hz: 500                 # main tick, 1e6 / tick_hz must be an integer number of µs
    phase_method: gcdplus        # gcdplus | optimal | paparazzi | zero
    optimal_time_limit_s: 2.0    # optimal: solver time limit at start
    tasks:
      - {name: rate_control, group: control, rate_hz: 500, budget_us: 120}
      - {name: telemetry, group: telemetry, divider: 50, budget_us: 300, phase: auto}
    chains: [[state_update, rate_control, mixer]]
    precedence:                  # producer, consumer, w_p, w_c, M0 (weights default to the
      - {producer: attitude_control, consumer: rate_control, m0: 1}   # balanced ones, M0 to 0)
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from .arith import gcd_all
from .fifo import cycle_loads
from .gcdplus import ORDER_VARIANTS, GcdPlusResult, run_order
from .methods import assign
from .model import Assignment, Task, TaskSet
from .precedence import Constraint, Edge, PhaseSystem, PrecedenceError, balanced_weights, build_constraints, in_tick_depth

GROUPS = ("input", "estimation", "guidance", "control", "actuators", "telemetry", "default")
PHASE_METHODS = ("gcdplus", "optimal", "paparazzi", "zero")
DEFAULT_OPTIMAL_TIME_LIMIT_S = 2.0


class ScheduleConfigError(ValueError):
    """Invalid executive configuration; one line naming the offending field."""


@dataclass(frozen=True)
class TaskSpec:
    name: str
    group: str
    divider: int
    budget_us: int
    phase: int | None = None  # None = auto


@dataclass(frozen=True)
class ScheduledTask:
    name: str
    group: str
    divider: int
    phase: int
    order: int
    offset_us: int
    budget_us: int


@dataclass(frozen=True)
class TickSchedule:
    tick_us: int
    method: str
    order_variant: str
    omega_us: int
    sum_delta_us: int
    certificate: bool
    certificate_reason: str
    max_tick_load_us: int
    tasks: tuple[ScheduledTask, ...]  # in execution order within a tick
    optimality: str = ""  # optimal method: "optimal" (proven) | "feasible" (time limit hit); "" otherwise
    lower_bound_us: int = 0  # optimal method: proven lower bound on the worst tick budget sum
    solver_s: float = 0.0  # optimal method: solver wall time
    warning: str = ""  # one line when the requested method could not be honoured (fallback used)
    precedence: tuple[Edge, ...] = ()

    @property
    def tick_hz(self) -> float:
        return 1e6 / self.tick_us

    def due(self, tick: int) -> list[ScheduledTask]:
        return [t for t in self.tasks if tick % t.divider == t.phase]


def _field(item: Mapping[str, Any], key: str, where: str, kind: type = int, required: bool = True) -> Any:
    if key not in item:
        if required:
            raise ScheduleConfigError(f"{where}: missing field '{key}'")
        return None
    value = item[key]
    if kind is int and (isinstance(value, bool) or not isinstance(value, int)):
        raise ScheduleConfigError(f"{where}: field '{key}' must be an integer, got {value!r}")
    if kind is str and not isinstance(value, str):
        raise ScheduleConfigError(f"{where}: field '{key}' must be a string, got {value!r}")
    return value


def parse_config(doc: object) -> tuple[int, str, list[TaskSpec], list[list[str]]]:
    """Validate an `executive:` mapping; return (tick_us, method, task specs, chains)."""
    if not isinstance(doc, Mapping):
        raise ScheduleConfigError("executive: must be a mapping")
    unknown = set(doc) - {"tick_hz", "phase_method", "tasks", "chains", "name", "report_period_s", "precedence",
                          "optimal_time_limit_s"}
    if unknown:
        raise ScheduleConfigError(f"executive: unknown field(s) {', '.join(sorted(unknown))}")
    tick_hz = doc.get("tick_hz", 500)
    if isinstance(tick_hz, bool) or not isinstance(tick_hz, int) or tick_hz <= 0 or 1_000_000 % tick_hz:
        raise ScheduleConfigError(f"executive.tick_hz must be a positive integer dividing 1000000, got {tick_hz!r}")
    tick_us = 1_000_000 // tick_hz
    method = doc.get("phase_method", "gcdplus")
    if method not in PHASE_METHODS:
        raise ScheduleConfigError(f"executive.phase_method must be one of {', '.join(PHASE_METHODS)}, got {method!r}")
    items = doc.get("tasks")
    if not isinstance(items, list) or not items:
        raise ScheduleConfigError("executive.tasks must be a non-empty list")
    specs: list[TaskSpec] = []
    for k, item in enumerate(items):
        where = f"executive.tasks[{k}]"
        if not isinstance(item, Mapping):
            raise ScheduleConfigError(f"{where}: must be a mapping")
        extra = set(item) - {"name", "group", "rate_hz", "divider", "budget_us", "phase"}
        if extra:
            raise ScheduleConfigError(f"{where}: unknown field(s) {', '.join(sorted(extra))}")
        name = _field(item, "name", where, str)
        where = f"executive task '{name}'"
        group = item.get("group", "default")
        if group not in GROUPS:
            raise ScheduleConfigError(f"{where}: unknown group '{group}' (groups: {', '.join(GROUPS)})")
        if ("rate_hz" in item) == ("divider" in item):
            raise ScheduleConfigError(f"{where}: give exactly one of 'rate_hz' or 'divider'")
        if "divider" in item:
            divider = _field(item, "divider", where)
            if divider <= 0:
                raise ScheduleConfigError(f"{where}: field 'divider' must be positive")
        else:
            rate = item["rate_hz"]
            if isinstance(rate, bool) or not isinstance(rate, (int, float)) or rate <= 0:
                raise ScheduleConfigError(f"{where}: field 'rate_hz' must be a positive number")
            divider = round(tick_hz / rate)
            if divider < 1 or abs(divider * rate - tick_hz) > 1e-9 * tick_hz:
                raise ScheduleConfigError(f"{where}: rate_hz {rate} does not divide the tick rate {tick_hz} Hz")
        budget = _field(item, "budget_us", where)
        if budget <= 0 or budget > tick_us:
            raise ScheduleConfigError(f"{where}: budget_us {budget} must be in 1..{tick_us} (one tick)")
        phase = item.get("phase", "auto")
        if phase != "auto":
            if isinstance(phase, bool) or not isinstance(phase, int) or not 0 <= phase < divider:
                raise ScheduleConfigError(f"{where}: phase must be 'auto' or an integer in 0..{divider - 1}")
        if any(s.name == name for s in specs):
            raise ScheduleConfigError(f"{where}: defined twice")
        specs.append(TaskSpec(name, group, divider, budget, None if phase == "auto" else phase))
    chains = doc.get("chains") or []
    by_name = {s.name: s for s in specs}
    seen: set[str] = set()
    for chain in chains:
        if not isinstance(chain, list) or len(chain) < 2:
            raise ScheduleConfigError("executive.chains: each chain must be a list of at least two task names")
        for name in chain:
            if name not in by_name:
                raise ScheduleConfigError(f"executive.chains: unknown task '{name}'")
            if name in seen:
                raise ScheduleConfigError(f"executive.chains: task '{name}' is in two chains")
            seen.add(name)
        if len({by_name[n].divider for n in chain}) != 1:
            raise ScheduleConfigError(f"executive.chains: {chain} must share one divider")
        if len({by_name[n].phase for n in chain}) != 1:
            raise ScheduleConfigError(f"executive.chains: {chain} must all be 'auto' or share one phase")
        if sum(by_name[n].budget_us for n in chain) > tick_us:
            raise ScheduleConfigError(f"executive.chains: {chain} budgets exceed one tick")
    return tick_us, method, specs, [list(c) for c in chains]


def parse_precedence(doc: Mapping[str, Any], specs: Sequence[TaskSpec]) -> tuple[Edge, ...]:
    """The `precedence:` list of an executive mapping: {producer, consumer, w_p, w_c, m0} mappings
    (w_p, w_c default to the balanced weights of the two dividers, m0 to 0)."""
    items = doc.get("precedence") or []
    if not isinstance(items, list):
        raise ScheduleConfigError("executive.precedence must be a list of {producer, consumer, w_p, w_c, m0}")
    dividers = {s.name: s.divider for s in specs}
    edges = []
    for k, item in enumerate(items):
        where = f"executive.precedence[{k}]"
        if not isinstance(item, Mapping):
            raise ScheduleConfigError(f"{where}: must be a mapping {{producer, consumer, w_p, w_c, m0}}")
        extra = set(item) - {"producer", "consumer", "w_p", "w_c", "m0"}
        if extra:
            raise ScheduleConfigError(f"{where}: unknown field(s) {', '.join(sorted(extra))}")
        producer, consumer = _field(item, "producer", where, str), _field(item, "consumer", where, str)
        for name in (producer, consumer):
            if name not in dividers:
                raise ScheduleConfigError(f"{where}: unknown task '{name}'")
        w_p, w_c = balanced_weights(dividers[producer], dividers[consumer])
        edge = Edge(producer, consumer, item.get("w_p", w_p), item.get("w_c", w_c), item.get("m0", 0))
        try:
            build_constraints([edge], {producer: 0, consumer: 1}, [dividers[producer], dividers[consumer]])
        except PrecedenceError as exc:
            raise ScheduleConfigError(f"{where}: {exc}") from None
        edges.append(edge)
    return tuple(edges)


def parse_time_limit(doc: Mapping[str, Any]) -> float:
    value = doc.get("optimal_time_limit_s", DEFAULT_OPTIMAL_TIME_LIMIT_S)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0 or value == float("inf"):
        raise ScheduleConfigError(f"executive.optimal_time_limit_s must be a positive number of seconds, got {value!r}")
    return float(value)


Repair = Callable[[list[int]], list[int]]


def _best_gcdplus_for_ticks(taskset: TaskSet, tick_us: int, repair: Repair | None = None) -> Assignment:
    """GCD+ for an executive: every order variant, keep the one whose phases give the lowest
    worst per-tick budget sum, certified variants first (the tick, not the FIFO delay, is what
    an executive overruns). `repair` moves phases (in ticks) to meet precedence edges; a
    repaired task's offset becomes phase·tick."""
    best = None
    for position, order in enumerate(ORDER_VARIANTS):
        result = run_order(taskset, order)
        phases = [(o // tick_us) % (t.period // tick_us) * tick_us for o, t in zip(result.offsets, taskset.tasks, strict=True)]
        if repair is not None:
            before = [p // tick_us for p in phases]
            moved = repair(before)
            if moved != before:
                offsets = tuple(o if a == m else m * tick_us for o, a, m in zip(result.offsets, before, moved, strict=True))
                phases = [m * tick_us for m in moved]
                result = GcdPlusResult(**{**result.__dict__, "certificate": False, "placements": tuple(
                    pl._replace(offset=o) for pl, o in zip(result.placements, offsets, strict=True))})
        worst = int(cycle_loads(taskset.periods, taskset.wcets, phases, cycle=tick_us)[1].max())
        key = (not result.certificate, worst, position)
        if best is None or key < best[0]:
            best = (key, result)
    assert best is not None
    result = best[1]
    return Assignment("gcdplus", result.offsets, result, f"order {result.order} (lowest worst tick load)")


def build_schedule(tick_us: int, method: str, specs: Sequence[TaskSpec], chains: Sequence[Sequence[str]] = (),
                   precedence: Sequence[Edge] = (), time_limit_s: float = DEFAULT_OPTIMAL_TIME_LIMIT_S) -> TickSchedule:
    """Phases and in-tick order for `specs` (see module docstring)."""
    chain_of = {name: tuple(chain) for chain in chains for name in chain}
    units: dict[str, list[TaskSpec]] = {}  # scheduling unit (chain head or task) -> members
    for spec in specs:
        head = chain_of.get(spec.name, (spec.name,))[0]
        units.setdefault(head, []).append(spec)
    heads = list(units)
    unit_of = {spec.name: heads.index(chain_of.get(spec.name, (spec.name,))[0]) for spec in specs}
    by_name = {spec.name: spec for spec in specs}
    # in-tick order: group, then precedence depth (chain links and edges inside one group)
    links = [(a, b) for chain in chains for a, b in zip(chain, chain[1:], strict=False)]
    links += [(e.producer, e.consumer) for e in precedence]
    depth = in_tick_depth([s.name for s in specs], [(a, b) for a, b in links if by_name[a].group == by_name[b].group])
    rank = {s.name: (GROUPS.index(s.group), depth[s.name]) for s in specs}
    first = {(e.producer, e.consumer): rank[e.producer] < rank[e.consumer] for e in precedence}
    dividers = [units[h][0].divider for h in heads]
    fixed = {i: units[h][0].phase for i, h in enumerate(heads) if units[h][0].phase is not None}
    try:
        constraints = build_constraints(precedence, unit_of, dividers, first)
        system = PhaseSystem(heads, dividers, constraints, {i: p for i, p in fixed.items() if p is not None})
        system.check()
    except PrecedenceError as exc:
        raise ScheduleConfigError(str(exc)) from None
    auto = [h for h in heads if units[h][0].phase is None]
    auto_index = [heads.index(h) for h in auto]
    budgets = [sum(m.budget_us for m in units[h]) for h in heads]

    def repair(auto_phases: list[int]) -> list[int]:
        full = [units[h][0].phase or 0 for h in heads]
        for i, p in zip(auto_index, auto_phases, strict=True):
            full[i] = p
        fixed_full = system.repair(full, budgets)
        return [fixed_full[i] for i in auto_index]

    offsets: dict[str, int] = {}
    variant, omega, sum_delta, certificate, reason = "", 0, 0, True, "no auto-phased tasks"
    optimality, bound, solver_s, warning = "", 0, 0.0, ""
    if auto:
        taskset = TaskSet(tuple(
            Task(head, units[head][0].divider * tick_us, sum(m.budget_us for m in units[head])) for head in auto
        ), unit="us")
        if method in ("gcdplus", "optimal"):
            assignment = _best_gcdplus_for_ticks(taskset, tick_us, repair if constraints else None)
        else:
            assignment = assign(taskset, method)
            phases = [(o // tick_us) % (t.period // tick_us) for o, t in zip(assignment.offsets, taskset.tasks, strict=True)]
            moved = repair(phases) if constraints else phases
            assignment = Assignment(method, tuple(o if a == m else m * tick_us for o, a, m in
                                                  zip(assignment.offsets, phases, moved, strict=True)))
        offsets = dict(zip(auto, assignment.offsets, strict=True))
        detail = assignment.detail
        if isinstance(detail, GcdPlusResult):
            variant, omega, sum_delta = detail.order, detail.omega, detail.sum_delta
            certificate, reason = detail.certificate, detail.certificate_reason
            if constraints and not certificate and detail.max_wcet <= omega and sum_delta <= omega:
                reason = "no zero-interference guarantee: precedence moved GCD+ phases"
        else:
            omega = gcd_all(t.period for t in taskset.tasks)
            certificate, reason = False, f"method {method} gives no certificate"
        if method == "optimal":
            offsets, optimality, bound, solver_s, warning = _optimal_offsets(
                heads, units, offsets, tick_us, constraints, fixed, time_limit_s)
            if not warning:
                variant, certificate = "", False
                reason = (f"worst tick budget sum {'proven optimal' if optimality == 'optimal' else 'best found'}, "
                          f"lower bound {bound} µs (CP-SAT, {solver_s:.2f} s)")
            else:
                method = "gcdplus"
    for head, members in units.items():
        if members[0].phase is not None:
            offsets[head] = members[0].phase * tick_us
    position = {name: i for chain in chains for i, name in enumerate(chain)}
    rows = []
    for spec in specs:
        head = chain_of.get(spec.name, (spec.name,))[0]
        offset = offsets[head]
        phase = (offset // tick_us) % spec.divider
        key = (*rank[spec.name], offset % tick_us, position.get(spec.name, 0), spec.name)
        rows.append((key, spec, phase, offset))
    rows.sort(key=lambda r: r[0])
    tasks = tuple(
        ScheduledTask(spec.name, spec.group, spec.divider, phase, order, offset, spec.budget_us)
        for order, (_, spec, phase, offset) in enumerate(rows)
    )
    _, loads = cycle_loads([t.divider * tick_us for t in tasks], [t.budget_us for t in tasks],
                           [t.phase * tick_us for t in tasks], cycle=tick_us)
    return TickSchedule(tick_us, method, variant, omega, sum_delta, certificate, reason, int(loads.max()), tasks,
                        optimality, bound, solver_s, warning, tuple(precedence))


def _optimal_offsets(heads: Sequence[str], units: Mapping[str, Sequence[TaskSpec]], hint_offsets: Mapping[str, int],
                     tick_us: int, constraints: Sequence[Constraint], fixed: Mapping[int, int | None],
                     time_limit_s: float) -> tuple[dict[str, int], str, int, float, str]:
    """Exact phases (optimal.py) warm-started with GCD+'s; (offsets, status, bound, seconds, warning)."""
    from .optimal import SolverInputError, solve_executive  # local: OR-Tools loads only for this method

    dividers = [units[h][0].divider for h in heads]
    budgets = [sum(m.budget_us for m in units[h]) for h in heads]
    hint = [(hint_offsets[h] // tick_us) % d if h in hint_offsets else (fixed.get(i) or 0)
            for i, (h, d) in enumerate(zip(heads, dividers, strict=True))]
    pinned = {i: p for i, p in fixed.items() if p is not None}
    try:
        solution = solve_executive(dividers, budgets, constraints, pinned, time_limit_s, hint)
    except SolverInputError as exc:
        return dict(hint_offsets), "", 0, 0.0, f"phase_method optimal: {exc}; using GCD+"
    if solution.phases is None:
        return (dict(hint_offsets), "", solution.bound, solution.wall_s,
                f"phase_method optimal: no solution within {time_limit_s:g} s ({solution.status.value}); using GCD+")
    offsets = {h: solution.phases[i] * tick_us for i, h in enumerate(heads) if h in hint_offsets}
    return offsets, solution.status.value, solution.bound, solution.wall_s, ""


def schedule_from_config(doc: object, method_override: str | None = None) -> TickSchedule:
    tick_us, method, specs, chains = parse_config(doc)
    assert isinstance(doc, Mapping)  # parse_config checked it
    if method_override is not None:
        if method_override not in PHASE_METHODS:
            raise ScheduleConfigError(f"phase method must be one of {', '.join(PHASE_METHODS)}")
        method = method_override
    return build_schedule(tick_us, method, specs, chains, parse_precedence(doc, specs), parse_time_limit(doc))
