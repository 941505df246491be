"""Live-tunable parameters without ROS: a table of typed, bounded values, batch validation, a
pending-change queue and the per-vehicle store the changes persist in.

What: a `TunableTable` lists a node's tunable values (controller gains, limits, noises,
thresholds) with unit, range and default; `check()` refuses a batch of changes with one line
naming the first bad value (unknown name, wrong type, not finite, out of range, or a cross-field
rule of the owner such as min < max); `PendingChanges` holds validated batches until the owner
applies them at its own boundary (the core: the executive's latch, never mid-chain);
`VehicleStore` keeps the values that differ from the defaults in one YAML file per vehicle and
node, written atomically (temp file + rename, under an advisory lock).
Why: the same rules serve `ros2 param set`, MAVLink PARAM_SET (through the node's
set_parameters service) and the `c4d param` CLI, so a value is accepted or refused for the same
reason whichever way it comes, and ROS-free so it is unit-tested without a graph.

Store layout (docs/parameters.md): ``$XDG_DATA_HOME/c4d/vehicles/<vehicle>/<node>.yaml``
(``~/.local/share`` when XDG_DATA_HOME is unset), a flat mapping ``name: value`` of the changed
values only; one file per node, so no two processes ever write the same file.
"""

from __future__ import annotations

import fcntl
import math
import os
import re
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

VEHICLE_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")


class TunableError(ValueError):
    """A refused change or an unusable store; the text is one line."""


@dataclass(frozen=True)
class Tunable:
    """One tunable value: name, default, unit, [low, high] range (inclusive), description."""

    name: str
    default: float
    unit: str
    low: float
    high: float
    description: str
    integer: bool = False

    def check(self, value: Any) -> str:
        """Why `value` cannot be this parameter's value ('' = it can)."""
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return f"{self.name}: expected a number, got {type(value).__name__}"
        if not math.isfinite(value):
            return f"{self.name}: {value} is not finite"
        if self.integer and value != int(value):
            return f"{self.name}: {value:g} is not an integer"
        if not self.low <= value <= self.high:
            return f"{self.name}: {value:g} is outside [{self.low:g}, {self.high:g}] {self.unit}".rstrip()
        return ""


CrossCheck = Callable[[Mapping[str, float]], str]


class TunableTable:
    """A node's tunables plus its cross-field rule (`cross(values) -> reason or ''`, on the values
    the change would leave in force)."""

    def __init__(self, items: Iterable[Tunable], cross: CrossCheck | None = None) -> None:
        self.items = {t.name: t for t in items}
        self.cross = cross

    def __iter__(self) -> Iterator[Tunable]:
        return iter(self.items.values())

    def __contains__(self, name: object) -> bool:
        return name in self.items

    def defaults(self) -> dict[str, float]:
        return {t.name: t.default for t in self.items.values()}

    def check(self, changes: Mapping[str, Any], current: Mapping[str, float]) -> str:
        """Why the batch `changes` cannot be applied on top of `current` ('' = it can)."""
        for name, value in changes.items():
            if name not in self.items:
                return f"{name}: no such parameter"
            reason = self.items[name].check(value)
            if reason:
                return reason
        if self.cross is not None:
            return self.cross({**current, **{k: float(v) for k, v in changes.items()}})
        return ""


class PendingChanges:
    """Validated changes waiting for the owner's boundary. `submit` validates against the values
    in force plus what is already queued (so two batches in one tick cannot together break a
    cross-field rule); `take` hands the merged changes over once, in arrival order."""

    def __init__(self, table: TunableTable, values: Mapping[str, float]) -> None:
        self.table = table
        self.values = dict(values)  # in force (applied)
        self.queued: dict[str, float] = {}

    def submit(self, changes: Mapping[str, Any]) -> str:
        reason = self.table.check(changes, {**self.values, **self.queued})
        if not reason:
            self.queued.update({k: float(v) for k, v in changes.items()})
        return reason

    def take(self) -> dict[str, float]:
        """The queued changes (empty: none); they are in force from now on."""
        if not self.queued:
            return {}
        changes, self.queued = self.queued, {}
        self.values.update(changes)
        return changes


def data_home(env: Mapping[str, str] | None = None) -> Path:
    env = os.environ if env is None else env
    base = env.get("XDG_DATA_HOME") or ""
    return Path(base) if base else Path(env.get("HOME", "~")).expanduser() / ".local" / "share"


def vehicle_dir(vehicle: str, env: Mapping[str, str] | None = None) -> Path:
    """Directory of a vehicle's stored parameters; TunableError for a name that is not a plain word."""
    if not VEHICLE_NAME.match(vehicle):
        raise TunableError(f"vehicle name {vehicle!r}: letters, digits, '_', '-', '.' only (max 64)")
    return data_home(env) / "c4d" / "vehicles" / vehicle


class VehicleStore:
    """The changed values of one node of one vehicle, in `<vehicle dir>/<node>.yaml`."""

    def __init__(self, path: Path) -> None:
        self.path = path

    @classmethod
    def of(cls, vehicle: str, node: str, env: Mapping[str, str] | None = None) -> VehicleStore:
        return cls(vehicle_dir(vehicle, env) / f"{node}.yaml")

    @contextmanager
    def _locked(self) -> Iterator[None]:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with open(self.path.with_name(self.path.name + ".lock"), "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            try:
                yield
            finally:
                fcntl.flock(lock, fcntl.LOCK_UN)

    def read(self) -> dict[str, Any]:
        """The stored mapping (empty when there is no file); TunableError when it is unreadable."""
        if not self.path.exists():
            return {}
        try:
            doc = yaml.safe_load(self.path.read_text()) or {}
        except (OSError, yaml.YAMLError) as exc:
            raise TunableError(f"{self.path}: unreadable ({exc.__class__.__name__})") from None
        if not isinstance(doc, dict):
            raise TunableError(f"{self.path}: not a mapping")
        return {str(k): v for k, v in doc.items()}

    def restore(self, table: TunableTable, values: Mapping[str, float]) -> tuple[dict[str, float], list[str]]:
        """The stored values that can be applied on top of `values`, each checked alone and then
        together; returns (accepted changes, one line per value ignored)."""
        problems: list[str] = []
        try:
            doc = self.read()
        except TunableError as exc:
            return {}, [f"{exc}; stored values ignored"]
        accepted: dict[str, float] = {}
        for name, value in doc.items():
            reason = table.check({name: value}, {**values, **accepted})
            if reason:
                problems.append(f"{self.path}: {reason}; ignored")
            else:
                accepted[name] = float(value)
        return accepted, problems

    def write(self, changed: Mapping[str, float]) -> None:
        """Replace the file with `changed` (remove it when empty): temp file + rename under a lock."""
        with self._locked():
            self._write(changed)

    def _write(self, changed: Mapping[str, float]) -> None:
        if not changed:
            self.path.unlink(missing_ok=True)
            return
        tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
        tmp.write_text(yaml.safe_dump({k: float(v) for k, v in sorted(changed.items())}, sort_keys=True))
        os.replace(tmp, self.path)

    def update(self, changes: Mapping[str, float], defaults: Mapping[str, float]) -> dict[str, float]:
        """Read-modify-write under the lock (the CLI while a node may be writing): `changes` merged
        into the stored values, values equal to their default dropped; returns what is stored."""
        with self._locked():
            stored = {k: float(v) for k, v in self.read().items()}
            stored.update(changes)
            stored = {k: v for k, v in stored.items() if v != defaults.get(k)}
            self._write(stored)
        return stored

    def reset(self) -> bool:
        """Remove the stored values (back to the airframe's / config's defaults at the next start)."""
        with self._locked():
            existed = self.path.exists()
            self.path.unlink(missing_ok=True)
        return existed


class DeferredWriter:
    """Writes a store off the caller's thread: `submit(changed)` returns at once, a daemon thread
    writes the newest snapshot (older ones not yet written are skipped). Why: the core applies
    changes inside its 500 Hz loop, where a file write (~1 ms, unbounded on a slow disk) must not run.
    `flush()` waits until everything submitted is on disk (tests, shutdown)."""

    def __init__(self, store: VehicleStore, on_error: Callable[[str], None] | None = None) -> None:
        import threading

        self.store, self.on_error = store, on_error
        self._lock = threading.Condition()
        self._latest: dict[str, float] | None = None
        self._busy = False
        self._thread = threading.Thread(target=self._run, name=f"store:{store.path.name}", daemon=True)
        self._thread.start()

    def submit(self, changed: Mapping[str, float]) -> None:
        with self._lock:
            self._latest = dict(changed)
            self._lock.notify_all()

    def flush(self, timeout_s: float = 5.0) -> bool:
        with self._lock:
            return self._lock.wait_for(lambda: self._latest is None and not self._busy, timeout_s)

    def _run(self) -> None:
        while True:
            with self._lock:
                self._lock.wait_for(lambda: self._latest is not None)
                snapshot, self._latest, self._busy = self._latest, None, True
            try:
                self.store.write(snapshot or {})
            except OSError as exc:
                if self.on_error is not None:
                    self.on_error(f"{self.store.path}: not saved ({exc})")
            with self._lock:
                self._busy = False
                self._lock.notify_all()
