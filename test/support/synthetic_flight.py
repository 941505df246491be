"""A deterministic synthetic flight for the navigation filter's tests (src/c4d_gnc/test/
test_navigation_sources.py) and bench/navigation_cost.py: analytic kinematics (a circle flown at
constant height after a static start, yaw swinging) -> IMU samples with noise and bias,
magnetometer, barometer, external pose (rate, latency, noise, frame offset) and GNSS fixes, fed to
a NavigationFilter on its own clock. Truth is known at every sample."""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field

import numpy as np

from c4d_common import quat
from c4d_common.geodesy import GeoOrigin, pressure_at_altitude
from c4d_gnc.ekf import GRAVITY, NavigationEkf
from c4d_gnc.external_pose import ExternalSample
from c4d_gnc.navigation_filter import NavigationConfig, NavigationFilter

HOME = GeoOrigin(43.5629, 1.4815, 146.0)
FIELD = np.array([0.0, 2.2e-5, -4.2e-5])  # world (ENU) magnetic field [T], north = +y
IMU_DT = 0.002


@dataclass
class Kinematics:
    """Static until t0, then a circle of `radius` at angular rate `omega` (smooth start), height `height`."""

    t0: float = 3.0
    radius: float = 5.0
    omega: float = 0.6  # [rad/s]: 3 m/s on the circle
    ramp_s: float = 2.0
    height: float = 2.0
    climb_s: float = 3.0
    yaw0: float = math.radians(20.0)

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
        """Position, velocity, acceleration (ENU), yaw, yaw rate at t."""
        tau = max(0.0, t - self.t0)
        e = math.exp(-tau / self.ramp_s)
        th = self.omega * (tau - (1.0 - e) * self.ramp_s)
        th1, th2 = self.omega * (1.0 - e), self.omega / self.ramp_s * e if tau > 0 else 0.0
        r = self.radius
        c, s = math.cos(th), math.sin(th)
        p = np.array([r * s, r - r * c, 0.0])
        v = np.array([r * th1 * c, r * th1 * s, 0.0])
        a = np.array([r * th2 * c - r * th1 * th1 * s, r * th2 * s + r * th1 * th1 * c, 0.0])
        if tau > 0:
            k = math.pi / self.climb_s
            if tau < self.climb_s:
                p[2] = self.height * (1 - math.cos(k * tau)) / 2
                v[2] = self.height * k * math.sin(k * tau) / 2
                a[2] = self.height * k * k * math.cos(k * tau) / 2
            else:
                p[2] = self.height
        yaw = self.yaw0 + (0.3 * math.sin(0.2 * tau) if tau > 0 else 0.0)
        rate = 0.06 * math.cos(0.2 * tau) if tau > 0 else 0.0
        return p, v, a, yaw, rate


@dataclass
class ExternalEmulator:
    """Truth seen through an external frame: map = R(yaw_offset)·ext + origin."""

    rate_hz: float = 100.0
    latency_s: float = 0.03
    noise_m: float = 0.01
    yaw_offset: float = math.radians(30.0)
    origin: tuple[float, float, float] = (1.5, -2.0, 0.3)
    frame_id: str = "odom"
    covariance: np.ndarray = field(default_factory=lambda: np.diag([1e-4, 1e-4, 1e-4, 1e-3, 1e-3, 1e-3]))

    def sample(self, t: float, p: np.ndarray, yaw: float, rng: random.Random) -> ExternalSample:
        c, s = math.cos(-self.yaw_offset), math.sin(-self.yaw_offset)
        d = p - np.asarray(self.origin)
        ext = np.array([c * d[0] - s * d[1], s * d[0] + c * d[1], d[2]]) + [rng.gauss(0, self.noise_m) for _ in range(3)]
        q = quat.from_euler(0.0, 0.0, yaw - self.yaw_offset)
        return ExternalSample(t=t, position=ext, quaternion=q, covariance=self.covariance.copy(), frame_id=self.frame_id)


DEFAULT_EXTERNAL = ExternalEmulator()


class SyntheticFlight:
    """Feeds a NavigationFilter from `Kinematics`; `run(until)` advances and records the horizontal error."""

    def __init__(self, config: NavigationConfig, external: ExternalEmulator | None = DEFAULT_EXTERNAL,
                 gnss_sigma_m: float | None = None, seed: int = 7, kinematics: Kinematics | None = None) -> None:
        self.filter = NavigationFilter(NavigationEkf(), config)
        self.kin = kinematics or Kinematics()
        self.external = external
        self.gnss_sigma_m = gnss_sigma_m
        self.gnss_bias = np.zeros(3)  # [m] added to every fix (a receiver bias, or a spoofer)
        self.gnss_drift = np.zeros(3)  # [m/s] spoofing drift, starting at gnss_drift_t
        self.gnss_drift_t = math.inf
        self.external_on = True
        self.rng = random.Random(seed)
        self.gyro_bias = np.array([0.002, -0.001, 0.0015])
        self.k = 0
        self.pending: list[tuple[float, ExternalSample]] = []  # (arrival, sample)
        self.errors: list[tuple[float, float]] = []  # (t, horizontal error) after alignment
        self.estimates: list[tuple[float, np.ndarray, np.ndarray]] = []  # (t, estimate, truth)

    def run(self, until: float) -> None:
        f, rng = self.filter, self.rng
        while self.k * IMU_DT < until:
            self.k += 1
            k, t = self.k, self.k * IMU_DT
            p, v, a, yaw, rate = self.kin.at(t)
            q = quat.from_euler(0.0, 0.0, yaw)
            f.on_ground = t < self.kin.t0
            specific = np.asarray(quat.rotate_inverse(q, tuple(a + [0.0, 0.0, GRAVITY])))
            gyro = np.array([0.0, 0.0, rate]) + self.gyro_bias + [rng.gauss(0, 0.003) for _ in range(3)]
            accel = specific + [rng.gauss(0, 0.05) for _ in range(3)]
            if k % 10 == 0:
                m = np.asarray(quat.rotate_inverse(q, tuple(FIELD))) + [rng.gauss(0, 2e-7) for _ in range(3)]
                f.magnetometer(tuple(m))
            advanced = f.imu(t, tuple(gyro), tuple(accel))
            if k % 10 == 5:
                f.baro(pressure_at_altitude(HOME.altitude + p[2] + rng.gauss(0, 0.1)), t)
            if self.external is not None and self.external_on and k % round(1 / (self.external.rate_hz * IMU_DT)) == 0:
                self.pending.append((t + self.external.latency_s, self.external.sample(t, p, yaw, rng)))
            while self.pending and self.pending[0][0] <= t + 1e-9:
                f.external(self.pending.pop(0)[1])
            if self.gnss_sigma_m is not None and k % 50 == 25:
                g = p + self.gnss_bias + np.array([rng.gauss(0, self.gnss_sigma_m), rng.gauss(0, self.gnss_sigma_m), 0.0])
                if t > self.gnss_drift_t:
                    g = g + self.gnss_drift * (t - self.gnss_drift_t)
                f.gnss(*HOME.to_geodetic(*g), self.gnss_sigma_m**2, (2 * self.gnss_sigma_m) ** 2, t)
            if advanced:
                est = f.ekf.p.copy()
                self.estimates.append((t, est, p))
                if t > self.kin.t0:
                    self.errors.append((t, math.hypot(est[0] - p[0], est[1] - p[1])))

    def rms(self, since: float) -> float:
        values = [e for t, e in self.errors if t >= since]
        return math.sqrt(sum(e * e for e in values) / len(values))

    def max_step(self, since: float, until: float) -> float:
        """Largest change of the estimate's error between two IMU samples (a step the controller would see)."""
        errs = [est - truth for t, est, truth in self.estimates if since <= t <= until]
        return max(float(np.linalg.norm(b - a)) for a, b in zip(errs, errs[1:], strict=False))
