"""The offboard gateway's decisions, free of ROS: is an external setpoint usable, and what goes on.

Why here and not in the node: every rule the public API promises (docs/offboard.md) — levels,
NaN/inf per level, frames, stamp age, the geofence clamp, the rate limit, the action's claim —
is decided in one place, with typed reasons (`Reject`), and unit-tested without a graph. The node
(offboard_node.py) only converts messages to `Setpoint`, calls `Gateway.offer`, and publishes.

Conventions are GuidanceSetpoint's: world frame `map` local ENU, body FLU, NaN = unset, angles
in rad, quaternions (w, x, y, z) body → world.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from enum import Enum, IntEnum
from typing import Protocol

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]  # (w, x, y, z)
NAN = math.nan
NAN3: Vec3 = (NAN, NAN, NAN)
WORLD_FRAME = "map"
BODY_FRAME = "base_link"
MIN_QUATERNION_NORM = 1e-6  # below this a quaternion has no direction to normalise to
RATE_BURST = 2.0  # the rate limiter lets this many setpoints through back to back (jitter of a stream at the limit)


class Level(IntEnum):
    """GuidanceSetpoint.LEVEL_*: which loop of the core's cascade the setpoint enters."""

    POSITION = 1
    VELOCITY = 2
    ACCELERATION = 3
    ATTITUDE = 4
    RATE = 5


LEVELS = frozenset(int(level) for level in Level)


class Reject(Enum):
    """Why a setpoint was not forwarded (the value is the key counted in offboard/status)."""

    ACTION_ACTIVE = "action_active"  # an action owns the stream (SetpointSink.claim)
    UNKNOWN_LEVEL = "unknown_level"  # control_level is none of LEVEL_*
    FRAME = "frame"  # header.frame_id not `map` (twist: `map` or `base_link`)
    INFINITE = "inf"  # +-inf in any field
    MISSING = "nan_required"  # NaN in a field the level needs
    QUATERNION = "bad_quaternion"  # attitude quaternion of (near) zero norm
    THRUST = "thrust_range"  # thrust outside [0, 1]
    UNSTAMPED = "unstamped"  # header.stamp zero
    STALE = "stale"  # stamp older than max_age_s
    FUTURE = "future"  # stamp more than max_future_s ahead
    NO_HEADING = "no_heading"  # a base_link twist before the estimate has a heading to rotate it by


@dataclass(frozen=True)
class Setpoint:
    """A GuidanceSetpoint as plain values (see GuidanceSetpoint.msg for each field's meaning)."""

    level: int
    frame: str
    stamp_s: float
    position: Vec3 = NAN3
    velocity: Vec3 = NAN3
    acceleration: Vec3 = NAN3
    yaw: float = NAN
    yaw_rate: float = NAN
    orientation: Quat = (1.0, 0.0, 0.0, 0.0)
    body_rate: Vec3 = NAN3
    thrust: float = NAN
    max_horizontal_speed: float = NAN
    max_vertical_speed: float = NAN

    def values(self) -> tuple[float, ...]:
        """Every number of the setpoint (for the inf check)."""
        return (*self.position, *self.velocity, *self.acceleration, self.yaw, self.yaw_rate, *self.orientation,
                *self.body_rate, self.thrust, self.max_horizontal_speed, self.max_vertical_speed)


def _finite(values: tuple[float, ...]) -> bool:
    return all(math.isfinite(v) for v in values)


def check_content(sp: Setpoint) -> Reject | None:
    """The level, frame and field rules (everything but the stamp); None when usable."""
    if sp.level not in LEVELS:
        return Reject.UNKNOWN_LEVEL
    if sp.frame != WORLD_FRAME:
        return Reject.FRAME
    if any(math.isinf(v) for v in sp.values()):
        return Reject.INFINITE
    if sp.level == Level.POSITION:
        usable = all(math.isfinite(p) or math.isfinite(v) for p, v in zip(sp.position, sp.velocity, strict=True))
        return None if usable else Reject.MISSING
    if sp.level == Level.VELOCITY:
        return None if _finite(sp.velocity) else Reject.MISSING
    if sp.level == Level.ACCELERATION:
        return None if _finite(sp.acceleration) else Reject.MISSING
    if sp.level == Level.ATTITUDE:
        if not _finite(sp.orientation):
            return Reject.MISSING
        if math.sqrt(sum(c * c for c in sp.orientation)) < MIN_QUATERNION_NORM:
            return Reject.QUATERNION
    elif not _finite(sp.body_rate):  # RATE
        return Reject.MISSING
    if not math.isfinite(sp.thrust):
        return Reject.MISSING
    return None if 0.0 <= sp.thrust <= 1.0 else Reject.THRUST


def check_stamp(stamp_s: float, now_s: float, max_age_s: float, max_future_s: float) -> Reject | None:
    """A stamp of zero, older than max_age_s or more than max_future_s ahead of now is refused."""
    if stamp_s == 0.0:
        return Reject.UNSTAMPED
    if now_s - stamp_s > max_age_s:
        return Reject.STALE
    if stamp_s - now_s > max_future_s:
        return Reject.FUTURE
    return None


def normalised(sp: Setpoint) -> Setpoint:
    """An ATTITUDE setpoint's quaternion scaled to unit norm (the core expects a unit quaternion)."""
    if sp.level != Level.ATTITUDE:
        return sp
    n = math.sqrt(sum(c * c for c in sp.orientation))
    w, x, y, z = sp.orientation
    return replace(sp, orientation=(w / n, x / n, y / n, z / n))


def body_to_world(v: Vec3, yaw: float) -> Vec3:
    """A FLU body-frame velocity in ENU, rotated by the heading only (z stays vertical): what a
    `base_link` twist means for a multirotor — forward/left in the horizontal plane."""
    c, s = math.cos(yaw), math.sin(yaw)
    return (c * v[0] - s * v[1], s * v[0] + c * v[1], v[2])


class Fence(Protocol):
    """What the gateway needs of a geofence (c4d_common.geofence.LocalFence)."""

    def clamp(self, position: Vec3, margin: float = ...) -> Vec3: ...


def clamp_to_fence(sp: Setpoint, fence: Fence) -> Setpoint | None:
    """The POSITION setpoint with its position target moved inside `fence`, or None when nothing
    changed. Unset axes stay unset (a NaN horizontal axis leaves the horizontal check out)."""
    if sp.level != Level.POSITION:
        return None
    x, y, z = sp.position
    horizontal = math.isfinite(x) and math.isfinite(y)
    vertical = math.isfinite(z)
    cx, cy, cz = fence.clamp((x if horizontal else 0.0, y if horizontal else 0.0, z if vertical else -math.inf))
    target = (cx if horizontal else x, cy if horizontal else y, cz if vertical else z)
    if target == sp.position or (not horizontal and not vertical):
        return None
    return replace(sp, position=target)


class RateLimiter:
    """Token bucket: at most `rate_hz` on average, `burst` back to back. Why a bucket and not a
    minimum interval: a stream at exactly the limit arrives with jitter, and an interval check
    would drop the early half of its samples."""

    def __init__(self, rate_hz: float, burst: float = RATE_BURST) -> None:
        self.rate_hz, self.burst = rate_hz, burst
        self.tokens, self.t = burst, -math.inf

    def allow(self, t: float) -> bool:
        """One setpoint at monotonic time `t` [s]: may it go on?"""
        self.tokens = min(self.burst, self.tokens + (t - self.t) * self.rate_hz) if self.t > -math.inf else self.burst
        self.t = t
        if self.tokens >= 1.0:
            self.tokens -= 1.0
            return True
        return False


@dataclass(frozen=True)
class Limits:
    """The gateway's parameters (offboard node: max_age_s, max_future_s, max_rate_hz, live_timeout_s)."""

    max_age_s: float = 0.5
    max_future_s: float = 0.1
    max_rate_hz: float = 100.0
    live_timeout_s: float = 0.5


@dataclass(frozen=True)
class Decision:
    """What became of one offered setpoint: forwarded (`setpoint`, possibly clamped) or not (`reason`,
    or `rate_limited`)."""

    setpoint: Setpoint | None
    reason: Reject | None = None
    clamped: bool = False
    rate_limited: bool = False


@dataclass
class Counters:
    """Totals since start, as offboard/status reports them."""

    received: int = 0
    accepted: int = 0
    rate_limited: int = 0
    clamped: int = 0
    action_setpoints: int = 0
    rejected: dict[Reject, int] = field(default_factory=lambda: dict.fromkeys(Reject, 0))

    @property
    def rejected_total(self) -> int:
        return sum(self.rejected.values())


class Gateway:
    """External and action setpoints in, the setpoints to publish on guidance/offboard out.

    `offer` (external input, checked in this order: action claim, content, stamp, rate, fence)
    and `offer_action` (an action server's own setpoint: no stamp check, no rate limit) count every
    outcome; `fence` is the active plan's fence in the home frame (None: no clamp)."""

    def __init__(self, limits: Limits | None = None) -> None:
        self.limits = limits or Limits()
        self.rate = RateLimiter(self.limits.max_rate_hz)
        self.counters = Counters()
        self.fence: Fence | None = None
        self.owner: str | None = None
        self.last_forward_t = -math.inf  # monotonic time of the last external setpoint forwarded

    def set_limits(self, limits: Limits) -> None:
        self.limits = limits
        self.rate.rate_hz = limits.max_rate_hz

    def refuse(self, reason: Reject) -> Decision:
        """Count an input refused before it became a Setpoint (e.g. NO_HEADING)."""
        self.counters.received += 1
        return self._rejected(reason)

    def _rejected(self, reason: Reject) -> Decision:
        self.counters.rejected[reason] += 1
        return Decision(None, reason)

    def offer(self, sp: Setpoint, now_s: float, t_mono: float) -> Decision:
        """An external setpoint at node time `now_s` (compared with its stamp) and monotonic time
        `t_mono` (rate limit, liveness)."""
        self.counters.received += 1
        if self.owner is not None:
            return self._rejected(Reject.ACTION_ACTIVE)
        reason = check_content(sp) or check_stamp(sp.stamp_s, now_s, self.limits.max_age_s, self.limits.max_future_s)
        if reason is not None:
            return self._rejected(reason)
        if not self.rate.allow(t_mono):
            self.counters.rate_limited += 1
            return Decision(None, rate_limited=True)
        out, clamped = self._clamped(normalised(sp))
        self.counters.accepted += 1
        self.last_forward_t = t_mono
        return Decision(out, clamped=clamped)

    def offer_action(self, sp: Setpoint) -> Decision:
        """An action server's setpoint (SetpointSink.publish_action_setpoint)."""
        reason = check_content(sp)
        if reason is not None:
            return self._rejected(reason)
        out, clamped = self._clamped(normalised(sp))
        self.counters.action_setpoints += 1
        return Decision(out, clamped=clamped)

    def _clamped(self, sp: Setpoint) -> tuple[Setpoint, bool]:
        inside = clamp_to_fence(sp, self.fence) if self.fence is not None else None
        if inside is None:
            return sp, False
        self.counters.clamped += 1
        return inside, True

    def live(self, t_mono: float) -> bool:
        """An external stream is being forwarded (the last one within live_timeout_s)."""
        return t_mono - self.last_forward_t <= self.limits.live_timeout_s

    def status(self, t_mono: float) -> dict[str, str]:
        """offboard/status key-values: stream, owner and every counter (rejected_<reason> each)."""
        c = self.counters
        values = {"stream_live": str(self.live(t_mono)).lower(), "action_owner": self.owner or "",
                  "fence": "active" if self.fence is not None else "none", "received": str(c.received),
                  "accepted": str(c.accepted), "rejected": str(c.rejected_total), "rate_limited": str(c.rate_limited),
                  "clamped": str(c.clamped), "action_setpoints": str(c.action_setpoints),
                  "max_rate_hz": f"{self.limits.max_rate_hz:g}"}
        values.update({f"rejected_{reason.value}": str(n) for reason, n in c.rejected.items()})
        return values
