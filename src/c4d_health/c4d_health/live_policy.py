"""The health node's live-tunable failsafe thresholds and timeouts: FailsafePolicy <-> flat parameters.

What: `policy_table(policy)` lists every threshold and timeout of the failsafe policy
(config/failsafe.yaml's top-level fields under the same names — battery thresholds, node timeout,
core-stall limits, offboard-loss timeout, obstacle ranges — and each event's `events.<event>.delay_s`,
plus `events.<event>.then_after_s` where the rule escalates) with unit, range and the policy's
values as defaults; the cross-field rules are the policy file's (0 < critical < low battery
threshold, 0 < protection radius < detection range). `policy_with(policy, values)` is the frozen
FailsafePolicy those values describe; the health node swaps it in at its tick boundary.
Not here: actions, `then` and `only_in_air` (what a failsafe does is a policy-file decision, read at
configure). Why a table: the same checks for `ros2 param set`, MAVLink PARAM_SET (BAT_LOW_THR, ...)
and `c4d param`, and the per-vehicle store (c4d_common.tunable).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

from c4d_common.tunable import Tunable, TunableTable

from .policy import CORE_STALL_KEYS, FailsafePolicy

# parameter: (attribute of FailsafePolicy, unit, low, high, description, integer)
TOP: dict[str, tuple[str, str, float, float, str, bool]] = {
    "battery_low_threshold": ("battery_low", "1", 0.01, 0.99, "state of charge below this: battery_low", False),
    "battery_critical_threshold": ("battery_critical", "1", 0.01, 0.99, "state of charge below this: battery_critical",
                                   False),
    "node_timeout_s": ("node_timeout_s", "s", 0.1, 30.0, "a monitored node silent this long is dead or stalled", False),
    "offboard_loss_timeout_s": ("offboard_loss_timeout_s", "s", 0.05, 30.0,
                                "in OFFBOARD, no setpoint on guidance/offboard this long: offboard_loss", False),
    "obstacle_detection_range_m": ("obstacle_detection_range_m", "m", 0.05, 100.0,
                                   "an obstacle's surface nearer than this: obstacle_near", False),
    "obstacle_protection_radius_m": ("obstacle_protection_radius_m", "m", 0.01, 50.0,
                                     "an obstacle nearer than this: obstacle_collision_risk", False),
}
# core_stall_* parameter: (unit, low, high, description, integer)
STALL: dict[str, tuple[str, float, float, str, bool]] = {
    "core_stall_ms": ("ms", 2.0, 1000.0, "a statistics window whose worst core tick is longer: core_stall", False),
    "core_stall_skipped_ticks": ("ticks", 0.0, 100000.0, "more skipped core ticks in one window: core_stall", True),
    "core_stats_timeout_s": ("s", 0.2, 60.0, "no executor statistics this long while the core is in the graph: core_stall",
                             False),
    "core_stall_repeat_count": ("stalls", 1.0, 1000.0, "this many core stalls within the window: core_stall_repeated",
                                True),
    "core_stall_repeat_window_s": ("s", 0.1, 3600.0, "the window of core_stall_repeat_count", False),
}
MAX_DELAY_S = 600.0


def policy_values(policy: FailsafePolicy) -> dict[str, float]:
    """The tunable values of `policy`, by parameter name."""
    values = {name: float(getattr(policy, attr)) for name, (attr, *_) in TOP.items()}
    values.update({name: float(getattr(policy.core_stall, CORE_STALL_KEYS[name])) for name in STALL})
    for event, rule in sorted(policy.rules.items()):
        values[f"events.{event}.delay_s"] = rule.delay_s
        if rule.then is not None:
            values[f"events.{event}.then_after_s"] = rule.then_after_s
    return values


def policy_table(policy: FailsafePolicy) -> TunableTable:
    """The health node's tunables with `policy`'s values as defaults, and the policy file's cross rules."""
    values = policy_values(policy)
    items = [Tunable(name, values[name], unit, low, high, what, integer)
             for name, (_, unit, low, high, what, integer) in TOP.items()]
    items += [Tunable(name, values[name], unit, low, high, what, integer)
              for name, (unit, low, high, what, integer) in STALL.items()]
    for name in values:
        if name.startswith("events."):
            _, event, term = name.split(".")
            what = ("the condition must last this long before the action" if term == "delay_s"
                    else "the action latched this long: escalate to its 'then'")
            items.append(Tunable(name, values[name], "s", 0.0, MAX_DELAY_S, f"{event}: {what}"))

    def cross(v: Mapping[str, float]) -> str:
        low, critical = v["battery_low_threshold"], v["battery_critical_threshold"]
        if not critical < low:
            return f"battery_critical_threshold ({critical:g}) must be below battery_low_threshold ({low:g})"
        near, far = v["obstacle_protection_radius_m"], v["obstacle_detection_range_m"]
        if not near < far:
            return f"obstacle_protection_radius_m ({near:g}) must be below obstacle_detection_range_m ({far:g})"
        return ""

    return TunableTable(items, cross)


def policy_with(policy: FailsafePolicy, values: Mapping[str, float]) -> FailsafePolicy:
    """`policy` with the tunables in `values` (any subset) replaced."""
    top = {TOP[n][0]: float(v) for n, v in values.items() if n in TOP}
    stall = {CORE_STALL_KEYS[n]: (int(v) if STALL[n][4] else float(v)) for n, v in values.items() if n in STALL}
    rules = dict(policy.rules)
    for name, value in values.items():
        if name.startswith("events."):
            _, event, term = name.split(".")
            rules[event] = replace(rules[event], **{term: float(value)})
    return replace(policy, rules=rules, core_stall=replace(policy.core_stall, **stall), **top)
