"""Live ROS parameters of a node: declared from a c4d_common.tunable table, validated on set,
applied at the owner's boundary, persisted per vehicle.

What: `LiveParameters(node, table, ...)` declares every tunable (descriptor: description with
unit, range), takes the start values (defaults, overridden by the launch's parameters, then by
the vehicle's stored changes), and from then on answers every set_parameters call: a batch is
checked as a whole (type, finite, range, the owner's cross-field rule, against the values in
force plus what is already queued) and refused with the reason in SetParametersResult, or
queued. The owner takes the queued changes where it is safe to apply them — the core in its
executive's latch (`take()`), an executor-driven node right away (`apply=` callback) — and
`applied()` hands the new values to the store (written off-thread).
Why: one mechanism for `ros2 param set`, rclpy SetParameters and the MAVLink bridge (which
calls the node's set_parameters service), so every route refuses for the same reason.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from rcl_interfaces.msg import SetParametersResult
from rclpy.parameter import Parameter

from c4d_common.tunable import DeferredWriter, PendingChanges, TunableTable, VehicleStore

from .params import ParameterError, Spec, declare


def specs(table: TunableTable) -> dict[str, Spec]:
    """The ROS parameter specs of a table: description with unit, range."""
    return {t.name: Spec(float(t.default), f"{t.description} [{t.unit}]", t.low, t.high) for t in table}


class LiveParameters:
    """See the module docstring. `log(text)` reports restores and store problems."""

    def __init__(self, node: Any, table: TunableTable, store: VehicleStore | None, log: Callable[[str], None],
                 apply: Callable[[dict[str, float]], None] | None = None) -> None:
        self.node, self.table, self.log, self.apply = node, table, log, apply
        self.writer = DeferredWriter(store, log) if store is not None else None
        values = {name: float(declare(node, name, spec)) for name, spec in specs(table).items()}
        reason = table.check(values, values)
        if reason:
            raise ParameterError(f"parameter {reason}")
        self.persisted: dict[str, float] = {}  # what the store holds: restored + changed since (not launch overrides)
        if store is not None:
            restored, problems = store.restore(table, values)
            for problem in problems:
                log(problem)
            if restored:
                node.set_parameters([Parameter(k, value=v) for k, v in restored.items()])
                values.update(restored)
                self.persisted = dict(restored)
                log(f"restored {len(restored)} parameter(s) from {store.path}: "
                    + ", ".join(f"{k}={v:g}" for k, v in sorted(restored.items())))
        self.pending = PendingChanges(table, values)
        node.add_on_set_parameters_callback(self._check)
        node.add_post_set_parameters_callback(self._queue)

    @property
    def values(self) -> dict[str, float]:
        """The values in force (applied)."""
        return dict(self.pending.values)

    def _tunables(self, params: list[Parameter]) -> dict[str, Any]:
        return {p.name: p.value for p in params if p.name in self.table}

    def _check(self, params: list[Parameter]) -> SetParametersResult:
        changes = self._tunables(params)
        if not changes:
            return SetParametersResult(successful=True)
        reason = self.pending.table.check(changes, {**self.pending.values, **self.pending.queued})
        return SetParametersResult(successful=not reason, reason=reason)

    def _queue(self, params: list[Parameter]) -> None:
        changes = self._tunables(params)
        if changes and not self.pending.submit(changes) and self.apply is not None:
            self.apply(self.take())

    def take(self) -> dict[str, float]:
        """The queued changes, now in force (empty: none); the store is updated off-thread."""
        changes = self.pending.take()
        if changes and self.writer is not None:
            self.persisted.update(changes)
            self.writer.submit(self.persisted)
        return changes

    def flush(self) -> None:
        if self.writer is not None:
            self.writer.flush()


def describe(changes: Mapping[str, float]) -> str:
    return ", ".join(f"{k}={v:g}" for k, v in sorted(changes.items()))
