"""Full message definitions in the rosbag2 layout (MCAP schema encoding `ros2msg`).

Why: `ros2 bag`, Foxglove and `rosbags` decode a recording from the schema text stored in the
file, not from the reader's installed packages, so the text must be exactly what rosbag2's
LocalMessageDefinitionSource writes: the root `.msg` file as installed, then every dependency
once, depth first in sorted order, each as "\\n" + 80 "=" + "\\nMSG: <name as written>\\n" + its
`.msg` text. Dependencies are the non-primitive field types found by the same regular
expression rosbag2 uses; a bare type name belongs to the referring package.

The `.msg` files are found through the ament index (share/<pkg>/msg/<Type>.msg), which covers
the PyPI wheels, a standard /opt/ros install and this workspace's install/ overlay.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

DELIMITER = "=" * 80 + "\n"
_FIELD_TYPE = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")
_PRIMITIVES = frozenset({"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16",
                         "int32", "uint32", "int64", "uint64", "string"})
_NAME = r"[a-zA-Z][a-zA-Z0-9_]*"
_TYPE_NAME = re.compile(rf"^({_NAME})/(?:({_NAME})/)?({_NAME})$")


class DefinitionError(LookupError):
    """A message type whose definition cannot be found or understood."""


def split_type(type_name: str) -> tuple[str, str, str]:
    """'pkg/msg/Type' or 'pkg/Type' -> (pkg, 'msg', Type)."""
    match = _TYPE_NAME.match(type_name)
    if not match:
        raise DefinitionError(f"message type name not understood: {type_name!r}")
    package, namespace, name = match.groups()
    return package, namespace or "msg", name


def dependencies(text: str, package: str) -> list[str]:
    """Non-primitive field types of a .msg text, qualified with `package` when bare, sorted."""
    found = set()
    for match in _FIELD_TYPE.finditer(text):
        type_name = match.group(1)
        if type_name in _PRIMITIVES:
            continue
        found.add(type_name if "/" in type_name else f"{package}/{type_name}")
    return sorted(found)


def ament_msg_file(type_name: str) -> Path:
    """Installed .msg file of a type, via the ament index."""
    from ament_index_python.packages import PackageNotFoundError, get_package_share_directory

    package, namespace, name = split_type(type_name)
    try:
        share = Path(get_package_share_directory(package))
    except (PackageNotFoundError, ValueError):
        raise DefinitionError(f"unknown message type {type_name}: package {package!r} is not installed") from None
    path = share / namespace / f"{name}.msg"
    if not path.is_file():
        raise DefinitionError(f"unknown message type {type_name}: no {path}")
    return path


def full_text(type_name: str, read: Callable[[str], str] | None = None) -> str:
    """The rosbag2 `ros2msg` schema text of `type_name` ('pkg/msg/Type')."""
    read = read or (lambda name: ament_msg_file(name).read_text())
    seen: set[str] = set()

    def append(name: str, depth: int) -> str:
        if depth <= 0:
            raise DefinitionError(f"definition of {type_name} nests too deeply")
        text = read(name)
        result = text
        for dep in dependencies(text, split_type(name)[0]):
            if dep not in seen:
                seen.add(dep)
                result += "\n" + DELIMITER + f"MSG: {dep}\n" + append(dep, depth - 1)
        return result

    return append(type_name, 50)


class DefinitionCache:
    """full_text() memoised per type (recording opens a file per flight with the same types)."""

    def __init__(self) -> None:
        self._texts: dict[str, str] = {}

    def get(self, type_name: str) -> str:
        if type_name not in self._texts:
            self._texts[type_name] = full_text(type_name)
        return self._texts[type_name]
