"""Navigation EKF on deterministic synthetic sensor streams (plant in closed loop + sensor models)."""

import math

import numpy as np
import pytest

from c4d_common import quat
from c4d_common.geodesy import GeoOrigin, pressure_at_altitude
from c4d_gnc.ekf import NavigationEkf
from c4d_gnc.gnc import Command, Request
from c4d_sim.sensors import SensorConfig, SensorSuite

HOME = GeoOrigin(43.5629, 1.4815, 146.0)


class Flight:
    """Closed loop with the sensor suite feeding an EKF (the EKF does not steer the vehicle)."""

    def __init__(self, make_loop, seed=2):
        self.loop = make_loop()
        self.sensors = SensorSuite(SensorConfig(), HOME, seed=seed)
        self.ekf = NavigationEkf()
        self.errors: list[tuple[float, float]] = []

    def step(self, ticks, record=True):
        loop, sens, ekf, dt = self.loop, self.sensors, self.ekf, self.loop.tick_s
        for _ in range(ticks):
            loop.executive.step()
            s, k = loop.plant.state, loop.executive.tick
            imu = sens.imu(s, dt)
            mag = sens.mag(s) if k % 10 == 0 else None
            if imu is None:
                continue
            if not ekf.aligned:
                ekf.align(imu.accel, mag)
                continue
            ekf.predict(imu.gyro, imu.accel, dt)
            if k % 50 == 0:
                g = sens.gps(s, 0.1)
                if g is not None:
                    ekf.update_gps(g.latitude, g.longitude, g.altitude, g.sigma_h, g.sigma_v)
            if k % 10 == 0:
                b = sens.baro(s)
                if b is not None:
                    ekf.update_baro(b[1])
                if mag is not None:
                    ekf.update_mag(mag)
            if record and ekf.origin is not None:
                est = HOME.to_enu(*ekf.origin.to_geodetic(*ekf.p))
                self.errors.append((math.hypot(est[0] - s.position[0], est[1] - s.position[1]),
                                    math.degrees(quat.angle_between(s.orientation, ekf.q))))


def test_estimates_position_attitude_and_biases(make_loop):
    f = Flight(make_loop)
    f.step(1500, record=False)  # alignment and home averaging on the ground
    f.loop.command(Request(Command.TAKEOFF, altitude=5.0))
    f.step(3000, record=False)
    f.step(10000)
    horizontal = math.sqrt(np.mean(np.square([e[0] for e in f.errors])))
    attitude = math.sqrt(np.mean(np.square([e[1] for e in f.errors])))
    assert horizontal <= 0.3 and attitude <= 2.0, (horizontal, attitude)
    assert np.allclose(f.ekf.bg, f.sensors.gyro_bias, atol=0.003)
    assert f.ekf.position_valid and f.ekf.heading_valid
    assert f.ekf.rejected == {"gps": 0, "baro": 0, "mag": 0, "drag": 0}


def test_survives_gps_and_mag_loss_with_flags(make_loop):
    f = Flight(make_loop)
    f.step(1500, record=False)
    f.loop.command(Request(Command.TAKEOFF, altitude=3.0))
    f.step(3000, record=False)
    cov_before = np.trace(f.ekf.P[0:3, 0:3])
    f.sensors.faults.gps_loss = True
    f.sensors.faults.mag_dropout = True
    f.step(1500, record=False)  # 3 s without GNSS nor magnetometer
    assert not f.ekf.position_valid and not f.ekf.heading_valid
    assert np.trace(f.ekf.P[0:3, 0:3]) > cov_before
    assert f.ekf.aligned and np.all(np.isfinite(f.ekf.p))  # still running, attitude still propagated
    f.sensors.faults.gps_loss = False
    f.sensors.faults.mag_dropout = False
    f.step(1500, record=False)
    assert f.ekf.position_valid and f.ekf.heading_valid


def test_outliers_are_gated_and_counted():
    ekf = NavigationEkf()
    for _ in range(60):
        ekf.align((0.0, 0.0, 9.80665), (0.0, 2.2e-5, -4.2e-5))
    for _ in range(25):
        for _ in range(50):
            ekf.predict((0.0, 0.0, 0.0), (0.0, 0.0, 9.80665), 0.002)
        ekf.update_gps(HOME.latitude, HOME.longitude, HOME.altitude, 0.3, 0.5)
        ekf.update_baro(pressure_at_altitude(HOME.altitude))
    assert ekf.origin is not None and ekf.position_valid
    far = HOME.to_geodetic(100.0, 0.0, 0.0)  # a 100 m jump
    assert not ekf.update_gps(*far, 0.3, 0.5)
    assert ekf.rejected["gps"] == 1 and abs(ekf.p[0]) < 0.5
    assert not ekf.update_baro(pressure_at_altitude(HOME.altitude + 50.0)) and ekf.rejected["baro"] == 1


@pytest.mark.parametrize("yaw_deg", [-120.0, 0.0, 45.0, 170.0])
def test_alignment_recovers_heading_from_the_magnetometer(yaw_deg):
    ekf = NavigationEkf()
    q = quat.from_euler(0.02, -0.03, math.radians(yaw_deg))
    field = quat.rotate_inverse(q, (0.0, 2.2e-5, -4.2e-5))
    accel = quat.rotate_inverse(q, (0.0, 0.0, 9.80665))
    while not ekf.align(accel, field):
        pass
    assert math.degrees(quat.angle_between(ekf.q, q)) < 0.1


def test_gnss_back_after_divergence_resets_position():
    """Dead reckoning drifted far beyond the innovation gate (here: forced 300 m and 20 m/s off):
    the first fix after the outage resets the position instead of being rejected forever."""
    ekf = NavigationEkf()
    s_home = HOME.to_geodetic(0.0, 0.0, 0.0)
    while not ekf.align((0.0, 0.0, 9.81), (0.2, 0.0, -0.4)):
        pass
    for _ in range(20):
        ekf.update_gps(*s_home, 0.5, 1.0)
    assert ekf.origin is not None
    ekf.p[:] = (300.0, -50.0, 0.0)
    ekf.v[:] = (20.0, 0.0, 0.0)
    ekf.t = 10.0  # last fix long ago
    lat, lon, alt = HOME.to_geodetic(2.0, 1.0, 0.0)
    assert ekf.update_gps(lat, lon, alt, 0.5, 1.0)
    assert ekf.resets == 1 and np.allclose(ekf.p, ekf.origin.to_enu(lat, lon, alt), atol=1e-6)
    assert np.allclose(ekf.v, 0.0) and ekf.position_valid


@pytest.mark.parametrize("zupt", [False, True])
def test_zero_velocity_updates_bound_drift_on_the_ground_without_gnss(make_loop, zupt):
    """Standing disarmed without GNSS for 30 s: zero-velocity updates keep the estimate within
    a metre; without them the accelerometer noise and bias walk integrate freely."""
    f = Flight(make_loop)
    f.step(1500, record=False)
    assert f.ekf.position_valid
    f.sensors.faults.gps_loss = True
    start = f.ekf.p.copy()
    for _ in range(300):  # 30 s
        f.step(50, record=False)
        if zupt:
            f.ekf.update_zero_velocity()
    drift = float(np.linalg.norm(f.ekf.p[:2] - start[:2]))
    if zupt:
        assert drift < 1.0 and float(np.linalg.norm(f.ekf.v)) < 0.1, drift
    else:
        assert drift > 1.0, drift  # the reason for the updates
