"""Read task sets from YAML or CSV files, with clear one-line errors.

YAML, integer time units:
    unit: us                     # optional, free text used in reports
    tasks:
      - {name: imu, period: 2000, wcet: 150}          # optional: offset
    chains:                      # optional equal-period precedence chains
      - {tasks: [estimate, control], separation: 0}

YAML, messages on a serial link (converted to bit times, as in the thesis case study):
    link: {bits_per_second: 57600, bits_per_byte: 10, overhead_bytes: 8}
    messages:
      - {name: ALIVE, period_s: 2, bytes: 17}   # period = period_s·bps, wcet = (bytes+overhead)·bits_per_byte

CSV: a header line with name,period,wcet[,offset] then one task per line.
"""

from __future__ import annotations

import csv
import io
from fractions import Fraction
from pathlib import Path
from typing import Any

import yaml

from .model import Chain, Task, TaskSet, TaskSetError


def _mapping(value: Any, what: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise TaskSetError(f"{what} must be a mapping, got {type(value).__name__}")
    return value


def _messages_to_tasks(doc: dict[str, Any]) -> list[Task]:
    link = _mapping(doc.get("link"), "'link'")
    bps = link.get("bits_per_second")
    if not isinstance(bps, int) or bps <= 0:
        raise TaskSetError("link.bits_per_second must be a positive integer")
    bits_per_byte = link.get("bits_per_byte", 10)
    overhead = link.get("overhead_bytes", 0)
    tasks = []
    for k, item in enumerate(doc["messages"] or []):
        item = _mapping(item, f"message #{k + 1}")
        name = item.get("name", f"m{k + 1}")
        try:
            period = Fraction(str(item["period_s"])) * bps
            size = int(item["bytes"])
        except (KeyError, ValueError, TypeError) as exc:
            raise TaskSetError(f"message '{name}': needs numeric period_s and bytes ({exc})") from None
        if period.denominator != 1:
            raise TaskSetError(f"message '{name}': period_s·bits_per_second = {float(period)} is not an integer")
        tasks.append(Task(str(name), int(period), (size + overhead) * bits_per_byte, item.get("offset")))
    return tasks


def taskset_from_dict(doc: Any) -> TaskSet:
    """TaskSet from a parsed YAML document (see module docstring)."""
    doc = _mapping(doc, "the task-set file")
    if "messages" in doc:
        tasks = _messages_to_tasks(doc)
        unit = doc.get("unit", f"1/{doc['link']['bits_per_second']} s")
    elif "tasks" in doc:
        if not isinstance(doc["tasks"], list):
            raise TaskSetError("'tasks' must be a list")
        tasks = []
        for k, item in enumerate(doc["tasks"]):
            item = _mapping(item, f"task #{k + 1}")
            unknown = set(item) - {"name", "period", "wcet", "offset"}
            if unknown:
                raise TaskSetError(f"task #{k + 1}: unknown key(s) {', '.join(sorted(unknown))}")
            if "period" not in item or "wcet" not in item:
                raise TaskSetError(f"task #{k + 1}: needs 'period' and 'wcet'")
            tasks.append(Task(str(item.get("name", f"t{k + 1}")), item["period"], item["wcet"], item.get("offset")))
        unit = str(doc.get("unit", "unit"))
    else:
        raise TaskSetError("the task-set file needs a 'tasks' list (or 'link' + 'messages')")
    chains = []
    for k, item in enumerate(doc.get("chains") or []):
        item = _mapping(item, f"chain #{k + 1}")
        names = item.get("tasks")
        if not isinstance(names, list):
            raise TaskSetError(f"chain #{k + 1}: 'tasks' must be a list of task names")
        chains.append(Chain(tuple(str(n) for n in names), item.get("separation", 0)))
    return TaskSet(tuple(tasks), tuple(chains), unit=unit)


def taskset_from_csv(text: str) -> TaskSet:
    rows = list(csv.DictReader(io.StringIO(text)))
    if not rows:
        raise TaskSetError("the CSV file has no task rows")
    missing = {"period", "wcet"} - set(rows[0])
    if missing:
        raise TaskSetError(f"the CSV header lacks column(s): {', '.join(sorted(missing))}")
    tasks = []
    for k, row in enumerate(rows, start=2):
        try:
            offset = int(row["offset"]) if row.get("offset") not in (None, "") else None
            tasks.append(Task(row.get("name") or f"t{k - 1}", int(row["period"]), int(row["wcet"]), offset))
        except ValueError:
            raise TaskSetError(f"CSV line {k}: period, wcet and offset must be integers") from None
    return TaskSet(tuple(tasks))


def load_taskset(path: str | Path) -> TaskSet:
    """TaskSet from a .yaml/.yml or .csv file; TaskSetError with a one-line reason otherwise."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise TaskSetError(f"cannot read {path}: {exc.strerror}") from None
    if path.suffix.lower() == ".csv":
        return taskset_from_csv(text)
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        # an unclosed bracket/quote or a key without ':' is noticed a line later: name where it starts
        opened = getattr(exc, "context_mark", None) if str(getattr(exc, "context", "")).startswith(
            ("while parsing a flow", "while scanning a")) else None
        mark = opened or getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark else ""
        raise TaskSetError(f"{path}: malformed YAML{where} ({getattr(exc, 'problem', None) or 'syntax error'})") from None
    return taskset_from_dict(doc)
