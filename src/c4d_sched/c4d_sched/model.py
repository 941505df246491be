"""Task model for offset assignment: periodic tasks (or messages) and precedence chains.

A task is released every `period` time units starting at its `offset` and needs `wcet` units
of a single non-preemptive resource (a cyclic executive's CPU, or a FIFO link). All values
are positive integers in one time unit chosen by the caller (µs for executives, bit times for
serial links) so that every computation is exact. Validation errors are `TaskSetError`s with a
one-line message suitable for a CLI.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field


class TaskSetError(ValueError):
    """An invalid task set; the message is one line that names the offending task."""


@dataclass(frozen=True)
class Task:
    """A periodic task: released at offset + k·period, runs wcet units (thesis τ_i = (T_i, C_i, O_i))."""

    name: str
    period: int
    wcet: int
    offset: int | None = None


@dataclass(frozen=True)
class Chain:
    """Equal-period precedence chain (thesis §3.4): each task starts at least `separation`
    time units after the previous one ends (τ_a ≺^X τ_b for consecutive names)."""

    tasks: tuple[str, ...]
    separation: int = 0


@dataclass(frozen=True)
class TaskSet:
    """Tasks (in the caller's order, which baselines such as Paparazzi's depend on) + chains."""

    tasks: tuple[Task, ...]
    chains: tuple[Chain, ...] = ()
    unit: str = "unit"
    names: tuple[str, ...] = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "names", tuple(t.name for t in self.tasks))
        validate(self)

    @property
    def periods(self) -> list[int]:
        return [t.period for t in self.tasks]

    @property
    def wcets(self) -> list[int]:
        return [t.wcet for t in self.tasks]

    @property
    def utilisation(self) -> float:
        return sum(t.wcet / t.period for t in self.tasks)

    def index(self, name: str) -> int:
        return self.names.index(name)

    @classmethod
    def from_pairs(cls, pairs: Sequence[tuple[int, int]], unit: str = "unit") -> TaskSet:
        """Tasks τ1..τn from (period, wcet) pairs, named t1..tn."""
        return cls(tuple(Task(f"t{i + 1}", int(p), int(c)) for i, (p, c) in enumerate(pairs)), unit=unit)


def _positive_int(value: object, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise TaskSetError(f"{what} must be a positive integer, got {value!r}")
    if value <= 0:
        raise TaskSetError(f"{what} must be a positive integer, got {value}")
    return value


def validate(taskset: TaskSet) -> None:
    """Raise TaskSetError unless the set is usable: non-empty, integer T ≥ C > 0, unique
    names, offsets ≥ 0, chains of existing equal-period tasks with a separation ≥ 0."""
    if not taskset.tasks:
        raise TaskSetError("the task set is empty")
    seen: set[str] = set()
    for task in taskset.tasks:
        if not isinstance(task.name, str) or not task.name:
            raise TaskSetError(f"task name must be a non-empty string, got {task.name!r}")
        if task.name in seen:
            raise TaskSetError(f"task '{task.name}' is defined twice")
        seen.add(task.name)
        _positive_int(task.period, f"task '{task.name}': period")
        _positive_int(task.wcet, f"task '{task.name}': wcet")
        if task.wcet > task.period:
            raise TaskSetError(f"task '{task.name}': wcet {task.wcet} exceeds its period {task.period}")
        if task.offset is not None and (
            isinstance(task.offset, bool) or not isinstance(task.offset, int) or task.offset < 0
        ):
            raise TaskSetError(f"task '{task.name}': offset must be an integer >= 0, got {task.offset!r}")
    chained: set[str] = set()
    for chain in taskset.chains:
        if len(chain.tasks) < 2:
            raise TaskSetError(f"chain {list(chain.tasks)} needs at least two tasks")
        if isinstance(chain.separation, bool) or not isinstance(chain.separation, int) or chain.separation < 0:
            raise TaskSetError(f"chain {list(chain.tasks)}: separation must be an integer >= 0")
        periods = set()
        for name in chain.tasks:
            if name not in seen:
                raise TaskSetError(f"chain {list(chain.tasks)}: unknown task '{name}'")
            if name in chained:
                raise TaskSetError(f"task '{name}' appears in more than one chain position")
            chained.add(name)
            periods.add(taskset.tasks[taskset.names.index(name)].period)
        if len(periods) != 1:
            raise TaskSetError(f"chain {list(chain.tasks)}: precedence needs equal periods, got {sorted(periods)}")


@dataclass(frozen=True)
class Assignment:
    """Offsets chosen by one method for a task set, in task order; `detail` is method-specific
    (a GcdPlusResult for GCD+), `note` a one-line remark (e.g. which GCD+ order won)."""

    method: str
    offsets: tuple[int, ...]
    detail: object | None = None
    note: str = ""
