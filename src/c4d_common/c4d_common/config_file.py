"""One way to read a YAML configuration mapping, with errors that name the file and the field.

Every c4d configuration (airframe, core, sim, failsafe policy, system, plans) is a YAML mapping
whose loader reports one line naming the offending field. These helpers give those loaders the
same reading, the same wording and one exception type to derive from.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any


class ConfigError(ValueError):
    """A configuration file or field is unusable; the text is one line for the user."""


# PyYAML contexts whose mark is where the broken construct starts (an unclosed bracket or quote, a key
# without ':'); the parser notices the problem only on a later line. Other contexts mark an enclosing
# block (often line 1): there the problem's own line is the right one.
_OPENING_CONTEXTS = ("while parsing a flow", "while scanning a")


def yaml_error_text(exc: Exception) -> str:
    """One line for a PyYAML error naming the line a person must fix:
    "malformed YAML at line 3 (while parsing a flow mapping: expected ',' or '}', but got '{' at line 4)"."""
    problem = getattr(exc, "problem", None) or "syntax error"
    problem_mark = getattr(exc, "problem_mark", None)
    context = getattr(exc, "context", None)
    context_mark = getattr(exc, "context_mark", None)
    if context and context_mark is not None and context.startswith(_OPENING_CONTEXTS):
        later = f" at line {problem_mark.line + 1}" if problem_mark is not None else ""
        return f"malformed YAML at line {context_mark.line + 1} ({context}: {problem}{later})"
    where = f" at line {problem_mark.line + 1}" if problem_mark is not None else ""
    return f"malformed YAML{where} ({problem})"


def read_yaml_mapping(path: str | Path, what: str, error: type[ConfigError] = ConfigError) -> dict[str, Any]:
    """Parse `path` as a YAML mapping. `what` names the file in errors ("sim config")."""
    import yaml

    path = Path(path)
    try:
        doc = yaml.safe_load(path.read_text())
    except OSError as exc:
        raise error(f"cannot read {what} {path}: {exc.strerror}") from None
    except yaml.YAMLError as exc:
        raise error(f"{what} {path}: {yaml_error_text(exc)}") from None
    if not isinstance(doc, dict):
        raise error(f"{what} {path}: must be a mapping")
    return doc


def reject_unknown(doc: Mapping[str, Any], allowed: set[str], what: str, error: type[ConfigError] = ConfigError) -> None:
    """Refuse fields that nobody reads (a typo would otherwise be silently ignored)."""
    unknown = set(doc) - allowed
    if unknown:
        raise error(f"{what}: unknown field(s) {', '.join(sorted(unknown))}")


def number(doc: Mapping[str, Any], key: str, what: str, *, positive: bool = False, default: float | None = None,
           error: type[ConfigError] = ConfigError) -> float:
    """`doc[key]` as a finite float (`default` when absent and given); `what` prefixes the field
    name in errors ("sim config: field 'start.latitude' …")."""
    if key not in doc and default is not None:
        return default
    value = doc.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or (positive and value <= 0):
        kind = "a positive number" if positive else "a number"
        raise error(f"{what}: field '{key}' must be {kind}, got {value!r}")
    return float(value)
