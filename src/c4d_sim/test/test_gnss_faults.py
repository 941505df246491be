"""GNSS spoofing and jamming fault modes on the fixes (seeded, no DDS): drift at a rate, jump, meaconing
delay, jam dropouts, jam noise/covariance factor; GNSS lost from boot (fault.gps_loss as a start value)."""

from __future__ import annotations

import statistics
import time
from dataclasses import replace

import pytest

from c4d_sim.plant import PlantState
from c4d_sim.sensors import SensorSuite
from c4d_sim.sim_config import default_sim_config, load_sim_config
from c4d_sim.simulation import Simulation

CONFIG = load_sim_config(default_sim_config())
QUIET = replace(CONFIG.sensors, gps_noise_horizontal=0.0, gps_noise_vertical=0.0)


def fly(suite: SensorSuite, seconds: float, speed_e: float = 2.0):
    """10 Hz fixes of a vehicle flying east at `speed_e` m/s, 10 m up: [(t, true position, ENU fix, sample)]."""
    out = []
    for k in range(round(seconds * 10)):
        t = 0.1 * k
        state = PlantState(t=t, position=(speed_e * t, 1.0, 10.0))
        fix = suite.gps(state, 0.1)
        if fix is not None:
            out.append((t, state.position, suite.origin.to_enu(fix.latitude, fix.longitude, fix.altitude), fix))
    return out


def test_jump_is_a_step_in_the_reported_position():
    suite = SensorSuite(QUIET, CONFIG.origin, seed=1)
    before = fly(suite, 1.0)
    suite.faults.gps_jump = (50.0, -20.0, 3.0)
    after = fly(suite, 1.0)
    assert all(fix == pytest.approx(p, abs=1e-6) for _, p, fix, _ in before)
    assert all(fix == pytest.approx((p[0] + 50.0, p[1] - 20.0, p[2] + 3.0), abs=1e-6) for _, p, fix, _ in after)


def test_drift_grows_at_its_rate():
    suite = SensorSuite(QUIET, CONFIG.origin, seed=1)
    suite.faults.gps_drift = (1.0, 0.0, 0.0)
    out = fly(suite, 10.0)
    t, p, fix, _ = out[-1]
    assert fix[0] - p[0] == pytest.approx(1.0 * (t + 0.1), abs=1e-6) and fix[1] == pytest.approx(p[1], abs=1e-6)


def test_meaconing_reports_where_the_vehicle_was_stamped_now():
    suite = SensorSuite(QUIET, CONFIG.origin, seed=1)
    fly(suite, 5.0)  # the receiver's history
    suite.faults.gps_delay_s = 1.55  # between two 10 Hz history entries: interpolated
    out = list(fly_from(suite, 5.0, 3.0))
    assert len(out) == 30
    for t, _, fix, sample in out:
        assert sample.stamp == t  # stamped at the sample time, not the delayed one
        assert fix == pytest.approx((2.0 * (t - 1.55), 1.0, 10.0), abs=1e-6)  # 3.1 m behind at 2 m/s


def fly_from(suite: SensorSuite, t0: float, seconds: float):
    for k in range(round(seconds * 10)):
        t = t0 + 0.1 * k
        state = PlantState(t=t, position=(2.0 * t, 1.0, 10.0))
        fix = suite.gps(state, 0.1)
        assert fix is not None
        yield t, state.position, suite.origin.to_enu(fix.latitude, fix.longitude, fix.altitude), fix


def test_meaconing_before_the_history_reports_the_oldest_position():
    suite = SensorSuite(QUIET, CONFIG.origin, seed=1)
    suite.faults.gps_delay_s = 30.0
    out = fly(suite, 2.0)
    assert all(fix == pytest.approx((0.0, 1.0, 10.0), abs=1e-6) for _, _, fix, _ in out)


def test_jamming_loses_fixes_with_its_probability():
    suite = SensorSuite(CONFIG.sensors, CONFIG.origin, seed=5)
    suite.faults.gps_jam_dropout = 0.4
    out = fly(suite, 200.0)
    assert len(out) / 2000 == pytest.approx(0.6, abs=0.03)
    suite.faults.gps_jam_dropout = 1.0
    assert fly(suite, 1.0) == []


def test_jamming_multiplies_noise_and_reported_sigma():
    suite = SensorSuite(CONFIG.sensors, CONFIG.origin, seed=5)
    suite.faults.gps_jam_sigma_factor = 4.0
    out = fly(suite, 200.0)
    east = [fix[0] - p[0] for _, p, fix, _ in out]
    up = [fix[2] - p[2] for _, p, fix, _ in out]
    assert statistics.stdev(east) == pytest.approx(4.0 * 0.3, rel=0.06)
    assert statistics.stdev(up) == pytest.approx(4.0 * 0.5, rel=0.06)
    assert (out[0][3].sigma_h, out[0][3].sigma_v) == pytest.approx((1.2, 2.0))


def test_gnss_lost_from_boot_gives_no_fix_while_the_other_sensors_run():
    t0 = time.monotonic_ns()
    sim = Simulation(CONFIG, lambda: t0)
    assert sim.set_fault("gps_loss", True) is None  # what the node does with the start value fault.gps_loss:=true
    fixes, baro = [], 0
    for k in range(1000):
        sim.physics(k)
        if k % 100 == 0:
            fixes += sim.gps_fixes()
        baro += sim.suite.baro(sim.plant.state) is not None
    assert fixes == [] and baro == 1000 and sim.imu.sampled == 500
    sim.set_fault("gps_loss", False)
    for k in range(1000, 1200):
        sim.physics(k)
        if k % 100 == 0:
            fixes += sim.gps_fixes()
    assert len(fixes) == 1  # fixes resume (the second one is still in its latency)


def test_a_zero_drift_rate_set_at_run_time_ends_the_spoofing():
    t0 = time.monotonic_ns()
    sim = Simulation(CONFIG, lambda: t0)
    assert sim.set_fault("gps_drift_m_s", [2.0, 0.0, 0.0]) is None
    sim.suite.gps(PlantState(), 1.0)  # one second of drift
    assert sim.suite.drift == [2.0, 0.0, 0.0]
    sim.set_fault("gps_drift_m_s", [0.0, 0.0, 0.0])
    assert sim.suite.drift == [0.0, 0.0, 0.0]
