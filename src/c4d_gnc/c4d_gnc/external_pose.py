"""External pose / odometry input (VIO, motion capture, UWB; ROS or MAVLink through the bridge), without ROS.

`ExternalValidator` decides whether a sample may be fused and, when not, why — each reason is one
of navigation/status' `external_rejected_*` counters. The checks are ordered cheapest first and
the rate limit comes before the covariance factorisation, so a 1 kHz flood costs little.
`FrameAlignment` maps the source's frame into `map`: a yaw offset and the origin of the external
frame in map, configured, or estimated from the first samples against the current estimate
(whose heading comes from the magnetometer) and then frozen.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

FUTURE_TOLERANCE_S = 0.005  # a sample may be stamped this far ahead of the newest IMU sample (clock jitter)
RATE_JITTER = 0.9  # a sample closer than 0.9 / max_rate_hz to the last accepted one is over the rate (stamp jitter)


class Rejection(Enum):
    """Why an external sample was not fused (navigation/status external_rejected_<value>)."""

    INVALID = "invalid"
    FRAME = "frame"
    STALE = "stale"
    FUTURE = "future"
    COVARIANCE = "covariance"
    RATE = "rate"
    GATE = "gate"


@dataclass
class ExternalSample:
    """One pose: position [m] and yaw [rad] of base_link in the external frame at sample time t [s]."""

    t: float
    position: np.ndarray  # (3,)
    quaternion: tuple[float, float, float, float]  # (w, x, y, z), body -> external frame
    covariance: np.ndarray  # (6, 6): x, y, z, rot x, rot y, rot z (ROS pose covariance); all zero: unknown
    frame_id: str
    child_frame_id: str = "base_link"  # Odometry's; a PoseWithCovarianceStamped's is base_link by definition
    arrival: float = math.nan  # IMU-clock time it was received (latency statistic)

    @property
    def yaw(self) -> float:
        w, x, y, z = self.quaternion
        return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


@dataclass(frozen=True)
class ExternalConfig:
    frame_ids: tuple[str, ...] = ("odom",)
    max_age_s: float = 0.5  # [s] older samples are stale
    max_rate_hz: float = 250.0  # [Hz] samples closer than 0.9/rate (sample time) to the last accepted one are dropped
    position_sigma_m: float = 0.05  # [m] σ used when the message's covariance is all zero
    yaw_sigma_rad: float = math.radians(2.0)  # [rad] σ used when the message's covariance is all zero


@dataclass
class Validated:
    """An accepted sample's position covariance (3, 3) [m²] and yaw variance [rad²]."""

    position_cov: np.ndarray
    yaw_var: float


@dataclass
class ExternalValidator:
    config: ExternalConfig = field(default_factory=ExternalConfig)
    counts: dict[Rejection, int] = field(default_factory=lambda: dict.fromkeys(Rejection, 0))
    last_accepted_t: float = -math.inf

    def rate_limited(self, t: float) -> bool:
        """True (and counted) when a sample stamped t comes too soon after the last accepted one.
        Cheap enough to run on the raw message's stamp before deserialising it."""
        if t - self.last_accepted_t < RATE_JITTER / self.config.max_rate_hz and t >= self.last_accepted_t:
            self.counts[Rejection.RATE] += 1
            return True
        return False

    def check(self, s: ExternalSample, newest_imu_t: float, oldest_history_t: float) -> Validated | Rejection:
        """Validate `s` against the IMU clock; a Rejection is counted before it is returned."""
        reason = self._reason(s, newest_imu_t, oldest_history_t)
        if isinstance(reason, Rejection):
            self.counts[reason] += 1
        return reason

    def _reason(self, s: ExternalSample, newest: float, oldest: float) -> Validated | Rejection:
        cfg = self.config
        if not (math.isfinite(s.t) and np.all(np.isfinite(s.position)) and all(map(math.isfinite, s.quaternion))
                and np.all(np.isfinite(s.covariance)) and abs(math.fsum(c * c for c in s.quaternion) - 1.0) < 0.1):
            return Rejection.INVALID
        if s.frame_id not in cfg.frame_ids or s.child_frame_id != "base_link":
            return Rejection.FRAME
        if s.t > newest + FUTURE_TOLERANCE_S:
            return Rejection.FUTURE
        if s.t < oldest or newest - s.t > cfg.max_age_s:
            return Rejection.STALE
        if s.t - self.last_accepted_t < RATE_JITTER / cfg.max_rate_hz and s.t >= self.last_accepted_t:
            return Rejection.RATE
        validated = self._covariance(s.covariance)
        if validated is None:
            return Rejection.COVARIANCE
        self.last_accepted_t = s.t
        return validated

    def _covariance(self, cov: np.ndarray) -> Validated | None:
        cfg = self.config
        if not np.any(cov):
            return Validated(np.eye(3) * cfg.position_sigma_m**2, cfg.yaw_sigma_rad**2)
        block = cov[0:3, 0:3]
        if not np.allclose(block, block.T, rtol=1e-6, atol=1e-12):
            return None
        try:
            np.linalg.cholesky(block)
        except np.linalg.LinAlgError:
            return None
        yaw_var = float(cov[5, 5])
        return Validated(block.copy(), yaw_var if yaw_var > 0 else cfg.yaw_sigma_rad**2)


def wrap(angle: float) -> float:
    return math.atan2(math.sin(angle), math.cos(angle))


class FrameAlignment:
    """The external frame in map: yaw offset ψ [rad] and origin o [m]; map = R(ψ)·ext + o.

    `configured(ψ, o)` is aligned from the start. Otherwise `estimate` collects `samples` pairs
    (external pose, the estimate at the same sample time); ψ = circular mean of the yaw
    differences (the estimate's heading is the magnetometer's), o = mean of p_map − R(ψ)·p_ext;
    then both are frozen (a moving offset would feed the source's drift back into itself).
    """

    def __init__(self, samples: int = 20) -> None:
        self.samples = samples
        self.yaw_offset = 0.0
        self.origin = np.zeros(3)
        self.aligned = False
        self._pairs: list[tuple[float, np.ndarray, np.ndarray]] = []
        self._c, self._s = 1.0, 0.0

    @classmethod
    def configured(cls, yaw_offset: float, origin: np.ndarray) -> FrameAlignment:
        a = cls()
        a._freeze(yaw_offset, np.asarray(origin, dtype=float))
        return a

    def _freeze(self, yaw_offset: float, origin: np.ndarray) -> None:
        self.yaw_offset, self.origin, self.aligned = wrap(yaw_offset), origin, True
        self._c, self._s = math.cos(self.yaw_offset), math.sin(self.yaw_offset)
        self._pairs.clear()

    def add(self, ext_position: np.ndarray, ext_yaw: float, map_position: np.ndarray, map_yaw: float) -> bool:
        """One pair for the estimate; True once aligned."""
        if self.aligned:
            return True
        self._pairs.append((wrap(map_yaw - ext_yaw), np.asarray(ext_position, dtype=float).copy(),
                            np.asarray(map_position, dtype=float).copy()))
        if len(self._pairs) < self.samples:
            return False
        yaw = math.atan2(sum(math.sin(d) for d, _, _ in self._pairs), sum(math.cos(d) for d, _, _ in self._pairs))
        c, s = math.cos(yaw), math.sin(yaw)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        origin = np.mean([m - rot @ e for _, e, m in self._pairs], axis=0)
        self._freeze(yaw, origin)
        return True

    def to_map(self, position: np.ndarray, yaw: float) -> tuple[np.ndarray, float]:
        c, s, p = self._c, self._s, position
        return (np.array([c * p[0] - s * p[1] + self.origin[0], s * p[0] + c * p[1] + self.origin[1],
                          p[2] + self.origin[2]]), wrap(yaw + self.yaw_offset))

    def covariance_to_map(self, cov: np.ndarray) -> np.ndarray:
        c, s = self._c, self._s
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        return rot @ cov @ rot.T
