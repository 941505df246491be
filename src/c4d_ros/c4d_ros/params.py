"""Declared ROS parameters with descriptors: description with unit, range, read-only.

Every c4d node declares its parameters through `declare()`. rclpy then enforces the range
both for the start value (overrides from the system YAML or `--ros-args -p`) and for later
`ros2 param set` / SetParameters calls, and `ros2 param describe` documents them. An
out-of-range start value raises `ParameterError` with one line naming the parameter; a node's
`main()` turns it into `node_runtime.fail()` (exit 2).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException


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
    command line). Raises ParameterError naming the parameter when the value is refused."""
    try:
        return node.declare_parameter(name, spec.default, spec.descriptor()).value
    except InvalidParameterValueException as exc:
        value = getattr(node, "_parameter_overrides", {}).get(name)  # rclpy keeps the start value only here
        shown = value.value if value is not None else "?"
        raise ParameterError(f"parameter '{name}': {_reason(exc, spec, shown)}") from None
    except InvalidParameterTypeException:
        raise ParameterError(f"parameter '{name}': expected {type(spec.default).__name__}") from None


def declare_all(node: Any, specs: dict[str, Spec]) -> dict[str, Any]:
    """Declare every parameter of `specs`; returns {name: value in force}."""
    return {name: declare(node, name, spec) for name, spec in specs.items()}


def _reason(exc: InvalidParameterValueException, spec: Spec, value: Any) -> str:
    if spec.low is not None and spec.high is not None:
        return f"{value!r} is outside [{spec.low:g}, {spec.high:g}]"
    return f"{value!r} refused ({exc})"
