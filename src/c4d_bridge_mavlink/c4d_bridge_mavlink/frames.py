"""Frame and mode conventions between c4d (ROS, REP-103/105) and MAVLink (PX4 flavour).

Frames: c4d positions/velocities are ENU in the local `map` frame and attitude is the rotation
body FLU → ENU; MAVLink's LOCAL_POSITION_NED is north-east-down and ATTITUDE(_QUATERNION) is the
rotation body FRD → NED. Both FLU→FRD and ENU→NED are 180° rotations, so
q_frd→ned = Q_ENU→NED ⊗ q_flu→enu ⊗ Q_FRD→FLU with fixed quaternions.

Modes: stock ground stations (QGroundControl, MAVSDK) decode HEARTBEAT.custom_mode with the PX4
layout for any autopilot that is not ArduPilot: main mode in bits 16–23, sub mode in bits
24–31. c4d reports its latched mode and navigation state in that layout and accepts
DO_SET_MODE requests in it.
"""

from __future__ import annotations

import math

from c4d_common import quat
from c4d_common.vehicle import Mode, Nav

Vec = tuple[float, float, float]
_S = math.sqrt(0.5)
Q_ENU_TO_NED: quat.Quat = (0.0, _S, _S, 0.0)  # 180° about the (1, 1, 0)/√2 axis: x↔y, z → −z
Q_FRD_TO_FLU: quat.Quat = (0.0, 1.0, 0.0, 0.0)  # 180° about x: y → −y, z → −z

# PX4 main modes and AUTO sub modes (px4_custom_mode.h)
PX4_MANUAL, PX4_ALTCTL, PX4_POSCTL, PX4_AUTO, PX4_ACRO, PX4_OFFBOARD, PX4_STABILIZED = 1, 2, 3, 4, 5, 6, 7
AUTO_READY, AUTO_TAKEOFF, AUTO_LOITER, AUTO_MISSION, AUTO_RTL, AUTO_LAND = 1, 2, 3, 4, 5, 6


def enu_to_ned(v: Vec) -> Vec:
    return (v[1], v[0], -v[2])


def flu_to_frd(v: Vec) -> Vec:
    return (v[0], -v[1], -v[2])


def ned_to_enu(v: Vec) -> Vec:
    """North-east-down → east-north-up (the same swap: the rotation is its own inverse)."""
    return (v[1], v[0], -v[2])


def frd_to_flu(v: Vec) -> Vec:
    return (v[0], -v[1], -v[2])


def attitude_to_ned(q_flu_enu: quat.Quat) -> quat.Quat:
    """Body FLU → ENU quaternion (w, x, y, z) to body FRD → NED, w ≥ 0."""
    q = quat.mul(quat.mul(Q_ENU_TO_NED, q_flu_enu), Q_FRD_TO_FLU)
    return q if q[0] >= 0 else (-q[0], -q[1], -q[2], -q[3])


def attitude_to_enu(q_frd_ned: quat.Quat) -> quat.Quat:
    """Body FRD → NED quaternion (w, x, y, z) to body FLU → ENU, w ≥ 0 (both fixed rotations are
    180° turns, their own inverses up to sign, so this is attitude_to_ned's formula)."""
    return attitude_to_ned(q_frd_ned)


def compass_heading_deg(q_flu_enu: quat.Quat) -> float:
    """Heading 0–360° clockwise from north (VFR_HUD, GLOBAL_POSITION_INT.hdg)."""
    return (90.0 - math.degrees(quat.yaw_of(q_flu_enu))) % 360.0


def px4_custom_mode(flight_mode: int, nav_state: int) -> int:
    """HEARTBEAT.custom_mode (PX4 layout) for a c4d mode / navigation state (c4d_common.vehicle Mode / Nav).

    AUTO with nothing to fly (NAV_NONE: disarmed, or armed on the ground before a take-off, e.g.
    after a landing) is AUTO.LOITER, PX4's Hold, as PX4 reports a landed vehicle: AUTO.READY is
    not a mode stock GCSs name (MAVProxy shows UNKNOWN). A go-to (NAV_GOTO outside a plan) is
    AUTO.LOITER too, as PX4 reports a reposition; NAV_RTL is AUTO.RTL."""
    if flight_mode == Mode.AUTO:
        sub = {Nav.TAKEOFF: AUTO_TAKEOFF, Nav.MISSION: AUTO_MISSION, Nav.HOLD: AUTO_LOITER, Nav.GOTO: AUTO_LOITER,
               Nav.RTL: AUTO_RTL, Nav.LAND: AUTO_LAND}.get(nav_state, AUTO_LOITER)
        return (PX4_AUTO << 16) | (sub << 24)
    main = {Mode.RATE: PX4_ACRO, Mode.ATTITUDE: PX4_STABILIZED, Mode.POSITION: PX4_POSCTL, Mode.KILL: PX4_MANUAL,
            Mode.OFFBOARD: PX4_OFFBOARD}
    return main.get(flight_mode, PX4_POSCTL) << 16


def decode_px4_mode(custom_mode: int) -> tuple[int, int]:
    """(main, sub) of a PX4 custom mode."""
    return (custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF


def mode_name(custom_mode: int) -> str:
    main, sub = decode_px4_mode(custom_mode)
    if main == PX4_AUTO:
        return "AUTO." + {AUTO_READY: "READY", AUTO_TAKEOFF: "TAKEOFF", AUTO_LOITER: "LOITER", AUTO_MISSION: "MISSION",
                          AUTO_RTL: "RTL", AUTO_LAND: "LAND"}.get(sub, f"{sub}")
    return {PX4_MANUAL: "MANUAL", PX4_ALTCTL: "ALTCTL", PX4_POSCTL: "POSCTL", PX4_ACRO: "ACRO",
            PX4_OFFBOARD: "OFFBOARD", PX4_STABILIZED: "STABILIZED"}.get(main, f"{main}")
