"""ROS time stamps ↔ float seconds (the unit of every ROS-free c4d library)."""

from __future__ import annotations

import math

from builtin_interfaces.msg import Time


def stamp_to_s(stamp: Time) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def s_to_stamp(t: float) -> Time:
    sec = math.floor(t)
    return Time(sec=int(sec), nanosec=int(round((t - sec) * 1e9)) % 1_000_000_000)
