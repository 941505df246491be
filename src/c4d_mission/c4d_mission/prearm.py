"""Pre-arm checks: what must hold before the mission node forwards an ARM (or TAKEOFF) to the core.

Why a class of its own: the checks are the vehicle's last gate on the ground, so they are tested
without ROS (test_prearm.py) and every refusal is typed — a kind for decisions, a text for the
operator (the node answers "pre-arm check failed: <text>"). A forced ARM skips them (the node
decides; the core still applies its own checks).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum

from c4d_common.geofence import BreachKind, LocalFence, Point3


class RefusalKind(Enum):
    ESTIMATOR_NOT_READY = "estimator not ready"
    SENSORS_UNHEALTHY = "sensors not healthy"
    GNSS_UNTRUSTED = "GNSS not trusted"
    BATTERY_LOW = "battery low"
    OUTSIDE_GEOFENCE = "outside the geofence"


@dataclass(frozen=True)
class Refusal:
    """Why the vehicle may not arm: `kind` for decisions, `text` for the operator."""

    kind: RefusalKind
    text: str

    def __str__(self) -> str:
        return self.text


@dataclass(frozen=True)
class PreArmInputs:
    """What the checks look at, taken from the latest messages by the node."""

    estimator_ready: bool  # attitude, horizontal position and home (origin) all valid
    position: Point3  # local ENU [m] from home
    sensor_ok: Mapping[str, bool] = field(default_factory=dict)  # sensor name -> healthy (perception/health)
    battery_fraction: float | None = None  # remaining charge 0..1, None before the first battery message
    fence: LocalFence | None = None  # the loaded plan's geofence in the home frame, None without a plan or home
    unused_sensors: frozenset[str] = frozenset()  # position sources the navigation does not fuse now (navigation/state)
    gnss_untrusted: str = ""  # the integrity verdict ("spoofed", "jammed") while the estimate depends on GNSS; "" = fine


class PreArmChecks:
    """Estimator ready, every sensor the estimate depends on healthy, GNSS trusted if it depends on it,
    battery above the reserve, inside the geofence —
    checked in that order; the first failing rule is the refusal."""

    def __init__(self, min_battery: float) -> None:
        self.min_battery = min_battery  # remaining-charge fraction below which arming is refused

    def check(self, inputs: PreArmInputs) -> Refusal | None:
        if not inputs.estimator_ready:
            return Refusal(RefusalKind.ESTIMATOR_NOT_READY, "estimator not ready (attitude, position and home needed)")
        # a GNSS-denied setup (external pose, docs/navigation.md) arms without a fix: only the sensors
        # the estimate depends on now must be healthy
        unhealthy = sorted(name for name, ok in inputs.sensor_ok.items() if not ok and name not in inputs.unused_sensors)
        if unhealthy:
            return Refusal(RefusalKind.SENSORS_UNHEALTHY, f"sensors not healthy: {', '.join(unhealthy)}")
        if inputs.gnss_untrusted:
            # taking off into a gnss_spoofed / gnss_jammed failsafe (hold, then land) helps nobody
            return Refusal(RefusalKind.GNSS_UNTRUSTED, f"GNSS {inputs.gnss_untrusted} (integrity monitor): wait until it "
                                                       "clears or fly on another source")
        battery = inputs.battery_fraction
        if battery is not None and battery < self.min_battery:
            return Refusal(RefusalKind.BATTERY_LOW, f"battery at {battery:.0%}, below the {self.min_battery:.0%} reserve")
        breach = inputs.fence.breach(inputs.position) if inputs.fence is not None else None
        if breach is not None:
            # the polygon keeps the words operators know; a ceiling or distance breach says which
            text = "outside the geofence" if breach.kind == BreachKind.POLYGON else f"outside the geofence: {breach.text}"
            return Refusal(RefusalKind.OUTSIDE_GEOFENCE, text)
        return None
