"""ESTIMATOR_STATUS (#230) from navigation/state + navigation/status, ROS-free.

What: `NavigationView` holds what the bridge heard (VehicleState validity bits and position sigmas,
EstimatorStatus sources and GNSS integrity); `estimator_status(view, time_usec)` encodes it:
- flags: ATTITUDE ← VALID_ATTITUDE, VELOCITY_HORIZ / _VERT ← VALID_VELOCITY_XY / _Z,
  POS_HORIZ_REL (and PRED_POS_HORIZ_REL) ← VALID_POSITION_XY, POS_HORIZ_ABS (and PRED_…_ABS) ←
  VALID_GLOBAL, POS_VERT_ABS ← VALID_POSITION_Z, POS_VERT_AGL ← VALID_TERRAIN_DISTANCE,
  CONST_POS_MODE ← attitude valid but no horizontal source fused (dead reckoning),
  GPS_GLITCH ← the GNSS integrity verdict is SPOOFED (fixes not fused);
- pos_horiz_ratio = the integrity monitor's score (max over its tests of statistic / alarm
  threshold: ≥ 1 = alarm, as PX4's innovation test ratios, where ≥ 1 means rejected); the other
  ratios are 0 (c4d does not compute them);
- pos_horiz_accuracy / pos_vert_accuracy = 1σ of the estimate's position covariance [m].
Why here: PX4 users watch ESTIMATOR_STATUS (QGC's EKF widget, MAVSDK telemetry) to see whether
the estimate is trustworthy and whether GPS is being rejected; c4d says the same things there.

GNSS_INTEGRITY (#441, the spoofing / jamming state message) exists only in the *development*
dialect of the pinned pymavlink 2.4.50, not in common: the bridge does not send it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .signing import mavlink

M = mavlink
# VehicleState.VALID_* (c4d_interfaces/msg/VehicleState.msg; test_estimator_status checks the values)
VALID_POSITION_XY, VALID_POSITION_Z, VALID_VELOCITY_XY, VALID_VELOCITY_Z = 1, 2, 4, 8
VALID_ATTITUDE, VALID_GLOBAL, VALID_TERRAIN_DISTANCE = 32, 512, 2048
SOURCE_NONE = 0  # VehicleState.SOURCE_NONE
STATE_SPOOFED = 3  # GnssIntegrity.STATE_SPOOFED
FLAG_OF_VALID = ((VALID_ATTITUDE, M.ESTIMATOR_ATTITUDE), (VALID_VELOCITY_XY, M.ESTIMATOR_VELOCITY_HORIZ),
                 (VALID_VELOCITY_Z, M.ESTIMATOR_VELOCITY_VERT),
                 (VALID_POSITION_XY, M.ESTIMATOR_POS_HORIZ_REL | M.ESTIMATOR_PRED_POS_HORIZ_REL),
                 (VALID_GLOBAL, M.ESTIMATOR_POS_HORIZ_ABS | M.ESTIMATOR_PRED_POS_HORIZ_ABS),
                 (VALID_POSITION_Z, M.ESTIMATOR_POS_VERT_ABS), (VALID_TERRAIN_DISTANCE, M.ESTIMATOR_POS_VERT_AGL))


@dataclass
class NavigationView:
    """The estimator's latest state as the bridge heard it; `state_heard` False = nothing to report."""

    state_heard: bool = False
    valid: int = 0  # VehicleState.valid
    sigma_h: float = math.nan  # [m] 1σ horizontal (mean of the x, y variances)
    sigma_v: float = math.nan  # [m]
    status_heard: bool = False  # navigation/status
    horizontal_source: int = SOURCE_NONE
    height_source: int = SOURCE_NONE
    gnss_state: int = 0  # GnssIntegrity.STATE_*
    gnss_score: float = 0.0


def flags_of(view: NavigationView) -> int:
    """ESTIMATOR_STATUS_FLAGS of the view (module docstring)."""
    flags = 0
    for bit, flag in FLAG_OF_VALID:
        if view.valid & bit:
            flags |= flag
    if view.status_heard:
        if view.valid & VALID_ATTITUDE and view.horizontal_source == SOURCE_NONE:
            flags |= M.ESTIMATOR_CONST_POS_MODE
        if view.gnss_state == STATE_SPOOFED:
            flags |= M.ESTIMATOR_GPS_GLITCH
    return flags


def estimator_status(view: NavigationView, time_usec: int) -> M.MAVLink_estimator_status_message | None:
    """ESTIMATOR_STATUS, or None before navigation/state has been heard."""
    if not view.state_heard:
        return None
    score = view.gnss_score if view.status_heard and math.isfinite(view.gnss_score) else 0.0
    return M.MAVLink_estimator_status_message(
        time_usec, flags_of(view), 0.0, score, 0.0, 0.0, 0.0, 0.0,
        view.sigma_h if math.isfinite(view.sigma_h) else 0.0, view.sigma_v if math.isfinite(view.sigma_v) else 0.0)
