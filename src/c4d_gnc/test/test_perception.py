"""Sensor monitor: validation limits and health classification (ROS-free)."""

import math

from c4d_gnc.perception import Health, ImuCalibration, SensorMonitor, valid_fix, valid_imu, valid_mag, valid_pressure, valid_range


def test_validation_rejects_nan_and_out_of_range():
    assert valid_imu((0.1, 0.0, 0.0), (0.0, 0.0, 9.8))
    assert not valid_imu((math.nan, 0.0, 0.0), (0.0, 0.0, 9.8))
    assert not valid_imu((0.0, 0.0, 0.0), (0.0, 0.0, 200.0))
    assert valid_pressure(101325.0) and not valid_pressure(5000.0) and not valid_pressure(math.inf)
    assert valid_mag((0.0, 2e-5, -4e-5)) and not valid_mag((0.0, 0.0, 0.0)) and not valid_mag((1.0, 0.0, 0.0))
    assert valid_fix(43.5, 1.4, 150.0, True) and not valid_fix(43.5, 1.4, 150.0, False)
    assert not valid_fix(95.0, 1.4, 150.0, True)
    assert valid_range(math.inf) and valid_range(-math.inf) and valid_range(2.0)
    assert not valid_range(math.nan) and not valid_range(-1.0)


def test_health_states():
    m = SensorMonitor("imu", expected_rate_hz=100.0, timeout_s=0.05, frozen_count=10)
    assert m.health(0.0) == Health.WAITING
    for k in range(20):
        m.accept(k * 0.01, (float(k),), True)
    assert m.health(0.195) == Health.OK and abs(m.rate() - 100.0) < 1.0
    assert m.health(0.5) == Health.STALE
    for k in range(20, 40):
        m.accept(k * 0.01, (1.0,), True)  # the same value again and again
    assert m.health(0.395) == Health.FROZEN
    for k in range(40, 100):
        m.accept(k * 0.01, (math.nan,), False)
    assert m.health(0.995) == Health.INVALID and m.rejected == 60
    slow = SensorMonitor("gps", 10.0, 5.0)
    for k in range(12):
        slow.accept(k * 0.5, (float(k),), True)
    assert slow.health(5.6) == Health.LOW_RATE


def test_calibration_is_applied():
    cal = ImuCalibration(gyro_offset=(0.01, 0.0, 0.0), accel_offset=(0.0, 0.1, 0.0), accel_scale=(1.0, 1.0, 0.5))
    gyro, accel = cal.apply((0.01, 0.0, 0.0), (0.0, 0.1, 19.6))
    assert gyro == (0.0, 0.0, 0.0) and accel == (0.0, 0.0, 9.8)
