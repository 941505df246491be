"""Open-loop survey flights for the GNSS integrity monitor: analytic kinematics → the simulator's
sensor models → the navigation EKF → c4d_gnc.gnss_integrity.

Why open loop: the monitor's false-alarm rate and detection times need many seeded flights, which
the whole graph cannot afford; the trajectory does not need a controller, only consistent
kinematics. A flight: on the ground (alignment, home from the first fixes), a climb, then
lawnmower legs at 3-5 m/s joined by semicircular turns (the heading follows the track), one leg
climbing 5 m, and a stop. Position, velocity, acceleration (C2: quintic blends), the attitude of
a multirotor (thrust along a + g + the linear drag per unit mass × v: quad_x's, no wind; yaw on the
track) and its body rates feed c4d_sim.sensors (IMU, GNSS with its faults, baro, magnetometer; seeded),
which feed the real NavigationEkf (zero-velocity updates on the ground, drag fusion in flight, as
NavigationFilter) and the monitor. The FixCheck is built
here: the estimate before each fix, and an IMU-only shadow integrated from the EKF's
`accel_world` per IMU sample. A fix the monitor judges SPOOFED is not fused (the filter's undo of
the fixes since the onset is not modelled). An external source, when enabled, is the truth plus
2 cm noise, given to the monitor only (not fused).
Shared by src/c4d_gnc/test/test_gnss_integrity_flights.py and bench/gnss_integrity.py.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field

import numpy as np

from c4d_common import quat
from c4d_common.airframe import default_airframe_path, load_airframe
from c4d_common.geodesy import GeoOrigin
from c4d_gnc.ekf import EkfConfig, NavigationEkf, drag_config
from c4d_gnc.gnss_integrity import FixCheck, GnssIntegrityMonitor, IntegrityConfig, IntegrityState, Verdict
from c4d_sim.plant import PlantState
from c4d_sim.sensors import SensorConfig, SensorSuite

GRAVITY = 9.80665
HOME = GeoOrigin(43.5629, 1.4815, 146.0)
QUAD = load_airframe(default_airframe_path("quad_x"))
GROUND_S, CLIMB_S, ALTITUDE_M = 6.0, 6.0, 20.0
RAMP_S = 3.0  # [s] speed ramps at the start and the end of the survey
ZUPT_EVERY = 50  # IMU samples between zero-velocity updates on the ground (NavigationFilter's)
TICK_S = 0.2  # the monitor's tick (5 Hz)


def blend(tau: float) -> tuple[float, float, float]:
    """Quintic smoothstep on [0, 1] and its first two derivatives (C2: no acceleration step)."""
    x = min(1.0, max(0.0, tau))
    if x in (0.0, 1.0):
        return x, 0.0, 0.0
    return 10 * x**3 - 15 * x**4 + 6 * x**5, 30 * x**2 - 60 * x**3 + 30 * x**4, 60 * x - 180 * x**2 + 120 * x**3


def trapezoid(t: float, start: float, duration: float, speed: float, ramp: float) -> tuple[float, float, float]:
    """Distance, speed and acceleration of a move at `speed` from `start` for `duration` [s] with C2 ramps of `ramp` s."""
    def integral(tau: float) -> float:  # ∫ blend over [0, tau] ramps
        x = min(1.0, max(0.0, tau))
        return ramp * (2.5 * x**4 - 3 * x**5 + x**6) + ramp * max(0.0, tau - 1.0)
    a, b = (t - start) / ramp, (t - (start + duration - ramp)) / ramp
    up, down = blend(a), blend(b)
    return speed * (integral(a) - integral(b)), speed * (up[0] - down[0]), speed * (up[1] - down[1]) / ramp


@dataclass(frozen=True)
class Survey:
    """Lawnmower legs of `leg_m` along `heading`, `spacing_m` apart, at `speed`; each U-turn blends
    the deceleration of a leg, the side step and the acceleration of the next (rounded, C2)."""

    speed: float  # [m/s]
    heading: float  # [rad] ENU direction of the first leg (also the vehicle's yaw)
    leg_m: float = 60.0
    spacing_m: float = 10.0
    duration_s: float = 100.0  # whole flight [s], ground phase included

    @property
    def start_s(self) -> float:
        return GROUND_S + CLIMB_S

    @property
    def leg_s(self) -> float:
        return self.leg_m / self.speed + RAMP_S

    @property
    def legs(self) -> int:
        return max(1, int((self.duration_s - 2.0 - self.start_s) // self.leg_s))

    def height(self, t: float) -> tuple[float, float, float]:
        """Height above home and its derivatives: the climb after take-off, +5 m during the second leg."""
        h, dh, ddh = 0.0, 0.0, 0.0
        for start, duration, rise in ((GROUND_S, CLIMB_S, ALTITUDE_M), (self.start_s + self.leg_s + 2.0, 8.0, 5.0)):
            b = blend((t - start) / duration)
            h, dh, ddh = h + rise * b[0], dh + rise * b[1] / duration, ddh + rise * b[2] / duration**2
        return h, dh, ddh

    def kinematics(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """Position, velocity, acceleration (ENU) and yaw at `t`."""
        along = np.array([math.cos(self.heading), math.sin(self.heading), 0.0])
        left = np.array([-along[1], along[0], 0.0])
        h = self.height(t)
        p, v, a = np.array([0.0, 0.0, h[0]]), np.array([0.0, 0.0, h[1]]), np.array([0.0, 0.0, h[2]])
        for k in range(self.legs):
            t0 = self.start_s + k * self.leg_s
            if t < t0 - 2 * RAMP_S:
                break
            x = trapezoid(t, t0, self.leg_s, self.speed, RAMP_S)
            sign = 1.0 if k % 2 == 0 else -1.0
            p, v, a = p + sign * along * x[0], v + sign * along * x[1], a + sign * along * x[2]
            if k + 1 < self.legs:  # the side step, centred on the end of this leg
                b, side_s = blend((t - (t0 + self.leg_s - RAMP_S)) / (2 * RAMP_S)), 2 * RAMP_S
                d = self.spacing_m
                p, v, a = p + left * d * b[0], v + left * d * b[1] / side_s, a + left * d * b[2] / side_s**2
        return p, v, a, self.heading


def attitude(acceleration: np.ndarray, yaw: float) -> quat.Quat:
    """A multirotor's attitude: thrust (body z) along a + g, body x towards `yaw` in the horizontal plane."""
    zx, zy, zz = float(acceleration[0]), float(acceleration[1]), float(acceleration[2]) + GRAVITY
    norm = math.sqrt(zx * zx + zy * zy + zz * zz)
    zx, zy, zz = zx / norm, zy / norm, zz / norm
    hx, hy = math.cos(yaw), math.sin(yaw)
    yx, yy, yz = -zz * hy, zz * hx, zx * hy - zy * hx  # z × heading
    norm = math.sqrt(yx * yx + yy * yy + yz * yz)
    yx, yy, yz = yx / norm, yy / norm, yz / norm
    xb = (yy * zz - yz * zy, yz * zx - yx * zz, yx * zy - yy * zx)  # y × z
    return quat.from_axes(xb, (yx, yy, yz), (zx, zy, zz))


@dataclass(frozen=True)
class Fault:
    """A GNSS fault from `t` [s] on (c4d_sim.sensors.Faults fields)."""

    t: float
    kind: str  # "drift" [m/s], "jump" [m], "delay" [s] (meaconing), "dropout" (probability), "sigma" (factor)
    value: float
    direction: float = 0.0  # [rad] ENU direction of a drift or jump

    @property
    def spoofing(self) -> bool:
        return self.kind in ("drift", "jump", "delay")

    def apply(self, suite: SensorSuite) -> None:
        f, unit = suite.faults, (math.cos(self.direction), math.sin(self.direction), 0.0)
        if self.kind == "drift":
            f.gps_drift = (self.value * unit[0], self.value * unit[1], 0.0)
        elif self.kind == "jump":
            f.gps_jump = (self.value * unit[0], self.value * unit[1], 0.0)
        elif self.kind == "delay":
            f.gps_delay_s = self.value
        elif self.kind == "dropout":
            f.gps_jam_dropout = self.value
        elif self.kind == "sigma":
            f.gps_jam_sigma_factor = self.value
        else:
            raise ValueError(f"unknown fault kind {self.kind!r}")


@dataclass
class FlightResult:
    seed: int
    survey: Survey
    fault: Fault | None
    verdicts: list[tuple[float, Verdict]] = field(default_factory=list)  # every check_fix / tick
    calls: list[FixCheck | float] = field(default_factory=list)  # the monitor's inputs in order (a float: a tick)
    max_error_m: float = 0.0  # horizontal estimate error vs truth while flying

    def episodes(self, state: IntegrityState) -> list[float]:
        """The times the verdict entered `state`."""
        out, previous = [], IntegrityState.UNKNOWN
        for t, v in self.verdicts:
            if v.state == state and previous != state:
                out.append(t)
            previous = v.state
        return out

    def detection_s(self) -> float:
        """Time from the fault to its state (SPOOFED for spoofing, JAMMED or SPOOFED for jamming); inf: missed."""
        if self.fault is None:
            return math.inf
        wanted = (IntegrityState.SPOOFED,) if self.fault.spoofing else (IntegrityState.JAMMED, IntegrityState.SPOOFED)
        for t, v in self.verdicts:
            if t >= self.fault.t and v.state in wanted:
                return t - self.fault.t
        return math.inf

    def false_alarms(self) -> int:
        """SPOOFED / JAMMED episodes that began before the fault (all of them in a nominal flight)."""
        limit = self.fault.t if self.fault is not None else math.inf
        return sum(1 for s in (IntegrityState.SPOOFED, IntegrityState.JAMMED) for t in self.episodes(s) if t < limit)


def fly(seed: int, duration_s: float = 100.0, fault: Fault | None = None, external: bool = False,
        config: IntegrityConfig | None = None, sensors: SensorConfig | None = None, drag: bool = True) -> FlightResult:
    """One seeded survey flight; the seed picks speed (3-5 m/s), heading and all sensor noise. `drag`: the
    vehicle has quad_x's linear drag (no wind) and the EKF fuses it, as the navigation node does by default;
    False: a drag-free vehicle and filter."""
    rng = random.Random(seed)
    survey = Survey(speed=rng.uniform(3.0, 5.0), heading=rng.uniform(-math.pi, math.pi), duration_s=duration_s)
    cfg = sensors or SensorConfig()
    suite = SensorSuite(cfg, HOME, seed=seed)
    ekf_config = drag_config(QUAD) if drag else EkfConfig()
    per_mass = np.array([ekf_config.drag_horizontal_per_s] * 2 + [ekf_config.drag_vertical_per_s])
    ekf, monitor = NavigationEkf(ekf_config), GnssIntegrityMonitor(config)
    result = FlightResult(seed, survey, fault)
    dt = 1.0 / cfg.imu_rate_hz
    gps_every, baro_every, mag_every = (round(cfg.imu_rate_hz / r) for r in (cfg.gps_rate_hz, cfg.baro_rate_hz,
                                                                            cfg.mag_rate_hz))
    tick_every = round(TICK_S / dt)
    shadow_p, shadow_v = np.zeros(3), np.zeros(3)
    shadow_started = False
    mag: tuple[float, float, float] | None = None
    n = round(duration_s / dt)
    upcoming = survey.kinematics(0.0)
    q_next = attitude(upcoming[2] + per_mass * upcoming[1], upcoming[3])
    accel_sum, accel_n = np.zeros(3), 0
    ext_rng = random.Random(seed + 10_000)
    for k in range(n + 1):
        t = k * dt
        position, velocity, acceleration, yaw = upcoming
        upcoming = survey.kinematics(t + dt)
        q, q_next = q_next, attitude(upcoming[2] + per_mass * upcoming[1], upcoming[3])  # thrust also beats drag
        # body rate: the rotation from this sample's attitude to the next one's
        dq = quat.mul(quat.conj(q), q_next)
        sign = 1.0 if dq[0] >= 0 else -1.0
        omega = tuple(2.0 * sign * c / dt for c in dq[1:])
        specific_force = quat.rotate_inverse(q, (acceleration[0], acceleration[1], acceleration[2] + GRAVITY))
        on_ground = t < GROUND_S
        state = PlantState(t=t, position=tuple(position), velocity=tuple(velocity), orientation=q,  # type: ignore[arg-type]
                           angular_velocity=omega, acceleration=tuple(acceleration),  # type: ignore[arg-type]
                           specific_force=specific_force, on_ground=on_ground)
        if fault is not None and t >= fault.t > t - dt:
            fault.apply(suite)
        if k % mag_every == 0:
            field_body = suite.mag(state)
            if field_body is not None:
                if ekf.aligned:
                    ekf.update_mag(field_body)
                mag = field_body
        imu = suite.imu(state, dt)
        if imu is not None:
            if not ekf.aligned:
                ekf.align(imu.accel, mag)
            elif k > 0:
                ekf.predict(imu.gyro, imu.accel, dt)
                if shadow_started:
                    shadow_p += shadow_v * dt + 0.5 * ekf.accel_world * dt * dt
                    shadow_v += ekf.accel_world * dt
                accel_sum += imu.accel
                accel_n += 1
                if k % ZUPT_EVERY == 0:  # NavigationFilter's rule: zero velocity on the ground, drag in flight
                    if on_ground:
                        ekf.update_zero_velocity()
                    else:
                        ekf.update_drag(accel_sum / accel_n)
                    accel_sum[:], accel_n = 0.0, 0
        if k % baro_every == 0:
            baro = suite.baro(state)
            if baro is not None:
                ekf.update_baro(baro[1])
        if k % gps_every == 0:
            sample = suite.gps(state, gps_every * dt)
            if sample is not None:
                if ekf.origin is None or not ekf.aligned:
                    ekf.update_gps(sample.latitude, sample.longitude, sample.altitude, sample.sigma_h, sample.sigma_v)
                else:
                    if not shadow_started:  # the shadow starts from the estimate once home is known
                        shadow_p, shadow_v, shadow_started = ekf.p.copy(), ekf.v.copy(), True
                    fix = np.asarray(ekf.origin.to_enu(sample.latitude, sample.longitude, sample.altitude))
                    ext = None
                    if external:
                        ext = position + np.array([ext_rng.gauss(0, 0.02), ext_rng.gauss(0, 0.02), 0.0])
                    check = FixCheck(
                        t=t, position=fix, sigma_h=sample.sigma_h, sigma_v=sample.sigma_v, predicted=ekf.p.copy(),
                        predicted_cov=ekf.P[0:3, 0:3].copy(), velocity=ekf.v.copy(),
                        inertial_position=shadow_p.copy(), inertial_velocity=shadow_v.copy(), external_position=ext,
                        gyro_bias_sigma=math.sqrt(max(ekf.P[9, 9], ekf.P[10, 10])),
                        velocity_sigma=math.sqrt(max(ekf.P[3, 3], ekf.P[4, 4])))
                    verdict = monitor.check_fix(check)
                    result.calls.append(check)
                    result.verdicts.append((t, verdict))
                    if verdict.fuse:
                        ekf.update_gps(sample.latitude, sample.longitude, sample.altitude, sample.sigma_h,
                                       sample.sigma_v)
        if k % tick_every == 0 and shadow_started:
            result.calls.append(t)
            result.verdicts.append((t, monitor.tick(t)))
        if not on_ground and ekf.origin is not None:
            result.max_error_m = max(result.max_error_m, float(np.linalg.norm((ekf.p - position)[:2])))
    return result



def replay(result: FlightResult, config: IntegrityConfig | None) -> FlightResult:
    """The same monitor inputs through a monitor with `config`. Exact up to the first SPOOFED verdict
    (until then every fix was fused in the recorded flight too): detection times and whether a
    nominal flight has a false alarm, without flying again (threshold studies)."""
    monitor = GnssIntegrityMonitor(config)
    out = FlightResult(result.seed, result.survey, result.fault, calls=result.calls, max_error_m=result.max_error_m)
    for call in result.calls:
        if isinstance(call, FixCheck):
            out.verdicts.append((call.t, monitor.check_fix(call)))
        else:
            out.verdicts.append((call, monitor.tick(call)))
    return out
