"""Failsafe event evaluation: which monitored conditions are true right now.

What: `evaluate(snapshot, policy, t)` turns a `HealthSnapshot` (the latest of everything the
health node hears: dead, stalled and inactive (lifecycle) nodes, GNSS health, the estimate, battery, the fence in
force (geofence/active: inclusion polygon, ceiling, distance, exclusion zones, and the floor while
flying), the ground link, executor overruns, core stalls, the offboard stream, the perceived
obstacles, the navigation's horizontal source and GNSS integrity verdict (navigation/status)) into
the active events, each with a detail for people: `{Event.BATTERY_LOW: "28%"}`. The
`FailsafeArbiter` (policy.py) then decides the action.

GNSS integrity: a SPOOFED / JAMMED verdict is `gnss_spoofed` / `gnss_jammed` when no other healthy
horizontal source is in use (the position rests on dead reckoning or on the distrusted GNSS: the
policy holds, then lands), and `gnss_spoofed_switched` / `gnss_jammed_switched` when the
navigation flies on a healthy external source (it already switched: the policy warns). Two events,
not one with two actions, so that each case keeps the policy's plain event → rule form. For the
same reason `gps_loss` does not fire while a healthy non-GNSS source is in use (GNSS disabled from
boot with an external pose is a valid configuration).

Why a pure function over a snapshot: every failsafe condition is tested without DDS
(test/test_events.py), and the node only copies messages into the snapshot. Decisions use the
typed fields (levels, flags, `BreachKind`), never the wording of a message; the geofence is the
one check pre-flight validation uses too (`c4d_common.geofence.LocalFence`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from c4d_common.geodesy import GeoOrigin
from c4d_common.geofence import LocalFence, Point3
from c4d_common.plan import Geofence

from .core_stall import CoreStallReport
from .policy import Event, FailsafePolicy

LINK_TIMEOUT_S = 3.0  # no heartbeat on the link topic for this long: link lost
Circle = tuple[float, float, float]  # an obstacle's horizontal bounding circle: east, north, radius [m]


@dataclass(frozen=True)
class GnssReport:
    """perception/health's `gps` status: ok (diagnostic level OK) and its message."""

    ok: bool
    message: str


@dataclass(frozen=True)
class Estimate:
    """What health needs of navigation/state."""

    attitude_valid: bool
    position_xy_valid: bool
    position: Point3  # ENU [m] from home
    home: GeoOrigin | None  # the estimator's origin; None while it is not set


# VehicleState.SOURCE_* and GnssIntegrity.STATE_* (test_events checks the values against c4d_interfaces)
SOURCE_NONE, SOURCE_GNSS, SOURCE_EXTERNAL = 0, 1, 2
GNSS_SPOOFED, GNSS_JAMMED = 3, 4
SOURCE_NAMES = {SOURCE_NONE: "dead reckoning", SOURCE_GNSS: "GNSS", SOURCE_EXTERNAL: "external"}


@dataclass(frozen=True)
class NavigationStatus:
    """What health needs of navigation/status: the horizontal source in use, the external input's
    health and the GNSS integrity verdict (state, score, the tests in alarm as text)."""

    horizontal_source: int  # SOURCE_*
    external_healthy: bool
    gnss_state: int  # GnssIntegrity.STATE_*
    gnss_score: float = 0.0
    gnss_alarms: str = ""  # e.g. "inertial, jump"

    @property
    def backed(self) -> bool:
        """The horizontal position is fused from a healthy source other than GNSS (only the external
        pose is one today): losing or distrusting GNSS does not take the position away."""
        return self.horizontal_source == SOURCE_EXTERNAL and self.external_healthy

    @property
    def source_name(self) -> str:
        return SOURCE_NAMES.get(self.horizontal_source, f"source {self.horizontal_source}")


@dataclass(frozen=True)
class LinkWatch:
    """The ground-link heartbeat topic and when it was last heard (None: never)."""

    topic: str
    last_heard: float | None


@dataclass(frozen=True)
class OffboardWatch:
    """The core's mode is OFFBOARD (vehicle/status) and when guidance/offboard was last heard, in
    the monitor's running time (its own stalls discounted, liveness.py)."""

    in_offboard: bool
    last_heard: float


@dataclass(frozen=True)
class HealthSnapshot:
    """The latest state the monitors judge; None = nothing received (no event)."""

    dead_nodes: tuple[str, ...] = ()  # sorted
    gnss: GnssReport | None = None
    estimate: Estimate | None = None
    battery_soc: float | None = None  # state of charge 0..1, NaN = unknown
    geofence: Geofence | None = None  # in force (geofence/active)
    link: LinkWatch | None = None  # None: the link is not watched
    new_overruns: int = 0  # executor overruns since the previous statistics message
    stalled_nodes: tuple[str, ...] = ()  # sorted; silent but still in the ROS graph
    core_stall: CoreStallReport | None = None
    offboard: OffboardWatch | None = None  # None: the core's mode not known yet
    flying: bool = False  # in the air, not taking off or landing: the fence's floor applies
    obstacles: tuple[Circle, ...] | None = None  # perception/surroundings (east, north, radius); None: none heard
    navigation: NavigationStatus | None = None  # navigation/status; None: not heard (no GNSS integrity events)
    inactive_nodes: tuple[str, ...] = ()  # sorted "name (state)": left ACTIVE (lifecycle_watch.py)


def nearest_obstacle(position: Point3, obstacles: tuple[Circle, ...]) -> float:
    """The horizontal distance [m] from `position` to the nearest obstacle surface (inf: none; 0 inside one)."""
    return min((max(0.0, math.hypot(position[0] - x, position[1] - y) - r) for x, y, r in obstacles), default=math.inf)


def evaluate(snapshot: HealthSnapshot, policy: FailsafePolicy, t: float) -> dict[str, str]:
    """Active events at time `t` [s] → detail, in `Event` order (the arbiter's tie-break)."""
    active: dict[str, str] = {}
    s = snapshot
    if s.dead_nodes:
        active[Event.NODE_DEAD] = ", ".join(s.dead_nodes)
    if s.stalled_nodes:
        active[Event.NODE_STALLED] = ", ".join(s.stalled_nodes)
    if s.inactive_nodes:
        active[Event.NODE_INACTIVE] = ", ".join(s.inactive_nodes)
    backed = s.navigation is not None and s.navigation.backed
    if s.gnss is not None and not s.gnss.ok and not backed:  # GNSS disabled + external pose is a valid setup
        active[Event.GPS_LOSS] = f"GNSS {s.gnss.message}"
    if s.estimate is not None and not (s.estimate.attitude_valid and s.estimate.position_xy_valid):
        active[Event.ESTIMATOR_INVALID] = "position or attitude estimate not valid"
    if s.battery_soc is not None and math.isfinite(s.battery_soc):
        if s.battery_soc < policy.battery_critical:
            active[Event.BATTERY_CRITICAL] = f"{s.battery_soc:.0%}"
        elif s.battery_soc < policy.battery_low:
            active[Event.BATTERY_LOW] = f"{s.battery_soc:.0%}"
    if s.geofence is not None and s.estimate is not None and s.estimate.home is not None:
        breach = LocalFence.from_geofence(s.geofence, s.estimate.home).breach(s.estimate.position, with_floor=s.flying)
        if breach is not None:
            active[Event.GEOFENCE_BREACH] = breach.text
    if s.link is not None and (s.link.last_heard is None or t - s.link.last_heard > LINK_TIMEOUT_S):
        active[Event.LINK_LOSS] = f"no heartbeat on {s.link.topic} for {LINK_TIMEOUT_S:g} s"
    if s.new_overruns:
        active[Event.EXECUTOR_OVERRUN] = f"{s.new_overruns} new overrun(s)"
    if s.core_stall is not None and s.core_stall.stall:
        active[Event.CORE_STALL] = s.core_stall.stall
    if s.core_stall is not None and s.core_stall.repeated:
        active[Event.CORE_STALL_REPEATED] = s.core_stall.repeated
    if s.offboard is not None and s.offboard.in_offboard and t - s.offboard.last_heard > policy.offboard_loss_timeout_s:
        active[Event.OFFBOARD_LOSS] = f"no offboard setpoint for {t - s.offboard.last_heard:.1f} s in OFFBOARD"
    if s.obstacles and s.estimate is not None and s.estimate.position_xy_valid:
        distance = nearest_obstacle(s.estimate.position, s.obstacles)
        if distance < policy.obstacle_protection_radius_m:
            active[Event.OBSTACLE_COLLISION_RISK] = f"obstacle {distance:.2f} m away (protection radius " \
                                                    f"{policy.obstacle_protection_radius_m:g} m)"
        elif distance < policy.obstacle_detection_range_m:
            active[Event.OBSTACLE_NEAR] = f"obstacle {distance:.1f} m away"
    if s.navigation is not None and s.navigation.gnss_state in (GNSS_SPOOFED, GNSS_JAMMED):
        nav = s.navigation
        spoofed = nav.gnss_state == GNSS_SPOOFED
        what = f"GNSS {'spoofed' if spoofed else 'jammed'} ({nav.gnss_alarms or 'alarm'}, score {nav.gnss_score:.1f})"
        if backed:
            active[Event.GNSS_SPOOFED_SWITCHED if spoofed else Event.GNSS_JAMMED_SWITCHED] = \
                f"{what}; navigation on the {nav.source_name} source"
        else:
            active[Event.GNSS_SPOOFED if spoofed else Event.GNSS_JAMMED] = \
                f"{what}; no other healthy horizontal source (on {nav.source_name})"
    return active
