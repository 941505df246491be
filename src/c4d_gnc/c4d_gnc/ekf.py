"""Navigation filter: 17-state error-state EKF (position, velocity, attitude, gyro and accel bias, wind).

Nominal state in ENU / FLU: p, v, q (body → world), b_g, b_a, w (horizontal wind). Prediction
integrates each IMU sample (strapdown: a = R(f − b_a) + g); the error covariance follows δṗ = δv,
δv̇ = −[R(f − b_a)]×δθ − R δb_a, δθ̇ = −R δb_g (attitude error in the world frame), biases and
wind as random walks. Updates: a position measurement on any subset of the axes (GNSS, external pose,
range height; NavigationFilter compares delayed ones with the state at their sample time), a yaw
measurement (external heading), barometric altitude (offset learnt at home), magnetometer heading,
and multirotor drag (`update_drag`: the body-frame horizontal specific force is the linear drag of
the air-relative velocity v − w — thrust has no horizontal body component — plus the accelerometer
bias). Drag is what keeps the velocity observable without any position source: a vehicle that lost
or cut off GNSS dead-reckons on it instead of on integrated tilt errors (PX4's EKF2 fuses it for the
same reason, EKF2_DRAG_CTRL). It needs the vehicle's drag per unit mass (`drag_horizontal_per_s`,
`drag_vertical_per_s`; the navigation node takes them from the airframe); 0 = not fused.
Every correction is passed to `on_correction` (the filter's state history and GNSS journal).
An IMU-only dead-reckoning shadow (`pi`, `vi`) is integrated alongside and never corrected: the
GNSS integrity monitor compares fixes with it. Static alignment (roll and pitch from
gravity, yaw from the magnetometer) starts the filter; home (the geodetic origin of the local
frame) is the mean of the first GNSS fixes, taken at rest (the barometer offset is the mean
barometric altitude over the same window). Each sensor is optional: without GNSS the position is flagged
invalid (and its covariance grows); without magnetometer the heading is flagged invalid.
Why an error-state filter: the attitude error stays small and three-dimensional, so the
filter is well conditioned with a unit quaternion as nominal attitude.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from c4d_common import quat
from c4d_common.airframe import Airframe
from c4d_common.geodesy import GeoOrigin, altitude_at_pressure

GRAVITY = 9.80665
Vec = tuple[float, float, float]


@dataclass(frozen=True)
class EkfConfig:
    gyro_noise: float = 0.003  # [rad/s] per sample σ (matches the IMU)
    accel_noise: float = 0.05  # [m/s²] per sample σ
    gyro_bias_walk: float = 2e-4  # [rad/s/√s]
    accel_bias_walk: float = 1e-3  # [m/s²/√s]
    gps_gate: float = 5.0  # [σ] innovation gate (Mahalanobis distance per axis)
    baro_noise: float = 0.15  # [m]
    mag_heading_noise: float = math.radians(3.0)
    mag_declination: float = 0.0  # [rad] of the local field (positive east)
    position_valid_s: float = 1.0  # a position fix younger than this keeps the position valid
    gps_reset_after_s: float = 3.0  # after an outage this long, a fix the gate rejects resets the position
    zero_velocity_sigma: float = 0.05  # [m/s] zero-velocity update while the vehicle stands on the ground
    unaided_velocity_sigma: float = 1.0  # [m/s] horizontal velocity pseudo-measurement (0) in flight without aiding; 0 = off
    home_fixes: int = 20  # GNSS fixes averaged to set home (the local frame's geodetic origin)
    heading_valid_s: float = 2.0
    # drag fusion: linear drag / mass of the air-relative velocity along the world's horizontal axes and
    # its vertical one (the airframe's drag.linear_n_per_m_s / mass_kg); 0 = no drag fusion
    drag_horizontal_per_s: float = 0.0  # [1/s]
    drag_vertical_per_s: float = 0.0  # [1/s]
    drag_noise: float = 0.02  # [m/s²] σ of a 0.1 s mean horizontal specific force against the drag model
    wind_walk: float = 0.1  # [m/s/√s] random walk of the horizontal wind


def drag_config(airframe: Airframe, cfg: EkfConfig | None = None) -> EkfConfig:
    """`cfg` (default EkfConfig()) with drag fusion on for `airframe`: its world-axis linear drag over its
    mass (the simulator's model, c4d_sim.plant; quad_x: 0.167 / 0.233 1/s)."""
    cx, cy, cz = airframe.drag_linear
    return replace(cfg or EkfConfig(), drag_horizontal_per_s=0.5 * (cx + cy) / airframe.mass,
                   drag_vertical_per_s=cz / airframe.mass)


N_STATES = 17  # error state: δp, δv, δθ, δb_g, δb_a (3 each), δw (horizontal wind, 2)
WIND = slice(15, 17)
VELOCITY_VALID_SIGMA = 0.5  # [m/s] dead reckoning on drag: the horizontal velocity is valid below this σ
WIND_PRIOR_SIGMA = 3.0  # [m/s] no wind is known before drag fusion has learnt it in flight


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def rotation_matrix(q: quat.Quat) -> np.ndarray:
    """Rotation matrix (body → world) of a unit quaternion."""
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


class NavigationEkf:
    def __init__(self, config: EkfConfig | None = None) -> None:
        self.cfg = config or EkfConfig()
        self.p = np.zeros(3)
        self.v = np.zeros(3)
        self.q: quat.Quat = quat.IDENTITY
        self.bg = np.zeros(3)
        self.ba = np.zeros(3)
        # a horizontal position source is fused (NavigationFilter sets it): the wind is observable and walks;
        # without one it is unobservable and held as last learnt, so drag measures the ground velocity against
        # it (in the closed loop a walking wind absorbed the dead-reckoning drift and the velocity error grew)
        self.horizontal_aiding = True
        self.wind = np.zeros(2)  # [m/s] horizontal wind (ENU), learnt by drag fusion against the aiding
        self.P = np.diag([100.0] * 3 + [4.0] * 3 + [0.05] * 3 + [0.02**2] * 3 + [0.2**2] * 3
                         + [WIND_PRIOR_SIGMA**2] * 2)
        self.aligned = False
        self.origin: GeoOrigin | None = None
        self.baro_offset: float | None = None
        self.t = 0.0
        self.pi = np.zeros(3)  # dead-reckoning shadow: IMU-only integration, never corrected
        self.vi = np.zeros(3)
        self.on_correction: Callable[[np.ndarray], None] | None = None  # every update's δx (N_STATES,)
        self.last_gps = -math.inf
        self.last_position = -math.inf  # last horizontal position fused (any source)
        self.valid_until = -math.inf  # dead reckoning declared valid until then (after a source cut-off)
        self.last_mag = -math.inf
        self.last_drag = -math.inf  # last drag measurement fused
        self.rejected = {"gps": 0, "baro": 0, "mag": 0, "drag": 0}
        self.resets = 0  # position resets to GNSS after an outage
        self.accel_world = np.zeros(3)
        self.omega = np.zeros(3)
        self._align_acc: list[np.ndarray] = []
        self._align_mag: np.ndarray | None = None
        self._home_fixes: list[tuple[float, float, float]] = []
        self._home_baro: list[float] = []

    def __setstate__(self, state: dict) -> None:
        """Snapshots journaled before the wind states (resim of older flights): no wind, its prior σ."""
        if "wind" not in state:
            P = np.zeros((N_STATES, N_STATES))
            n = len(state["P"])
            P[:n, :n] = state["P"]
            P[n:, n:] = np.eye(N_STATES - n) * WIND_PRIOR_SIGMA**2
            state["P"], state["wind"] = P, np.zeros(2)
            state["rejected"] = {**state.get("rejected", {}), "drag": 0}
        state.setdefault("horizontal_aiding", True)
        state.setdefault("last_drag", -math.inf)
        self.__dict__.update(state)

    # ---------------------------------------------------------------- alignment
    def align(self, accel: Vec, mag: Vec | None) -> bool:
        """Static alignment from averaged accelerometer samples (+ magnetometer for yaw)."""
        self._align_acc.append(np.asarray(accel, dtype=float))
        if mag is not None:
            self._align_mag = np.asarray(mag, dtype=float)
        if len(self._align_acc) < 50:
            return False
        f = np.mean(self._align_acc, axis=0)
        roll = math.atan2(f[1], f[2])
        pitch = math.atan2(-f[0], math.hypot(f[1], f[2]))
        yaw = 0.0
        if self._align_mag is not None:
            yaw = self._heading_from_mag(self._align_mag, roll, pitch)
        self.q = quat.from_euler(roll, pitch, yaw)
        # after a static alignment the tilt error is what the accelerometer bias hides (~b_a/g);
        # a tight tilt prior keeps the (unobservable in hover) tilt / bias split physical
        self.P[6:8, 6:8] = np.eye(2) * math.radians(1.0) ** 2
        self.P[8, 8] = math.radians(10.0 if mag is not None else 180.0) ** 2
        self.P[12:15, 12:15] = np.eye(3) * 0.1**2
        self.aligned = True
        self._align_acc.clear()
        return True

    def _heading_from_mag(self, m: np.ndarray, roll: float, pitch: float) -> float:
        """ENU yaw (0 = east) of the body x axis from a body-frame field sample and tilt."""
        level = quat.rotate(quat.from_euler(roll, pitch, 0.0), (float(m[0]), float(m[1]), float(m[2])))
        # horizontal field points to magnetic north; body x heading relative to north, then ENU
        north_angle = math.atan2(level[1], level[0])  # angle of north in the yaw-free body frame
        return math.pi / 2 - north_angle - self.cfg.mag_declination

    # ---------------------------------------------------------------- prediction
    def predict(self, gyro: Vec, accel: Vec, dt: float) -> None:
        if not self.aligned or dt <= 0:
            return
        cfg = self.cfg
        w = np.asarray(gyro) - self.bg
        f = np.asarray(accel) - self.ba
        R = rotation_matrix(self.q)
        a = R @ f + np.array([0.0, 0.0, -GRAVITY])
        self.p += self.v * dt + 0.5 * a * dt * dt
        self.v += a * dt
        self.pi += self.vi * dt + 0.5 * a * dt * dt
        self.vi += a * dt
        self.q = quat.integrate(self.q, (float(w[0]), float(w[1]), float(w[2])), dt)
        self.accel_world, self.omega = a, w
        phi = np.eye(N_STATES)
        phi[0:3, 3:6] = np.eye(3) * dt
        phi[3:6, 6:9] = -_skew(R @ f) * dt
        phi[3:6, 12:15] = -R * dt
        phi[6:9, 9:12] = -R * dt
        q_diag = np.concatenate([
            np.zeros(3),
            np.full(3, (cfg.accel_noise * dt) ** 2),
            np.full(3, (cfg.gyro_noise * dt) ** 2),
            np.full(3, cfg.gyro_bias_walk**2 * dt),
            np.full(3, cfg.accel_bias_walk**2 * dt),
            np.full(2, cfg.wind_walk**2 * dt if self.horizontal_aiding else 0.0),
        ])
        self.P = phi @ self.P @ phi.T + np.diag(q_diag)
        self.t += dt

    # ---------------------------------------------------------------- updates
    def rotate(self, theta: np.ndarray) -> None:
        """Apply a small attitude correction `theta` [rad] about the world axes (the error state's δθ)."""
        angle = float(np.linalg.norm(theta))
        if angle > 1e-12:
            axis = theta / angle
            s = math.sin(angle / 2)
            dq = (math.cos(angle / 2), float(axis[0] * s), float(axis[1] * s), float(axis[2] * s))
            self.q = quat.normalize(quat.mul(dq, self.q))

    def _update(self, H: np.ndarray, innovation: np.ndarray, Rm: np.ndarray, gate: float | None = None) -> bool:
        S = H @ self.P @ H.T + Rm
        if gate is not None:
            d2 = float(innovation @ np.linalg.solve(S, innovation))
            if d2 > gate * gate * len(innovation):
                return False
        K = self.P @ H.T @ np.linalg.inv(S)
        dx = K @ innovation
        self.p += dx[0:3]
        self.v += dx[3:6]
        self.rotate(dx[6:9])
        self.bg += dx[9:12]
        self.ba += dx[12:15]
        self.wind += dx[WIND]
        I_KH = np.eye(N_STATES) - K @ H
        self.P = I_KH @ self.P @ I_KH.T + K @ Rm @ K.T  # Joseph form: stays symmetric positive
        if self.on_correction is not None:
            self.on_correction(dx)
        return True

    def gate_passes(self, rows: np.ndarray, innovation: np.ndarray, Rm: np.ndarray, gate: float) -> bool:
        """Would a position measurement on `rows` (axis indices 0-2) pass the gate? Nothing is fused."""
        S = self.P[np.ix_(rows, rows)] + Rm
        return float(innovation @ np.linalg.solve(S, innovation)) <= gate * gate * len(innovation)

    def update_position(self, rows: np.ndarray, innovation: np.ndarray, Rm: np.ndarray, gate: float | None) -> bool:
        """Position measurement on the axes `rows` (e.g. [0, 1] horizontal, [2] height) with its
        innovation (measurement − the state at its sample time) and covariance Rm [m²]."""
        if not self.aligned:
            return False
        H = np.zeros((len(rows), N_STATES))
        H[np.arange(len(rows)), rows] = 1.0
        return self._update(H, innovation, Rm, gate)

    def update_yaw(self, innovation: float, variance: float, gate: float) -> bool:
        """Heading measurement (e.g. the external source's yaw in map): innovation [rad], variance [rad²]."""
        if not self.aligned:
            return False
        H = np.zeros((1, N_STATES))
        H[0, 8] = 1.0
        ok = self._update(H, np.array([innovation]), np.array([[variance]]), gate)
        if ok:
            self.last_mag = self.t  # the heading is measured
        return ok

    def set_home(self, latitude: float, longitude: float, altitude: float, ready: bool = True) -> bool:
        """Average the latest `home_fixes` fixes into home (the local frame's geodetic origin) once there
        are that many and the caller is `ready` (NavigationFilter: the gyro bias converged); True once set."""
        if self.origin is not None:
            return True
        # home = mean of the latest fixes (one fix alone carries its full noise into the frame)
        self._home_fixes.append((latitude, longitude, altitude))
        del self._home_fixes[:-self.cfg.home_fixes]
        if len(self._home_fixes) < self.cfg.home_fixes or not ready:
            return False
        lat, lon, alt = (sum(c) / len(self._home_fixes) for c in zip(*self._home_fixes, strict=True))
        self.origin = GeoOrigin(lat, lon, alt)
        self._home_fixes.clear()
        # home is set while the vehicle stands still where the fixes were taken: it is at 0
        self.p[:] = 0.0
        self.v[:] = 0.0
        if self._home_baro:  # the barometer's offset is learnt over the same window
            self.baro_offset = sum(self._home_baro) / len(self._home_baro)
        return False

    def learn_baro_offset(self, altitude: float) -> None:
        """Without a GNSS home (configured origin, or no GNSS): the barometer's offset is the mean
        barometric altitude of the first samples, taken where the estimate stands (at rest)."""
        if self.baro_offset is None:
            self._home_baro.append(altitude - float(self.p[2]))
            if len(self._home_baro) >= self.cfg.home_fixes:
                self.baro_offset = sum(self._home_baro) / len(self._home_baro)

    def update_gps(self, latitude: float, longitude: float, altitude: float, sigma_h: float, sigma_v: float,
                   age: float = 0.0) -> bool:
        """A GNSS fix against the current state, its latency compensated with the current velocity
        (the simple path, used without a state history); NavigationFilter fuses at sample time."""
        if self.origin is None:
            self.set_home(latitude, longitude, altitude)
            return False
        if not self.aligned:
            return False
        z = np.asarray(self.origin.to_enu(latitude, longitude, altitude)) + self.v * max(0.0, age)
        Rm = np.diag([sigma_h**2, sigma_h**2, sigma_v**2])
        ok = self.update_position(np.arange(3), z - self.p, Rm, self.cfg.gps_gate)
        if ok:
            self.last_gps = self.last_position = self.t
        elif self.t - self.last_gps > self.cfg.gps_reset_after_s:
            self.reset_position(z, Rm)
            self.last_gps = self.last_position = self.t
            ok = True
        else:
            self.rejected["gps"] += 1
        return ok

    def reset_position(self, z: np.ndarray, Rm: np.ndarray) -> None:
        """GNSS is back after an outage and dead reckoning drifted beyond the gate: trust the fix
        (PX4's EKF does the same), restart the velocity from rest with a wide uncertainty so the
        next fixes re-estimate it, and drop the stale position/velocity correlations."""
        self.resets += 1
        dx = np.zeros(N_STATES)
        dx[0:3], dx[3:6] = z - self.p, -self.v
        self.p = z.copy()
        self.v[:] = 0.0
        if self.on_correction is not None:
            self.on_correction(dx)
        self.P[0:6, :] = 0.0
        self.P[:, 0:6] = 0.0
        self.P[0:3, 0:3] = Rm
        self.P[3:6, 3:6] = np.eye(3) * 25.0  # (5 m/s)²

    def update_zero_velocity(self) -> bool:
        """Zero-velocity update (the vehicle is known to stand still, e.g. disarmed on the
        ground): bounds the dead-reckoning drift without GNSS and makes tilt and accelerometer
        bias observable, so a vehicle that landed blind does not diverge while it waits."""
        if not self.aligned:
            return False
        H = np.zeros((3, N_STATES))
        H[:, 3:6] = np.eye(3)
        return self._update(H, -self.v, np.eye(3) * self.cfg.zero_velocity_sigma**2)

    def update_unaided_velocity(self) -> bool:
        """Horizontal velocity pseudo-measurement of zero with a loose σ (`unaided_velocity_sigma`), applied
        while the vehicle is held still in flight (a HOLD or LAND failsafe) and no horizontal source is fused
        (PX4's EKF2 fuses a fake position for the same reason; NavigationFilter decides when).
        Why: without horizontal aiding, tilt, gyro bias and accelerometer bias are unobservable; pure
        strapdown integration then runs away cubically (5-15 m in 20 s of hover in the synthetic flight).
        Held still, the loose zero keeps the velocity bounded and lets the accelerometer level the attitude
        again (hover: 0.2-0.8 m after 24 s instead of 6-19 m); on a vehicle flying a path it would pull the
        velocity towards zero, hence only while station keeping."""
        sigma = self.cfg.unaided_velocity_sigma
        if not self.aligned or sigma <= 0.0:
            return False
        H = np.zeros((2, N_STATES))
        H[0, 3] = H[1, 4] = 1.0
        return self._update(H, -self.v[0:2], np.eye(2) * sigma**2)

    def update_drag(self, accel: Vec) -> bool:
        """Drag fusion: `accel` is the mean accelerometer reading [m/s², body FLU] over ~0.1 s of flight.
        Model: its horizontal body components are the drag R⁻¹(−D (v − w)) of the air-relative velocity
        (D = diag(k_h, k_h, k_v), w the horizontal wind, no vertical wind) plus b_a — a multirotor's thrust
        is along body z. Gated at 5σ (a gust the wind state has not followed, a collision): rejected,
        counted, not fused. False when not fused (drag fusion off, not aligned, or gated out)."""
        cfg = self.cfg
        if not self.aligned or cfg.drag_horizontal_per_s <= 0.0:
            return False
        drag = np.diag([cfg.drag_horizontal_per_s, cfg.drag_horizontal_per_s, cfg.drag_vertical_per_s])
        Rt = rotation_matrix(self.q).T
        u = drag @ (self.v - np.array([self.wind[0], self.wind[1], 0.0]))  # drag deceleration, world axes
        predicted = -(Rt @ u)[0:2] + self.ba[0:2]
        H = np.zeros((2, N_STATES))
        H[:, 3:6] = -(Rt @ drag)[0:2]
        H[:, 6:9] = -(Rt @ _skew(u))[0:2]  # R_true = (I + [δθ]×) R
        H[0, 12] = H[1, 13] = 1.0
        H[:, WIND] = (Rt @ drag)[0:2, 0:2]
        innovation = np.asarray(accel, dtype=float)[0:2] - predicted
        ok = self._update(H, innovation, np.eye(2) * cfg.drag_noise**2, 5.0)
        if ok:
            self.last_drag = self.t
        else:
            self.rejected["drag"] += 1
        return ok

    def update_baro(self, pressure: float) -> bool:
        altitude = altitude_at_pressure(pressure)
        if self.origin is None:
            self._home_baro.append(altitude)  # averaged into the offset when home is set
            return False
        if not self.aligned or self.baro_offset is None:
            return False
        H = np.zeros((1, N_STATES))
        H[0, 2] = 1.0
        ok = self._update(H, np.array([altitude - self.baro_offset - self.p[2]]), np.array([[self.cfg.baro_noise**2]]), 5.0)
        if not ok:
            self.rejected["baro"] += 1
        return ok

    def update_mag(self, field: Vec) -> bool:
        if not self.aligned:
            return False
        roll, pitch, yaw = quat.to_euler(self.q)
        measured = self._heading_from_mag(np.asarray(field), roll, pitch)
        innovation = math.atan2(math.sin(measured - yaw), math.cos(measured - yaw))
        H = np.zeros((1, N_STATES))
        H[0, 8] = 1.0  # world-frame yaw error
        ok = self._update(H, np.array([innovation]), np.array([[self.cfg.mag_heading_noise**2]]), 5.0)
        if ok:
            self.last_mag = self.t
        else:
            self.rejected["mag"] += 1
        return ok

    # ---------------------------------------------------------------- outputs
    @property
    def position_valid(self) -> bool:
        recent = self.t - self.last_position < self.cfg.position_valid_s or self.t < self.valid_until
        return self.aligned and recent and float(np.trace(self.P[0:3, 0:3])) < 27.0

    @property
    def velocity_valid(self) -> bool:
        """The horizontal velocity is trustworthy: with the position, or — dead reckoning — while drag fusion
        measures it (a drag sample fused within position_valid_s) and its σ is below VELOCITY_VALID_SIGMA."""
        if self.position_valid:
            return True
        drag_recent = self.t - self.last_drag < self.cfg.position_valid_s
        return self.aligned and drag_recent and max(self.P[3, 3], self.P[4, 4]) < VELOCITY_VALID_SIGMA**2

    @property
    def heading_valid(self) -> bool:
        return self.aligned and self.t - self.last_mag < self.cfg.heading_valid_s
