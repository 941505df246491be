"""Sensor models for the SITL vehicle, ROS-free and seeded.

IMU (gyro + accelerometer: white noise + bias random walk, body FLU), GNSS (geodetic fix with
horizontal/vertical noise and a transport latency), barometer (ISA pressure of the true AMSL
altitude plus noise), magnetometer (Earth field rotated into the body, plus noise), downward
range finder (distance to the ground along body −z, max range), battery (open-circuit voltage
from the state of charge, sag I·R, current from the motor thrusts). Faults change what the
models output: dropout (no sample), freeze (last sample repeated), GNSS loss, spoofing (drift at a
rate, a jump, meaconing: the position of `gps_delay_s` ago, stamped now) and jamming (fixes lost
with a probability, noise and reported σ multiplied), battery drain factor. The node turns samples
into sensor_msgs.
"""

from __future__ import annotations

import math
import random
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field, fields

from c4d_common import quat
from c4d_common.geodesy import GeoOrigin, pressure_at_altitude

from .plant import PlantState

Vec = tuple[float, float, float]
RANGE_MIN = 0.05  # [m] minimum range of the downward range finder
GPS_DELAY_MAX_S = 60.0  # [s] longest meaconing delay (the receiver's true-position history is kept this long)
EARTH_FIELD_ENU: Vec = (0.0, 2.2e-5, -4.2e-5)  # [T] ~ mid-latitude: 22 µT north, 42 µT down


def _clip(value: float, full_scale: float) -> float:
    return max(-full_scale, min(full_scale, value))


class SensorConfigError(ValueError):
    """Invalid sensor configuration (names the field)."""


@dataclass(frozen=True)
class SensorConfig:
    imu_rate_hz: float = 500.0
    gyro_noise: float = 0.003  # [rad/s] per sample
    gyro_bias_walk: float = 2e-4  # [rad/s/√s]
    gyro_bias_initial: float = 0.01  # [rad/s] σ of the turn-on bias
    accel_noise: float = 0.05  # [m/s²] per sample
    accel_bias_walk: float = 1e-3  # [m/s²/√s]
    accel_bias_initial: float = 0.05
    accel_range: float = 156.9  # [m/s²] full scale (±16 g): readings beyond it are clipped, as a MEMS part does
    gyro_range: float = 34.9  # [rad/s] full scale (±2000 °/s)
    gps_rate_hz: float = 10.0
    gps_noise_horizontal: float = 0.3  # [m] σ
    gps_noise_vertical: float = 0.5
    gps_latency_s: float = 0.05
    baro_rate_hz: float = 50.0
    baro_noise: float = 0.1  # [m] equivalent σ
    mag_rate_hz: float = 50.0
    mag_noise: float = 3e-7  # [T] σ
    range_rate_hz: float = 50.0
    range_noise: float = 0.02
    range_max: float = 10.0
    battery_rate_hz: float = 10.0
    battery_cells: int = 4
    battery_capacity_ah: float = 5.0
    battery_resistance: float = 0.03  # [Ω] pack
    amps_per_newton: float = 1.3  # motor current per newton of thrust
    avionics_amps: float = 0.8

    @classmethod
    def from_dict(cls, doc: Mapping | None) -> SensorConfig:
        doc = dict(doc or {})
        known = {f.name: f for f in fields(cls)}
        for key, value in doc.items():
            if key not in known:
                raise SensorConfigError(f"sensors: unknown field '{key}'")
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
                raise SensorConfigError(f"sensors: field '{key}' must be a non-negative number, got {value!r}")
        for key in ("imu_rate_hz", "gps_rate_hz", "baro_rate_hz", "mag_rate_hz", "range_rate_hz", "battery_rate_hz",
                    "battery_capacity_ah", "range_max", "accel_range", "gyro_range"):
            if key in doc and doc[key] <= 0:
                raise SensorConfigError(f"sensors: field '{key}' must be > 0")
        if "battery_cells" in doc:
            doc["battery_cells"] = int(doc["battery_cells"])
        return cls(**doc)


@dataclass
class Faults:
    """Active faults (set by the node's parameters). Dropout = no samples, freeze = stuck."""

    imu_dropout: bool = False
    imu_freeze: bool = False
    gps_loss: bool = False
    gps_drift: Vec = (0.0, 0.0, 0.0)  # [m/s] drift rate of the reported position (ENU)
    gps_jump: Vec = (0.0, 0.0, 0.0)  # [m] step added to the reported position (ENU)
    gps_delay_s: float = 0.0  # [s] meaconing: fixes report the true position this long ago, stamped now
    gps_jam_dropout: float = 0.0  # probability that a fix is lost (jamming)
    gps_jam_sigma_factor: float = 1.0  # jamming: noise and reported σ multiplied (HDOP-like)
    baro_dropout: bool = False
    baro_freeze: bool = False
    mag_dropout: bool = False
    range_dropout: bool = False
    battery_drain_factor: float = 1.0


@dataclass
class ImuSample:
    stamp: float
    gyro: Vec
    accel: Vec
    orientation: quat.Quat


@dataclass
class GpsSample:
    stamp: float  # measurement time (published `latency` later)
    latitude: float
    longitude: float
    altitude: float
    sigma_h: float
    sigma_v: float


@dataclass
class BatterySample:
    stamp: float
    voltage: float
    current: float
    charge_ah: float
    percentage: float


@dataclass
class SensorSuite:
    config: SensorConfig
    origin: GeoOrigin
    seed: int = 0
    faults: Faults = field(default_factory=Faults)

    def __post_init__(self) -> None:
        c = self.config
        self.rng = random.Random(self.seed)
        g = self.rng.gauss
        self.gyro_bias = [g(0, c.gyro_bias_initial) for _ in range(3)]
        self.accel_bias = [g(0, c.accel_bias_initial) for _ in range(3)]
        self.drift = [0.0, 0.0, 0.0]
        self.gps_history: deque[tuple[float, Vec]] = deque()  # (t, true position) at each GNSS sample, for meaconing
        self.charge_used_ah = 0.0
        self._last_imu: ImuSample | None = None
        self._last_baro: tuple[float, float] | None = None

    def _walk(self, bias: list[float], rate: float, dt: float) -> None:
        s = rate * math.sqrt(dt)
        for k in range(3):
            bias[k] += self.rng.gauss(0, s)

    def imu(self, s: PlantState, dt: float) -> ImuSample | None:
        c, f = self.config, self.faults
        self._walk(self.gyro_bias, c.gyro_bias_walk, dt)
        self._walk(self.accel_bias, c.accel_bias_walk, dt)
        specific_force, angular_velocity = s.take_imu_means()  # filtered over the sample interval
        if f.imu_dropout:
            return None
        if f.imu_freeze and self._last_imu is not None:
            return ImuSample(s.t, self._last_imu.gyro, self._last_imu.accel, self._last_imu.orientation)
        g = self.rng.gauss
        gyro = tuple(_clip(angular_velocity[k] + self.gyro_bias[k] + g(0, c.gyro_noise), c.gyro_range) for k in range(3))
        accel = tuple(_clip(specific_force[k] + self.accel_bias[k] + g(0, c.accel_noise), c.accel_range)
                      for k in range(3))
        sample = ImuSample(s.t, gyro, accel, s.orientation)  # type: ignore[arg-type]
        self._last_imu = sample
        return sample

    def gps(self, s: PlantState, dt: float) -> GpsSample | None:
        c, f = self.config, self.faults
        for k in range(3):
            self.drift[k] += f.gps_drift[k] * dt
        history = self.gps_history
        history.append((s.t, s.position))
        while history[0][0] < s.t - GPS_DELAY_MAX_S:
            history.popleft()
        if f.gps_loss:
            return None
        if f.gps_jam_dropout > 0.0 and self.rng.random() < f.gps_jam_dropout:
            return None
        g, jump = self.rng.gauss, f.gps_jump
        sigma_h, sigma_v = c.gps_noise_horizontal * f.gps_jam_sigma_factor, c.gps_noise_vertical * f.gps_jam_sigma_factor
        p = self.position_at(s.t - f.gps_delay_s) if f.gps_delay_s > 0.0 else s.position
        e = p[0] + self.drift[0] + jump[0] + g(0, sigma_h)
        n = p[1] + self.drift[1] + jump[1] + g(0, sigma_h)
        u = p[2] + self.drift[2] + jump[2] + g(0, sigma_v)
        lat, lon, alt = self.origin.to_geodetic(e, n, u)
        return GpsSample(s.t, lat, lon, alt, sigma_h, sigma_v)

    def position_at(self, t: float) -> Vec:
        """The true position at time t, linear between the GNSS samples' history (the oldest before it)."""
        history = self.gps_history
        if t <= history[0][0]:
            return history[0][1]
        for i in range(len(history) - 1, 0, -1):  # newest first: a delay of seconds looks back a few dozen entries
            t0, p0 = history[i - 1]
            if t0 <= t:
                t1, p1 = history[i]
                a = min(1.0, (t - t0) / (t1 - t0)) if t1 > t0 else 1.0
                return (p0[0] + a * (p1[0] - p0[0]), p0[1] + a * (p1[1] - p0[1]), p0[2] + a * (p1[2] - p0[2]))
        return history[-1][1]

    def baro(self, s: PlantState) -> tuple[float, float] | None:
        """(stamp, static pressure [Pa])."""
        if self.faults.baro_dropout:
            return None
        if self.faults.baro_freeze and self._last_baro is not None:
            return (s.t, self._last_baro[1])
        altitude = self.origin.altitude + s.position[2] + self.rng.gauss(0, self.config.baro_noise)
        self._last_baro = (s.t, pressure_at_altitude(altitude))
        return self._last_baro

    def mag(self, s: PlantState) -> Vec | None:
        if self.faults.mag_dropout:
            return None
        b = quat.rotate_inverse(s.orientation, EARTH_FIELD_ENU)
        g, sigma = self.rng.gauss, self.config.mag_noise
        return (b[0] + g(0, sigma), b[1] + g(0, sigma), b[2] + g(0, sigma))

    def range_down(self, s: PlantState) -> float | None:
        """Distance along body −z to flat ground; REP 117: +inf = nothing within range,
        −inf = closer than the minimum range (e.g. standing on the ground)."""
        if self.faults.range_dropout:
            return None
        cos_tilt = quat.body_z(s.orientation)[2]
        if cos_tilt <= 0.1:
            return math.inf
        distance = s.position[2] / cos_tilt + self.rng.gauss(0, self.config.range_noise)
        if distance < RANGE_MIN:
            return -math.inf
        return distance if distance <= self.config.range_max else math.inf

    def battery(self, s: PlantState, dt: float) -> BatterySample:
        c = self.config
        current = c.avionics_amps + c.amps_per_newton * sum(s.thrusts)
        self.charge_used_ah += current * dt / 3600.0 * self.faults.battery_drain_factor
        soc = max(0.0, 1.0 - self.charge_used_ah / c.battery_capacity_ah)
        open_circuit = c.battery_cells * (3.3 + 0.9 * soc)  # 4.2 V/cell full, 3.3 V/cell empty
        return BatterySample(s.t, open_circuit - current * c.battery_resistance, current,
                             c.battery_capacity_ah * soc, soc)
