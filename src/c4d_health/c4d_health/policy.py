"""Failsafe policy: events → actions, with delays, most-severe-wins and no oscillation.

`FailsafePolicy.from_yaml()` validates the policy file (one line naming the field on error).
`FailsafeArbiter.update(now, active_events, in_air)` returns the action to request: an event
counts once its condition has held for its `delay_s`; among the counted events the most severe
action wins; the chosen action is latched and only ever escalates until `reset()` (called on
disarm), so the vehicle never flips between, say, RTL and land as conditions flicker.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path

import yaml

from c4d_common.config_file import yaml_error_text
from c4d_common.vehicle import FailsafeAction as Action  # VehicleStatus.FAILSAFE_*; order = severity


class Event(StrEnum):
    """The monitored conditions (policy keys, diagnostics names `health/<event>`), in the order
    they are evaluated and reported."""

    NODE_DEAD = "node_dead"  # silent and gone from the ROS graph
    NODE_STALLED = "node_stalled"  # silent but still in the ROS graph
    GPS_LOSS = "gps_loss"
    ESTIMATOR_INVALID = "estimator_invalid"
    BATTERY_LOW = "battery_low"
    BATTERY_CRITICAL = "battery_critical"
    GEOFENCE_BREACH = "geofence_breach"
    LINK_LOSS = "link_loss"
    EXECUTOR_OVERRUN = "executor_overrun"
    CORE_STALL = "core_stall"  # the GNC core's executive stalled (a long tick, many skipped ticks, or silent stats)
    CORE_STALL_REPEATED = "core_stall_repeated"  # core stalls again and again within a window


EVENTS = tuple(e.value for e in Event)


class PolicyError(ValueError):
    pass


@dataclass(frozen=True)
class Rule:
    action: Action
    delay_s: float = 0.0
    only_in_air: bool = True


@dataclass(frozen=True)
class CoreStallLimits:
    """When a window of the core's executor statistics counts as a stall, and when stalls repeat.

    Defaults from measured flights (2-core SITL machine, 500 Hz core): the worst tick of a 1 s
    window stays below 6 ms and at most 9 ticks are skipped; the DDS publish stalls this monitor
    is for lasted 100-330 ms.
    """

    worst_tick_ms: float = 20.0  # a window's worst tick longer than this [ms] is a stall
    skipped_ticks: int = 25  # more skipped ticks than this in one window is a stall
    stats_timeout_s: float = 1.5  # no statistics for this long [s] while the core is in the graph: stalled
    repeat_count: int = 3  # this many stalls ...
    repeat_window_s: float = 10.0  # ... within this long [s]: core_stall_repeated


CORE_STALL_KEYS = {"core_stall_ms": "worst_tick_ms", "core_stall_skipped_ticks": "skipped_ticks",
                   "core_stats_timeout_s": "stats_timeout_s", "core_stall_repeat_count": "repeat_count",
                   "core_stall_repeat_window_s": "repeat_window_s"}


@dataclass(frozen=True)
class FailsafePolicy:
    rules: dict[str, Rule]
    battery_low: float = 0.30
    battery_critical: float = 0.15
    node_timeout_s: float = 1.0
    core_stall: CoreStallLimits = CoreStallLimits()

    @classmethod
    def from_yaml(cls, path: str | Path) -> FailsafePolicy:
        try:
            doc = yaml.safe_load(Path(path).read_text())
        except OSError as exc:
            raise PolicyError(f"cannot read failsafe policy {path}: {exc.strerror}") from None
        except yaml.YAMLError as exc:
            raise PolicyError(f"failsafe policy {path}: {yaml_error_text(exc)}") from None
        return cls.from_dict(doc)

    @classmethod
    def from_dict(cls, doc: object) -> FailsafePolicy:
        if not isinstance(doc, dict) or not isinstance(doc.get("events"), dict):
            raise PolicyError("failsafe policy: needs an 'events' mapping")
        unknown = set(doc) - {"events", "battery_low_threshold", "battery_critical_threshold", "node_timeout_s", *CORE_STALL_KEYS}
        if unknown:
            raise PolicyError(f"failsafe policy: unknown field(s) {', '.join(sorted(unknown))}")
        rules = {}
        for event, rule in doc["events"].items():
            if event not in EVENTS:
                raise PolicyError(f"failsafe policy: unknown event '{event}' (events: {', '.join(EVENTS)})")
            if not isinstance(rule, dict) or str(rule.get("action", "")).upper() not in Action.__members__:
                raise PolicyError(f"failsafe policy: events.{event}.action must be one of "
                                  f"{', '.join(a.name.lower() for a in Action)}")
            delay = rule.get("delay_s", 0.0)
            if isinstance(delay, bool) or not isinstance(delay, (int, float)) or delay < 0:
                raise PolicyError(f"failsafe policy: events.{event}.delay_s must be a number >= 0")
            rules[event] = Rule(Action[str(rule["action"]).upper()], float(delay), bool(rule.get("only_in_air", True)))
        low, critical = doc.get("battery_low_threshold", 0.30), doc.get("battery_critical_threshold", 0.15)
        if not (isinstance(low, (int, float)) and isinstance(critical, (int, float)) and 0 < critical < low < 1):
            raise PolicyError("failsafe policy: need 0 < battery_critical_threshold < battery_low_threshold < 1")
        timeout = doc.get("node_timeout_s", 1.0)
        if not isinstance(timeout, (int, float)) or timeout <= 0:
            raise PolicyError("failsafe policy: node_timeout_s must be > 0")
        return cls(rules, float(low), float(critical), float(timeout), core_stall_limits(doc))


def core_stall_limits(doc: dict) -> CoreStallLimits:
    """The core_stall_* fields of a policy document (defaults for the missing ones); PolicyError names a bad one."""
    values: dict[str, float | int] = {}
    for key, attr in CORE_STALL_KEYS.items():
        if key not in doc:
            continue
        value = doc[key]
        integer = isinstance(getattr(CoreStallLimits, attr), int)
        if isinstance(value, bool) or not isinstance(value, int if integer else (int, float)) or value <= 0:
            raise PolicyError(f"failsafe policy: {key} must be {'an integer' if integer else 'a number'} > 0")
        values[attr] = value if integer else float(value)
    return CoreStallLimits(**values)


@dataclass
class FailsafeArbiter:
    policy: FailsafePolicy
    since: dict[str, float] = field(default_factory=dict)
    action: Action = Action.NONE
    reason: str = ""

    def update(self, now: float, active: dict[str, str], in_air: bool) -> Action:
        """`active`: event → human-readable detail for every condition true right now."""
        for event in list(self.since):
            if event not in active:
                del self.since[event]
        best, why = Action.NONE, ""
        for event, detail in active.items():
            start = self.since.setdefault(event, now)
            rule = self.policy.rules.get(event)
            if rule is None or (rule.only_in_air and not in_air) or now - start < rule.delay_s:
                continue
            if rule.action > best:
                best, why = rule.action, f"{event}: {detail}"
        if best > self.action:  # escalate only
            self.action, self.reason = best, why
        return self.action

    def reset(self) -> None:
        self.since.clear()
        self.action, self.reason = Action.NONE, ""
