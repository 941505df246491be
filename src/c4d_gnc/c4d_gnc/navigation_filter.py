"""The navigation EKF driven by the sensor streams' timing, without ROS.

Why a class of its own: what the navigation node does with each sample — align first,
predict on every IMU sample but never across a gap, zero-velocity updates while disarmed,
GNSS age against the IMU clock, the terrain distance only while a range reading is fresh —
is logic, and it is unit-tested here without DDS. The node only converts messages.
"""

from __future__ import annotations

import math

import numpy as np

from .ekf import NavigationEkf

Vec = tuple[float, float, float]

ZUPT_EVERY = 50  # IMU samples between zero-velocity updates (10 Hz at 500 Hz)
MAX_IMU_GAP_S = 0.1  # a longer gap between IMU samples is not integrated
RANGE_TIMEOUT_S = 0.5  # a range reading older than this gives no terrain distance
DEFAULT_SIGMA_H_M, DEFAULT_SIGMA_V_M = 1.0, 2.0  # GNSS accuracy when a fix reports no covariance


class NavigationFilter:
    def __init__(self, ekf: NavigationEkf) -> None:
        self.ekf = ekf
        self.on_ground = False  # disarmed = standing still: zero-velocity updates bound the drift
        self.imu_t: float | None = None  # sample time of the last IMU sample [s]
        self.imu_count = 0
        self.mag: Vec | None = None
        self.range_m, self.range_t = math.inf, -math.inf
        self.omega = np.zeros(3)  # bias-corrected body rate [rad/s]
        self.alpha = np.zeros(3)  # low-passed body angular acceleration [rad/s²]

    def imu(self, t: float, gyro: Vec, accel: Vec) -> bool:
        """One IMU sample at time `t` [s]; True when the estimate advanced (publish it)."""
        ekf, last = self.ekf, self.imu_t
        self.imu_t = t
        if not ekf.aligned:
            ekf.align(accel, self.mag)
            return False
        if last is None or not 0.0 < t - last < MAX_IMU_GAP_S:
            return False  # first sample after a gap: no integration over an unknown interval
        dt = t - last
        ekf.predict(gyro, accel, dt)
        self.imu_count += 1
        if self.on_ground and self.imu_count % ZUPT_EVERY == 0:
            ekf.update_zero_velocity()
        omega = np.asarray(gyro) - ekf.bg
        self.alpha = 0.8 * self.alpha + 0.2 * (omega - self.omega) / dt
        self.omega = omega
        return True

    def magnetometer(self, field: Vec) -> None:
        self.mag = field
        self.ekf.update_mag(field)

    def gnss(self, latitude: float, longitude: float, altitude: float, var_h: float, var_v: float, stamp: float) -> None:
        """A fix taken at `stamp` [s] with variances [m²] (<= 0: unknown); its age is measured on the IMU clock."""
        sigma_h = math.sqrt(var_h) if var_h > 0 else DEFAULT_SIGMA_H_M
        sigma_v = math.sqrt(var_v) if var_v > 0 else DEFAULT_SIGMA_V_M
        age = (self.imu_t or stamp) - stamp
        self.ekf.update_gps(latitude, longitude, altitude, sigma_h, sigma_v, age)

    def range_down(self, distance: float, t: float) -> None:
        """A downward range [m] at `t`; −inf means closer than the minimum range (on the ground)."""
        self.range_m, self.range_t = (0.0 if distance == -math.inf else distance), t

    def terrain_distance(self, t: float) -> float:
        """Distance to the ground [m] at `t`, NaN without a fresh finite range reading."""
        return float(self.range_m) if math.isfinite(self.range_m) and t - self.range_t < RANGE_TIMEOUT_S else math.nan
