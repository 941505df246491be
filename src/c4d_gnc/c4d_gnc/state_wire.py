"""navigation/state written straight to CDR from a NavigationFilter: the navigation node's and `resim`'s.

Why apart from the node: re-simulation (c4d_resim) must write the same bytes the node published
for the same filter state — one function for both makes "bit-identical" a property of the code,
not of two copies kept in step. ~40 µs less per sample than filling a VehicleState and serializing it.
"""

from __future__ import annotations

import math

from c4d_interfaces.msg import VehicleState
from c4d_ros import cdr

from .navigation_filter import NavigationFilter

ALWAYS_VALID = (VehicleState.VALID_ATTITUDE | VehicleState.VALID_ANGULAR_VELOCITY | VehicleState.VALID_ACCELERATION
                | VehicleState.VALID_ANGULAR_ACCELERATION)
MAP_FRAME, BASE_LINK = cdr.text("map"), cdr.text("base_link")
STATE_FRAMES = (MAP_FRAME[0], BASE_LINK[0])  # the string lengths of navigation/state's CDR layout
VELOCITY_VALID = VehicleState.VALID_VELOCITY_XY | VehicleState.VALID_VELOCITY_Z
POSITION_VALID = VehicleState.VALID_POSITION_XY | VehicleState.VALID_POSITION_Z | VELOCITY_VALID


def state_cdr(filt: NavigationFilter, sec: int, nanosec: int, t: float) -> bytes:
    """The serialized c4d_interfaces/VehicleState of `filt`'s estimate, stamped with the IMU sample time."""
    ekf = filt.ekf
    valid = ALWAYS_VALID
    if ekf.heading_valid:
        valid |= VehicleState.VALID_HEADING
    if ekf.position_valid:
        valid |= POSITION_VALID
    elif ekf.velocity_valid:  # dead reckoning on drag fusion: the velocity without the position
        valid |= VELOCITY_VALID
    terrain = filt.terrain_distance(t)
    if not math.isnan(terrain):
        valid |= VehicleState.VALID_TERRAIN_DISTANCE
    origin = geodetic = (0.0, 0.0, 0.0)
    if ekf.origin is not None:
        valid |= VehicleState.VALID_ORIGIN
        o = ekf.origin
        origin = (o.latitude, o.longitude, o.altitude)
        if ekf.position_valid:
            valid |= VehicleState.VALID_GLOBAL
            geodetic = o.to_geodetic(*ekf.p)
    P = ekf.P
    qw, qx, qy, qz = ekf.q
    return cdr.VEHICLE_STATE.pack(
        STATE_FRAMES, sec, nanosec, *MAP_FRAME, *BASE_LINK, valid, *ekf.p.tolist(), *ekf.v.tolist(),
        *ekf.accel_world.tolist(), qx, qy, qz, qw, *filt.omega.tolist(), *filt.alpha.tolist(),
        *P[0:3, 0:3].ravel().tolist(), *P[3:6, 3:6].ravel().tolist(), *P[6:9, 6:9].ravel().tolist(),
        *ekf.bg.tolist(), *ekf.ba.tolist(), terrain, *origin, *geodetic,
        filt.horizontal.fusing(t), filt.height.fusing(t))
