"""The core's conversions of its slow inputs (obstacles, geofence), shared by the core node and `resim`.

Why a module of their own: re-simulation (c4d_resim) must turn the recorded perception/surroundings
and geofence/active messages into the blackboard exactly as the node did; one function each keeps
the two identical. Message objects in, c4d_common types out; no rclpy node.
"""

from __future__ import annotations

import math

from c4d_common.barrier import FenceGeometry, Obstacle
from c4d_common.geodesy import GeoOrigin
from c4d_common.plan import Geofence

SCAN_AGE_S = 0.5  # a scan stamp older (or newer) than this against the arrival time is replaced by it


def obstacles_from_msg(msg, now: float) -> tuple[Obstacle, ...]:
    """c4d_interfaces/Surroundings as the barrier's cylinders (local ENU), stamped with the scan's time when it
    is plausible (movers are extrapolated from it), else with the arrival time `now`."""
    stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
    if not 0.0 <= now - stamp <= SCAN_AGE_S:
        stamp = now
    return tuple(
        Obstacle(int(o.id), o.position.x, o.position.y, float(o.radius), o.velocity.x, o.velocity.y,
                 float(o.height) if math.isfinite(o.height) and o.height > 0 else math.inf, stamp)
        for o in msg.obstacles if math.isfinite(o.position.x) and math.isfinite(o.position.y) and o.radius >= 0)


def fence_local(geofence: Geofence, origin: tuple[float, float, float]) -> FenceGeometry | None:
    """The fence in local ENU around `origin` (home); None for an empty fence."""
    return None if geofence.empty else FenceGeometry.from_geofence(geofence, GeoOrigin(*origin))
