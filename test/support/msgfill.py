"""Deterministic, every-field-distinct instances of any ROS 2 message type, and deep comparison.

Why: the interface tests must prove that *every* field of every project message survives a
real DDS hop between processes. Filling by hand would miss fields added later; this walks the
rosidl type description (`SLOT_TYPES`) instead, so a new field is covered automatically.
Values depend only on (seed, field path), so two processes build identical messages without
talking; floats are multiples of 1/8 so float32 fields round-trip exactly.
"""

from __future__ import annotations

import hashlib
import importlib
from typing import Any

from rosidl_parser import definition as d

INT_RANGES = {
    "int8": (-128, 127), "uint8": (0, 255), "char": (0, 255), "octet": (0, 255),
    "int16": (-32768, 32767), "uint16": (0, 65535),
    "int32": (-(2**31), 2**31 - 1), "uint32": (0, 2**32 - 1),
    "int64": (-(2**63), 2**63 - 1), "uint64": (0, 2**64 - 1),
}
FLOAT_TYPES = {"float", "double", "long double"}


def _number(seed: int, path: str) -> int:
    digest = hashlib.sha256(f"{seed}:{path}".encode()).digest()
    return int.from_bytes(digest[:8], "little")


def message_class(namespaced: d.NamespacedType) -> type:
    """Import the Python class of a rosidl NamespacedType (e.g. geometry_msgs/msg/Point)."""
    module = importlib.import_module(".".join(namespaced.namespaces))
    return getattr(module, namespaced.name)


def _basic(typename: str, seed: int, path: str) -> Any:
    n = _number(seed, path)
    if typename == "boolean":
        return bool(n & 1)
    if typename in FLOAT_TYPES:
        return (n % 200001 - 100000) / 8.0  # exact in float32 and float64
    if typename in INT_RANGES:
        lo, hi = INT_RANGES[typename]
        return lo + n % (hi - lo + 1)
    raise TypeError(f"unsupported basic type {typename} at {path}")


def _value(slot: Any, seed: int, path: str) -> Any:
    if isinstance(slot, d.BasicType):
        value = _basic(slot.typename, seed, path)
        return bytes([value]) if slot.typename == "octet" else value
    if isinstance(slot, (d.UnboundedString, d.BoundedString, d.UnboundedWString, d.BoundedWString)):
        text = f"{path}#{seed}"
        limit = getattr(slot, "maximum_size", None)
        return text[: int(limit)] if limit else text
    if isinstance(slot, d.NamespacedType):
        return fill(message_class(slot), seed, path)
    if isinstance(slot, d.Array):
        return [_value(slot.value_type, seed, f"{path}[{i}]") for i in range(slot.size)]
    if isinstance(slot, (d.UnboundedSequence, d.BoundedSequence)):
        length = 2 + _number(seed, path + "#len") % 2
        if isinstance(slot, d.BoundedSequence):
            length = min(length, slot.maximum_size)
        return [_value(slot.value_type, seed, f"{path}[{i}]") for i in range(length)]
    raise TypeError(f"unsupported slot type {slot!r} at {path}")


def fill(cls: type, seed: int, path: str = "") -> Any:
    """Return an instance of message class `cls` with every field set from (seed, path)."""
    msg = cls()
    for name, slot in zip(cls.get_fields_and_field_types(), cls.SLOT_TYPES, strict=True):
        setattr(msg, name, _value(slot, seed, f"{path}.{name}"))
    return msg


def to_plain(value: Any) -> Any:
    """Message -> nested dict/list of plain Python values (arrays and numpy scalars unwrapped)."""
    if hasattr(value, "get_fields_and_field_types"):
        return {name: to_plain(getattr(value, name)) for name in value.get_fields_and_field_types()}
    if isinstance(value, (str, bytes, bool, int, float)):
        return value
    if hasattr(value, "tolist"):
        return to_plain(value.tolist())
    if isinstance(value, (list, tuple)) or hasattr(value, "__iter__"):
        return [to_plain(v) for v in value]
    return value


def leaf_paths(plain: Any, prefix: str = "") -> list[str]:
    """All leaf field paths of a `to_plain` tree (used to show how many fields were checked)."""
    if isinstance(plain, dict):
        return [p for k, v in plain.items() for p in leaf_paths(v, f"{prefix}.{k}")]
    if isinstance(plain, list):
        return [p for i, v in enumerate(plain) for p in leaf_paths(v, f"{prefix}[{i}]")]
    return [prefix]


def differences(expected: Any, actual: Any, prefix: str = "") -> list[str]:
    """Field paths where two `to_plain` trees differ, with both values."""
    if isinstance(expected, dict) and isinstance(actual, dict):
        keys = sorted(set(expected) | set(actual))
        return [p for k in keys for p in differences(expected.get(k), actual.get(k), f"{prefix}.{k}")]
    if isinstance(expected, list) and isinstance(actual, list):
        if len(expected) != len(actual):
            return [f"{prefix}: length {len(expected)} != {len(actual)}"]
        pairs = enumerate(zip(expected, actual, strict=True))
        return [p for i, (a, b) in pairs for p in differences(a, b, f"{prefix}[{i}]")]
    return [] if expected == actual else [f"{prefix}: expected {expected!r}, got {actual!r}"]


def interface_types(package: str) -> dict[str, type]:
    """All message and service classes of an installed interface package, by 'msg/Name'."""
    from ament_index_python.packages import get_resource

    content, _ = get_resource("rosidl_interfaces", package)
    result: dict[str, type] = {}
    for line in content.splitlines():
        rel = line.split(";")[0].strip()
        if rel.endswith((".msg", ".srv")) and "/" in rel:
            kind, file_name = rel.split("/", 1)
            name = file_name.rsplit(".", 1)[0]
            module = importlib.import_module(f"{package}.{kind}")
            result[f"{kind}/{name}"] = getattr(module, name)
    return dict(sorted(result.items()))
