"""Load and validate a core configuration (config/core.yaml): airframe + executive schedule.

Every problem is a CoreConfigError with one line naming the field, raised before anything
starts (the node then exits with code 2 and the motors are never armed).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from c4d_common.airframe import Airframe, AirframeError, default_airframe_path, load_airframe
from c4d_common.config_file import ConfigError, read_yaml_mapping, reject_unknown
from c4d_common.share import share_file
from c4d_sched.tickschedule import ScheduleConfigError, TickSchedule, schedule_from_config

from .gnc import GncCore

KNOWN_TASKS = (*GncCore.TASKS, "status")
REQUIRED_TASKS = ("state_update", "guidance", "position_control", "attitude_control", "rate_control", "mixer")


class CoreConfigError(ConfigError):
    """Invalid core configuration (one line)."""


@dataclass(frozen=True)
class CoreConfig:
    airframe: Airframe
    schedule: TickSchedule
    executive_name: str
    report_period_s: float
    source: Path  # the file read
    airframe_ref: str  # the airframe as named (bundled name or YAML path): the override or the file's entry

    def parameters(self) -> dict[str, str]:
        """The core's file-backed parameters as in force: what `ros2 param get core <name>` reports."""
        return {"config": str(self.source), "airframe": self.airframe_ref, "phase_method": self.schedule.method}


def default_config_path() -> Path:
    return share_file("c4d_gnc", "config", "core.yaml")


def load_core_config(path: str | Path | None = None, airframe: str | None = None,
                     phase_method: str | None = None) -> CoreConfig:
    path = Path(path) if path else default_config_path()
    doc = read_yaml_mapping(path, "core config", CoreConfigError)
    reject_unknown(doc, {"airframe", "executive"}, "core config", CoreConfigError)
    name = airframe or doc.get("airframe", "quad_x")
    try:
        frame_path = Path(name) if str(name).endswith((".yaml", ".yml")) else default_airframe_path(str(name))
        if not frame_path.is_absolute() and not frame_path.exists():
            frame_path = path.parent / frame_path
        frame = load_airframe(frame_path)
    except AirframeError as exc:
        raise CoreConfigError(str(exc)) from None
    executive = doc.get("executive")
    try:
        schedule = schedule_from_config(executive, phase_method)
    except ScheduleConfigError as exc:
        raise CoreConfigError(str(exc)) from None
    names = [t.name for t in schedule.tasks]
    for task in names:
        if task not in KNOWN_TASKS:
            raise CoreConfigError(f"executive task '{task}': unknown task (core tasks: {', '.join(KNOWN_TASKS)})")
    for task in REQUIRED_TASKS:
        if task not in names:
            raise CoreConfigError(f"executive: missing task '{task}'")
    period = executive.get("report_period_s", 1.0)
    if isinstance(period, bool) or not isinstance(period, (int, float)) or period <= 0:
        raise CoreConfigError("executive.report_period_s must be a positive number")
    return CoreConfig(frame, schedule, str(executive.get("name", "gnc_core")), float(period), path, str(name))
