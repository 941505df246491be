"""Mission journal: the accepted plan and the progress through it, kept on disk across a restart.

Why: the supervisor restarts a mission node that dies (SIGKILL, crash) within a second or two;
without a record the new process comes up with no plan, the core holds once the guidance
setpoints go stale and the flight never completes. `MissionJournal` writes the plan (every
field of the `Plan` model, so it round-trips exactly), the executor's `Checkpoint` and the fence
in force (geofence/active: a fence set in flight survives a restart) to one JSON file whenever
they change (upload, start, item advance, pause, completion, abort, clear, fence set — never
per tick), atomically: a temporary file in the same directory, fsync, `os.replace`, so a kill
mid-write leaves the previous journal intact. `resume_status` decides what a restarted node
does with an active mission: continue it only when the vehicle still flies it (armed, in the
air, AUTO, no failsafe), otherwise keep the plan paused or aborted with the reason.
ROS-free; unit-tested in test/test_mission_journal.py.
"""

from __future__ import annotations

import json
import os
import tempfile
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from c4d_common.plan import Geofence, Item, Plan
from c4d_common.vehicle import FailsafeAction, Landed, MissionStatus, Mode

from .executor import Checkpoint
from .fence import FenceSource, geofence_from_dict

VERSION = 1
FLYING = (Landed.IN_AIR, Landed.TAKEOFF, Landed.LANDING)


class JournalError(ValueError):
    """A journal file that cannot be read back (one line saying why)."""


@dataclass(frozen=True)
class JournalEntry:
    """One journal record: the plan in force (None after a clear), the progress through it and the
    fence in force with its source (None: none accepted or set; journals before issue 18 have none)."""

    plan: Plan | None
    checkpoint: Checkpoint
    fence: tuple[Geofence, FenceSource] | None = None


def plan_to_dict(plan: Plan) -> dict[str, Any]:
    return asdict(plan)


def plan_from_dict(doc: dict[str, Any]) -> Plan:
    """The inverse of plan_to_dict (TypeError / KeyError / ValueError on a malformed record)."""
    geofence = geofence_from_dict(doc["geofence"])
    items = tuple(Item(**item) for item in doc["items"])
    return Plan(items, geofence, str(doc["name"]), float(doc["cruise_speed"]), float(doc["rtl_altitude"]),
                int(doc["plan_id"]))


def _checkpoint_from_dict(doc: dict[str, Any]) -> Checkpoint:
    fields = dict(doc)
    fields["status"] = MissionStatus[fields["status"]]
    return Checkpoint(**fields)


class MissionJournal:
    """Reads and atomically writes the journal file at `path` (parent directories are created)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

    def load(self) -> JournalEntry | None:
        """The last entry written, None when there is no journal; JournalError when it is unreadable."""
        try:
            text = self.path.read_text()
        except FileNotFoundError:
            return None
        except OSError as exc:
            raise JournalError(f"cannot read {self.path}: {exc.strerror}") from None
        try:
            doc = json.loads(text)
            if doc.get("version") != VERSION:
                raise JournalError(f"{self.path}: version {doc.get('version')!r}, expected {VERSION}")
            plan = plan_from_dict(doc["plan"]) if doc["plan"] is not None else None
            checkpoint = _checkpoint_from_dict(doc["checkpoint"])
            raw_fence = doc.get("fence")
            fence = (geofence_from_dict(raw_fence["fence"]), FenceSource(raw_fence["source"])) \
                if raw_fence is not None else None
        except JournalError:
            raise
        except (ValueError, TypeError, KeyError, AttributeError) as exc:
            raise JournalError(f"{self.path}: malformed journal ({type(exc).__name__}: {exc})") from None
        if plan is not None and plan.plan_id != checkpoint.plan_id:
            raise JournalError(f"{self.path}: plan id {plan.plan_id} but progress of plan {checkpoint.plan_id}")
        if plan is not None and not 0 <= checkpoint.current <= len(plan.items):
            raise JournalError(f"{self.path}: item {checkpoint.current} outside the plan's {len(plan.items)} items")
        return JournalEntry(plan, checkpoint, fence)

    def save(self, entry: JournalEntry) -> None:
        """Replace the journal with `entry` atomically (OSError when the file cannot be written)."""
        doc = {"version": VERSION, "plan": plan_to_dict(entry.plan) if entry.plan is not None else None,
               "checkpoint": {**asdict(entry.checkpoint), "status": entry.checkpoint.status.name},
               "fence": None if entry.fence is None else {"source": entry.fence[1].value, "fence": asdict(entry.fence[0])}}
        text = json.dumps(doc, indent=1)  # NaN (an item's "current" coordinate) round-trips as NaN
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{self.path.name}.", dir=self.path.parent)
        try:
            with os.fdopen(fd, "w") as f:
                f.write(text)
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, self.path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise


@dataclass(frozen=True)
class VehicleCheck:
    """What the restarted node knows of the vehicle (the latched vehicle/status)."""

    armed: bool
    landed: Landed
    mode: Mode
    failsafe: FailsafeAction


@dataclass(frozen=True)
class Resumption:
    """The status a journalled mission takes back after a restart, and why (for the log)."""

    status: MissionStatus
    reason: str

    @property
    def resumed(self) -> bool:
        return self.status == MissionStatus.ACTIVE


def resume_status(saved: MissionStatus, vehicle: VehicleCheck) -> Resumption:
    """An active mission continues only while the vehicle still flies it: armed, in the air, in
    AUTO and under no failsafe that took it (hold → paused; RTL, land, terminate → aborted, as the
    mission node itself does on those commands). A vehicle on the ground ends it (aborted); one
    taken into another mode keeps it paused (mission/control resume continues it). Any other
    saved status is kept as it was: a completed or aborted mission never flies again by itself."""
    if saved != MissionStatus.ACTIVE:
        return Resumption(saved, f"was {saved.name.lower()}")
    if not vehicle.armed or vehicle.landed not in FLYING:
        return Resumption(MissionStatus.ABORTED, "the vehicle is disarmed or on the ground")
    if vehicle.failsafe >= FailsafeAction.RTL:
        return Resumption(MissionStatus.ABORTED, f"failsafe {vehicle.failsafe.name} active")
    if vehicle.failsafe == FailsafeAction.HOLD:
        return Resumption(MissionStatus.PAUSED, "failsafe HOLD active")
    if vehicle.mode != Mode.AUTO:
        return Resumption(MissionStatus.PAUSED, f"the vehicle is in {vehicle.mode.name} mode")
    return Resumption(MissionStatus.ACTIVE, "the vehicle still flies the mission")
