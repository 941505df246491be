"""The fence in force (geofence/active): the accepted plan's, or one set in flight (geofence/set).

Why a class of its own: three sources change the fence (a plan acceptance, geofence/set — which the
MAVLink fence upload calls — and a restart's journal), and every consumer (the core's barrier,
health's breach check, the offboard gateway's clamp, the bridge's FENCE_STATUS) must see the same
one. The rules, decided here and documented in docs/mission.md:

- A plan accepted with a fence of its own makes that fence the active one.
- geofence/set replaces the active fence at once (in flight too); an empty fence clears it. The
  set fence stays in force until a plan with its own (non-empty) fence is accepted: a plan without
  a fence uploaded after it is validated against it and carries it (mission/plan shows the fence
  the plan flies under). A plan without a fence replacing a plan's fence leaves no fence.
- A new fence is refused with a one-line reason when it is malformed (c4d_ros.plan_msgs
  geofence_from_msg) or when the vehicle is outside it (`breach`; the floor only while flying),
  unless forced (the core's barrier then pushes the vehicle back inside).
- Go-to targets and plans are validated against the active fence (plan_validation.check_goto /
  validate); a plan leg being flown that the new fence blocks (`leg_blocked`) pauses the mission
  (the arbiter asks the core to HOLD: the vehicle stops before the zone and never crosses it). A
  go-to or RTL is not stopped (checked or forced when commanded; an RTL returns from a breach).

ROS-free; unit-tested in test/test_fence.py. `revision` counts changes so the node publishes
geofence/active once per change.
"""

from __future__ import annotations

import math
from dataclasses import replace
from enum import Enum
from typing import Any

from c4d_common.geodesy import GeoOrigin
from c4d_common.geofence import LocalFence, point_inside
from c4d_common.plan import Geofence, Plan

Vec = tuple[float, float, float]


class FenceSource(Enum):
    """Where the active fence came from."""

    NONE = "none"  # nothing accepted or set yet
    PLAN = "plan"  # the accepted plan's
    SET = "set"  # geofence/set (or the MAVLink fence upload), in force until a plan brings its own


def refusal(fence: Geofence, force: bool, home: GeoOrigin | None, position: Vec, flying: bool) -> str:
    """Why `fence` must not replace the active one ("" when it may): the vehicle is outside it.
    Without a home position there is nothing to judge (the vehicle cannot be armed without one; the
    pre-arm check tests the fence then). An empty fence (a clear) is always accepted."""
    if fence.empty or force or home is None:
        return ""
    breach = LocalFence.from_geofence(fence, home).breach(position, with_floor=flying)
    if breach is None:
        return ""
    return f"the vehicle is outside the new fence ({breach.text}); set force to accept it"


def leg_blocked(fence: Geofence, home: GeoOrigin, start: Vec, end: Vec) -> str:
    """Why the straight leg start → end cannot be flown inside `fence` ("" when it can): it leaves
    the inclusion polygon, enters an exclusion zone, or ends further out beyond the maximum distance
    from home. A leg from where the vehicle already is outside (a fence set with force) is judged
    only by what it makes worse: out of the polygon any way back is fine, and the exclusion zone
    it starts in does not count."""
    if fence.empty:
        return ""
    local = LocalFence.from_geofence(fence, home)
    a, b = (start[0], start[1]), (end[0], end[1])
    inside_now = replace(local, polygon=(), max_distance=0.0).breach((*a, 0.0))  # the zone it is in, if any
    others = local if inside_now is None else replace(
        local, exclusion_polygons=tuple(p for p in local.exclusion_polygons if not point_inside(a, list(p))),
        exclusion_circles=tuple(c for c in local.exclusion_circles if math.dist(a, c[:2]) >= c[2]))
    zone = others.leg_exclusion(a, b)
    if zone:
        return f"enters the geofence's {zone}"
    if local.polygon and point_inside(a, list(local.polygon)) and not local.leg_inside(a, b):
        return "leaves the geofence polygon"
    if local.max_distance > 0 and math.hypot(*b) > max(local.max_distance, math.hypot(*a)):
        return f"ends beyond the geofence's {local.max_distance:g} m from home"
    return ""


class ActiveFence:
    """The fence in force and where it came from (module docstring for the rules)."""

    def __init__(self) -> None:
        self.fence = Geofence()
        self.source = FenceSource.NONE
        self.revision = 0  # +1 on every change (the node publishes geofence/active when it moves)

    def for_plan(self, plan: Plan) -> Plan:
        """The plan as it will be validated and flown: a plan without a fence of its own takes a
        fence set in flight."""
        if plan.geofence.empty and self.source == FenceSource.SET:
            return replace(plan, geofence=self.fence)
        return plan

    def plan_accepted(self, plan: Plan) -> None:
        """`plan` (as returned by for_plan) was accepted: its fence is in force — a set fence it
        inherited stays a set fence."""
        if self.source == FenceSource.SET and plan.geofence == self.fence:
            return
        self._change(plan.geofence, FenceSource.PLAN)

    def set(self, fence: Geofence) -> None:
        """geofence/set accepted `fence` (empty: clears the fence in force)."""
        self._change(fence, FenceSource.SET)

    def restore(self, fence: Geofence, source: FenceSource) -> None:
        """The fence persisted before a restart."""
        self._change(fence, source)

    def _change(self, fence: Geofence, source: FenceSource) -> None:
        self.fence, self.source = fence, source
        self.revision += 1


def geofence_from_dict(doc: dict[str, Any]) -> Geofence:
    """A Geofence from `dataclasses.asdict` (JSON lists back to tuples); the exclusion and floor
    fields are optional (journals written before issue 18 have none)."""
    def points(raw: Any) -> tuple[tuple[float, float], ...]:
        return tuple((float(a), float(b)) for a, b in raw)

    return Geofence(points(doc["polygon"]), float(doc["max_altitude"]), float(doc["max_distance"]),
                    tuple(points(p) for p in doc.get("exclusion_polygons", ())),
                    tuple((float(a), float(b), float(r)) for a, b, r in doc.get("exclusion_circles", ())),
                    float(doc.get("min_altitude", 0.0)))
