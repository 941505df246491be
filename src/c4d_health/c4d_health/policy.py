"""Failsafe policy: events → actions, with delays, most-severe-wins and no oscillation.

`FailsafePolicy.from_yaml()` validates the policy file (one line naming the field on error).
`FailsafeArbiter.update(now, active_events, in_air)` returns the action to request: an event
counts once its condition has held for its `delay_s`; among the counted events the most severe
action wins; the chosen action is latched and only ever escalates until `reset()` (called on
disarm), so the vehicle never flips between, say, RTL and land as conditions flicker.

A rule may escalate by itself (`then`, `then_after_s`, like PX4's COM_OF_LOSS_T then
COM_OBL_RC_ACT): once its action has been latched for `then_after_s`, the arbiter escalates to
`then` even if the condition has cleared meanwhile — offboard_loss's HOLD takes the vehicle out
of OFFBOARD, which ends the condition, and the landing must still follow. What cancels a pending
escalation: disarm (`reset()`), a more severe action latched by another rule (its own `then`, if
any, replaces it), and `clear(event)` — the node's call when the operator takes over again
(re-entering OFFBOARD with a live stream after an offboard_loss).
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
    NODE_INACTIVE = "node_inactive"  # a flight-critical node announced a lifecycle state other than ACTIVE
    GPS_LOSS = "gps_loss"
    ESTIMATOR_INVALID = "estimator_invalid"
    BATTERY_LOW = "battery_low"
    BATTERY_CRITICAL = "battery_critical"
    GEOFENCE_BREACH = "geofence_breach"
    LINK_LOSS = "link_loss"
    EXECUTOR_OVERRUN = "executor_overrun"
    CORE_STALL = "core_stall"  # the GNC core's executive stalled (a long tick, many skipped ticks, or silent stats)
    CORE_STALL_REPEATED = "core_stall_repeated"  # core stalls again and again within a window
    OFFBOARD_LOSS = "offboard_loss"  # in OFFBOARD, guidance/offboard silent for offboard_loss_timeout_s
    OBSTACLE_NEAR = "obstacle_near"  # a perceived obstacle inside the detection range (D3.3 §6.7: 2 m)
    OBSTACLE_COLLISION_RISK = "obstacle_collision_risk"  # inside the protection radius (0.5 m)
    # GNSS integrity (navigation/status): the verdict with no other healthy horizontal source in use
    # (the position rests on dead reckoning or on GNSS) ...
    GNSS_SPOOFED = "gnss_spoofed"
    GNSS_JAMMED = "gnss_jammed"
    # ... and the same verdict while the navigation flies on another healthy source (it switched)
    GNSS_SPOOFED_SWITCHED = "gnss_spoofed_switched"
    GNSS_JAMMED_SWITCHED = "gnss_jammed_switched"


EVENTS = tuple(e.value for e in Event)


class PolicyError(ValueError):
    pass


@dataclass(frozen=True)
class Rule:
    """An event's failsafe: `action` once the condition has held `delay_s` (ignored on the ground
    when `only_in_air`); then `then` (if set) once `action` has been latched for `then_after_s`."""

    action: Action
    delay_s: float = 0.0
    only_in_air: bool = True
    then: Action | None = None
    then_after_s: float = 0.0


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
    offboard_loss_timeout_s: float = 0.5  # guidance/offboard silent this long in OFFBOARD: offboard_loss [s]
    obstacle_detection_range_m: float = 2.0  # an obstacle's surface nearer than this: obstacle_near [m]
    obstacle_protection_radius_m: float = 0.5  # nearer than this: obstacle_collision_risk [m]

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
        unknown = set(doc) - {"events", "battery_low_threshold", "battery_critical_threshold", "node_timeout_s",
                              "offboard_loss_timeout_s", "obstacle_detection_range_m", "obstacle_protection_radius_m",
                              *CORE_STALL_KEYS}
        if unknown:
            raise PolicyError(f"failsafe policy: unknown field(s) {', '.join(sorted(unknown))}")
        rules = {}
        for event, rule in doc["events"].items():
            if event not in EVENTS:
                raise PolicyError(f"failsafe policy: unknown event '{event}' (events: {', '.join(EVENTS)})")
            if not isinstance(rule, dict):
                raise PolicyError(f"failsafe policy: events.{event} must be a mapping with an action")
            rules[event] = rule_of(event, rule)
        low, critical = doc.get("battery_low_threshold", 0.30), doc.get("battery_critical_threshold", 0.15)
        if not (isinstance(low, (int, float)) and isinstance(critical, (int, float)) and 0 < critical < low < 1):
            raise PolicyError("failsafe policy: need 0 < battery_critical_threshold < battery_low_threshold < 1")
        timeout = doc.get("node_timeout_s", 1.0)
        if not isinstance(timeout, (int, float)) or timeout <= 0:
            raise PolicyError("failsafe policy: node_timeout_s must be > 0")
        offboard_timeout = doc.get("offboard_loss_timeout_s", 0.5)
        if not _number(offboard_timeout) or offboard_timeout <= 0:
            raise PolicyError("failsafe policy: offboard_loss_timeout_s must be a number > 0")
        detection, protection = doc.get("obstacle_detection_range_m", 2.0), doc.get("obstacle_protection_radius_m", 0.5)
        if not (_number(detection) and _number(protection) and 0 < protection < detection):
            raise PolicyError("failsafe policy: need 0 < obstacle_protection_radius_m < obstacle_detection_range_m")
        return cls(rules, float(low), float(critical), float(timeout), core_stall_limits(doc), float(offboard_timeout),
                   float(detection), float(protection))


def _number(value: object) -> bool:
    return not isinstance(value, bool) and isinstance(value, (int, float))


def _action(event: str, rule: dict, key: str) -> Action:
    name = str(rule.get(key, "")).upper()
    if name not in Action.__members__:
        raise PolicyError(f"failsafe policy: events.{event}.{key} must be one of {', '.join(a.name.lower() for a in Action)}")
    return Action[name]


def rule_of(event: str, rule: dict) -> Rule:
    """One event's rule from its policy mapping; PolicyError names the bad field."""
    unknown = set(rule) - {"action", "delay_s", "only_in_air", "then", "then_after_s"}
    if unknown:
        raise PolicyError(f"failsafe policy: events.{event}: unknown field(s) {', '.join(sorted(map(str, unknown)))}")
    action = _action(event, rule, "action")
    delay = rule.get("delay_s", 0.0)
    if not _number(delay) or delay < 0:
        raise PolicyError(f"failsafe policy: events.{event}.delay_s must be a number >= 0")
    then = _action(event, rule, "then") if "then" in rule else None
    if then is not None and then <= action:
        raise PolicyError(f"failsafe policy: events.{event}.then must be more severe than its action ({action.name.lower()})")
    after = rule.get("then_after_s", 0.0)
    if not _number(after) or after < 0 or ("then_after_s" in rule and then is None):
        raise PolicyError(f"failsafe policy: events.{event}.then_after_s must be a number >= 0, with a 'then' action")
    return Rule(action, float(delay), bool(rule.get("only_in_air", True)), then, float(after))


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


@dataclass(frozen=True)
class Escalation:
    """A latched rule's own next step: `action` at time `due` [s], whatever its condition does meanwhile."""

    action: Action
    due: float
    reason: str


@dataclass
class FailsafeArbiter:
    policy: FailsafePolicy
    since: dict[str, float] = field(default_factory=dict)
    action: Action = Action.NONE
    reason: str = ""
    cause: str = ""  # the event whose rule latched `action` ("" while none)
    pending: Escalation | None = None  # the latched rule's `then`, not due yet

    def update(self, now: float, active: dict[str, str], in_air: bool) -> Action:
        """`active`: event → human-readable detail for every condition true right now."""
        for event in list(self.since):
            if event not in active:
                del self.since[event]
        best, why, cause = Action.NONE, "", ""
        for event, detail in active.items():
            start = self.since.setdefault(event, now)
            rule = self.policy.rules.get(event)
            if rule is None or (rule.only_in_air and not in_air) or now - start < rule.delay_s:
                continue
            if rule.action > best:
                best, why, cause = rule.action, f"{event}: {detail}", event
        if best > self.action:  # escalate only
            self.action, self.reason, self.cause = best, why, cause
            rule = self.policy.rules[cause]
            self.pending = None if rule.then is None else Escalation(
                rule.then, now + rule.then_after_s, f"{why} ({rule.action.name.lower()} for {rule.then_after_s:g} s, "
                                                    f"then {rule.then.name.lower()})")
        pending = self.pending
        if pending is not None and now >= pending.due:
            self.pending = None
            if pending.action > self.action:
                self.action, self.reason = pending.action, pending.reason
        return self.action

    def clear(self, event: str) -> bool:
        """Forget the failsafe latched by `event` and its pending escalation (the operator took over
        again, e.g. re-entered OFFBOARD with a live stream after an offboard_loss); a failsafe
        latched by another event stays. True when something was cleared."""
        if not self.cause or self.cause != event:
            return False
        self.reset()
        return True

    def reset(self) -> None:
        self.since.clear()
        self.action, self.reason, self.cause, self.pending = Action.NONE, "", "", None
