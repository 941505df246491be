"""Declared ROS parameters with descriptors: description with unit, range, read-only.

Every c4d node declares its parameters through `declare()`. rclpy then enforces the range
both for the start value (overrides from the system YAML or `--ros-args -p`) and for later
`ros2 param set` / SetParameters calls, and `ros2 param describe` documents them. An
out-of-range start value raises `ParameterError` with one line naming the parameter; a node's
`main()` turns it into `node_runtime.fail()` (exit 2).

Every parameter reports the value in force, so `ros2 param get` / `ros2 param dump` document a
running vehicle (issue 14): a parameter whose empty start value means "the bundled file" names
its fallback in `Spec.empty` and is declared with the file's path; a parameter whose value comes
from a configuration file's content (the core's `airframe`, `phase_method`) is declared through
a `Declaration`, which the node settles with the merged values once it has read its file.
Read-only parameters get their read-only descriptor only after that (rclpy's `set_descriptor`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.parameter import Parameter


class ParameterError(ValueError):
    """A parameter's start value is unusable; the text is one line naming the parameter."""


@dataclass(frozen=True)
class Spec:
    """One parameter: default value, description (say the unit), optional [low, high] range."""

    default: Any
    description: str
    low: float | None = None
    high: float | None = None
    read_only: bool = False  # a change needs a restart
    empty: Callable[[], Any] | None = None  # the value in force when the start value is empty, e.g. the bundled file

    def descriptor(self) -> ParameterDescriptor:
        d = ParameterDescriptor(description=self.description, read_only=self.read_only)
        if self.low is not None and self.high is not None:
            if isinstance(self.default, bool):
                pass
            elif isinstance(self.default, int):
                d.integer_range = [IntegerRange(from_value=int(self.low), to_value=int(self.high), step=0)]
            elif isinstance(self.default, float):
                d.floating_point_range = [FloatingPointRange(from_value=float(self.low), to_value=float(self.high), step=0.0)]
        return d


def declare(node: Any, name: str, spec: Spec) -> Any:
    """Declare `name` with `spec` on `node` and return the value in force (default, file or
    command line; an empty one replaced by `spec.empty()`). Raises ParameterError naming the
    parameter when the value is refused."""
    if spec.empty is None:
        return _declare(node, name, spec)
    start = _declare(node, name, replace(spec, read_only=False))
    value = effective_value(spec, start)
    if value != start:
        _set(node, name, value)
    if spec.read_only:
        _make_read_only(node, name, spec)
    return value


def declare_all(node: Any, specs: dict[str, Spec]) -> dict[str, Any]:
    """Declare every parameter of `specs`; returns {name: value in force}."""
    return {name: declare(node, name, spec) for name, spec in specs.items()}


def effective_value(spec: Spec, start: Any) -> Any:
    """The value in force for a start value: `spec.empty()` when the start value is empty ('' or
    an empty list, or [''], the typed stand-in for an empty string list), else the start value."""
    if spec.empty is None or start not in ("", [], [""]):
        return start
    value = spec.empty()
    return str(value) if isinstance(spec.default, str) else value


class Declaration:
    """Parameters declared with their start values but not final yet: the node reads its
    configuration file with `values`, then `settle()` sets the merged values in force and only
    then marks the read-only ones read-only. Why: a parameter such as the core's `phase_method`
    ('' = the config file's) must report what the node runs with, not the empty override slot."""

    def __init__(self, node: Any, specs: dict[str, Spec]) -> None:
        self.node, self.specs = node, specs
        self.values = {name: declare(node, name, replace(spec, read_only=False)) for name, spec in specs.items()}

    def settle(self, effective: Mapping[str, Any]) -> dict[str, Any]:
        """Set each parameter named in `effective` to its value there, make the read-only ones
        read-only; returns {name: value in force}. A value the descriptor refuses: ParameterError."""
        unknown = set(effective) - set(self.specs)
        if unknown:
            raise ParameterError(f"parameter '{sorted(unknown)[0]}': not declared")
        for name, value in effective.items():
            if value != self.values[name]:
                _set(self.node, name, value)
                self.values[name] = value
        for name, spec in self.specs.items():
            if spec.read_only:
                _make_read_only(self.node, name, spec)
        return dict(self.values)


def _declare(node: Any, name: str, spec: Spec) -> Any:
    try:
        return node.declare_parameter(name, spec.default, spec.descriptor()).value
    except InvalidParameterValueException as exc:
        value = getattr(node, "_parameter_overrides", {}).get(name)  # rclpy keeps the start value only here
        shown = value.value if value is not None else "?"
        raise ParameterError(f"parameter '{name}': {_reason(exc, spec, shown)}") from None
    except InvalidParameterTypeException:
        raise ParameterError(f"parameter '{name}': expected {type(spec.default).__name__}") from None


def _set(node: Any, name: str, value: Any) -> None:
    result = node.set_parameters([Parameter(name, value=value)])[0]
    if not result.successful:
        raise ParameterError(f"parameter '{name}': value in force {value!r} refused ({result.reason})")


def _make_read_only(node: Any, name: str, spec: Spec) -> None:
    descriptor = spec.descriptor()
    descriptor.type = node.describe_parameter(name).type  # the type rclpy inferred at declaration
    node.set_descriptor(name, descriptor)


def _reason(exc: InvalidParameterValueException, spec: Spec, value: Any) -> str:
    if spec.low is not None and spec.high is not None:
        return f"{value!r} is outside [{spec.low:g}, {spec.high:g}]"
    return f"{value!r} refused ({exc})"
