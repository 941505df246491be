"""Setpoint ownership: which source steers the cascade, chosen by the mode — and the offboard stream's proof of life.

Why: three sources publish setpoints (the mission node on guidance/setpoint, the MAVLink pilot on
guidance/pilot, the offboard gateway on guidance/offboard). Exactly one may steer at a time, and the
mode decides which (PX4 does the same with its nav state), so a forgotten publisher can never fight
the owner. A setpoint from a source that does not own the stream is ignored and counted (the count
is in vehicle/status). The offboard stream is the exception to counting: it must be live *before*
OFFBOARD is entered (PX4: setpoints for >= 1 s at >= 2 Hz), so its samples outside OFFBOARD are its
proof of life, not a fight.

ROS-free; the core node calls `receive()` from its input phase, GncCore reads `latest()`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Generic, TypeVar

from c4d_common.vehicle import Mode, Nav, SetpointSource

Setpoint = TypeVar("Setpoint")  # gnc.Setpoint; generic here so that gnc can import this module without a cycle

OFFBOARD_MAX_GAP_S = 0.5  # a longer gap between offboard setpoints breaks the stream (>= 2 Hz keeps it live)
OFFBOARD_ENTRY_S = 1.0  # OFFBOARD is entered only after the stream has been live this long
FOLLOWING_NAV = (Nav.MISSION, Nav.GOTO, Nav.RTL)  # AUTO states that follow the mission's setpoints


def owner(mode: Mode, nav: Nav) -> SetpointSource:
    """The source that owns the setpoint stream in this mode (CORE: the core's own targets)."""
    if mode == Mode.OFFBOARD:
        return SetpointSource.OFFBOARD
    if mode in (Mode.RATE, Mode.ATTITUDE):
        return SetpointSource.PILOT
    if mode == Mode.AUTO and nav in FOLLOWING_NAV:
        return SetpointSource.MISSION
    return SetpointSource.CORE


@dataclass
class StreamLiveness:
    """When an unbroken stream (gaps <= max_gap_s, arrival times on the core's clock) started and last arrived."""

    max_gap_s: float = OFFBOARD_MAX_GAP_S
    start: float = -1.0
    last: float = -1.0

    def arrived(self, now: float) -> None:
        if self.last < 0 or now - self.last > self.max_gap_s:
            self.start = now
        self.last = now

    def live_for(self, now: float) -> float:
        """[s] how long the stream has been live at `now`; 0 when it is not live."""
        if self.last < 0 or now - self.last > self.max_gap_s:
            return 0.0
        return self.last - self.start


@dataclass
class SetpointInputs(Generic[Setpoint]):
    """The newest setpoint of each source, the ignored count and the offboard stream's liveness."""

    newest: dict[SetpointSource, Setpoint] = field(default_factory=dict)
    ignored: int = 0
    offboard: StreamLiveness = field(default_factory=StreamLiveness)

    def receive(self, source: SetpointSource, setpoint: Setpoint, now: float, current_owner: SetpointSource) -> bool:
        """Take one setpoint from `source` arriving at `now`; False (and counted) when `source` does not own the
        stream — except the offboard stream, whose samples before OFFBOARD are its required proof of life."""
        if source == SetpointSource.OFFBOARD:
            self.offboard.arrived(now)
        elif source != current_owner:
            self.ignored += 1
            return False
        self.newest[source] = setpoint
        return True

    def latest(self, source: SetpointSource) -> Setpoint | None:
        return self.newest.get(source)
