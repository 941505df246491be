"""MANUAL_CONTROL (pilot sticks) → a pilot setpoint for the core's RATE / ATTITUDE modes.

MAVLink sticks: x = pitch (forward stick +1000 = nose down), y = roll (+1000 = right wing down),
z = thrust (0 … 1000), r = yaw (+1000 = yaw right, clockwise from above), -1000 … 1000.
c4d setpoints are body FLU / world ENU: FLU roll + = right wing down (same sign as FRD),
FLU pitch + = nose down (rotation about the left axis), ENU yaw + = counter-clockwise, so the
yaw stick changes sign. Thrust is normalised collective: the stick's centre (500) is the
airframe's hover command and the ends are 0 and 1 (piecewise linear), so a centred stick holds
altitude roughly whatever the airframe.

Why here and pure: the sign conventions are exactly what a pilot feels first; they are unit
tested. The core already falls back to a level, gently sinking attitude when pilot input stops
(setpoint timeout), which is the loss-of-RC behaviour.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from c4d_common import quat
from c4d_common.vehicle import Mode

MAX_TILT = math.radians(30.0)  # full roll/pitch stick in ATTITUDE mode
MAX_RATE = math.radians(180.0)  # full stick in RATE mode (roll, pitch)
MAX_YAW_RATE = math.radians(120.0)


@dataclass(frozen=True)
class PilotSetpoint:
    level: str  # "attitude" | "rate"
    orientation: quat.Quat  # body FLU → ENU (attitude level)
    body_rate: tuple[float, float, float]  # FLU rad/s (rate level)
    yaw_rate: float  # ENU rad/s
    thrust: float  # [0, 1]


def _axis(value: float) -> float:
    return max(-1.0, min(1.0, value / 1000.0)) if math.isfinite(value) else 0.0


def stick_thrust(z: float, hover: float) -> float:
    """0 … 1000 → [0, 1] with 500 = hover (piecewise linear)."""
    u = max(0.0, min(1000.0, z)) if math.isfinite(z) else 500.0
    return hover * u / 500.0 if u <= 500.0 else hover + (1.0 - hover) * (u - 500.0) / 500.0


def pilot_setpoint(x: float, y: float, z: float, r: float, mode: str, yaw: float, hover: float) -> PilotSetpoint:
    """Setpoint for `mode` ("attitude" | "rate"); `yaw` = the attitude-mode heading target (ENU rad)."""
    roll, pitch, yaw_rate = _axis(y), _axis(x), -_axis(r) * MAX_YAW_RATE
    thrust = stick_thrust(z, hover)
    if mode == "rate":
        return PilotSetpoint("rate", quat.IDENTITY, (roll * MAX_RATE, pitch * MAX_RATE, yaw_rate), yaw_rate, thrust)
    return PilotSetpoint("attitude", quat.from_euler(roll * MAX_TILT, pitch * MAX_TILT, yaw), (0.0, 0.0, 0.0), yaw_rate,
                         thrust)


class PilotInput:
    """The MANUAL_CONTROL stream → pilot setpoints, only in the core's RATE / ATTITUDE modes (the
    core ignores other levels there, and other modes ignore pilot setpoints).

    Why a class: the attitude-mode heading target is integrated from the yaw stick between frames
    and re-taken from the vehicle whenever the pilot (re)enters manual control (> 0.5 s gap)."""

    LEVELS = {Mode.RATE: "rate", Mode.ATTITUDE: "attitude"}

    def __init__(self, hover: float) -> None:
        self.hover = hover  # the airframe's hover command: the thrust stick's centre
        self.yaw = math.nan  # ENU rad, attitude-mode heading target
        self.t = -math.inf  # time of the last used frame [s]
        self.ignored = 0
        self.used = 0

    def setpoint(self, x: float, y: float, z: float, r: float, flight_mode: int, orientation: quat.Quat | None,
                 now: float) -> PilotSetpoint | None:
        """The setpoint for one MANUAL_CONTROL frame, or None when the vehicle is not in a pilot mode."""
        mode = self.LEVELS.get(flight_mode)
        if mode is None or orientation is None:
            self.ignored += 1
            return None
        if now - self.t > 0.5 or not math.isfinite(self.yaw):  # (re)entering manual: hold the current heading
            self.yaw = quat.yaw_of(orientation)
        dt = min(0.1, max(0.0, now - self.t))
        self.t = now
        sp = pilot_setpoint(x, y, z, r, mode, self.yaw, self.hover)
        self.yaw = math.remainder(self.yaw + sp.yaw_rate * dt, math.tau)
        self.used += 1
        return sp
