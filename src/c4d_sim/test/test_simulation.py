"""The simulator without DDS: typed configuration, executive task table, fault settings, motor
command with the ESC failsafe, GNSS latency."""

from __future__ import annotations

import math
import time

import pytest

from c4d_sim.sim_config import SimConfig, SimConfigError, default_sim_config, load_sim_config
from c4d_sim.simulation import ESC_TIMEOUT_S, SENSOR_TASKS, Simulation, task_specs


@pytest.fixture(scope="module")
def config() -> SimConfig:
    return load_sim_config(default_sim_config())


def simulation(config: SimConfig) -> Simulation:
    t0 = time.monotonic_ns()
    return Simulation(config, lambda: t0)


def test_default_config_is_typed(config):
    assert config.physics_rate_hz == 1000 and config.truth_rate_hz == 100.0
    assert abs(config.origin.latitude - 43.5629) < 1e-9 and len(config.wind_mean) == 3
    assert len(config.airframe.motors) == 4


def test_task_table_and_rates_that_do_not_divide(config):
    specs = task_specs(config)
    assert [s.name for s in specs] == ["physics", *SENSOR_TASKS]
    assert {s.name: s.divider for s in specs}["imu"] == 2 and specs[0].divider == 1
    from dataclasses import replace

    bad = replace(config, sensors=replace(config.sensors, imu_rate_hz=300.0))
    with pytest.raises(SimConfigError, match="300.0 Hz rate does not divide the physics rate 1000 Hz"):
        task_specs(bad)


def test_faults_are_applied_or_refused_with_a_reason(config):
    sim = simulation(config)
    assert sim.set_fault("imu_dropout", True) is None and sim.faults.imu_dropout
    assert sim.set_fault("gps_drift_m_s", [1.0, 0.0, -1.0]) is None and sim.faults.gps_drift == (1.0, 0.0, -1.0)
    assert sim.set_fault("motor_health", [1.0, 0.5, 1.0, 1.0]) is None and sim.plant.motor_health[1] == 0.5
    assert sim.set_fault("wind_gust_m_s", 3.0) is None and sim.extra_gust == 3.0
    assert sim.set_fault("motor_health", [1.0, 2.0]) == "motor_health needs 4 values in [0, 1]"
    assert sim.set_fault("gps_drift_m_s", [1.0]) == "gps_drift_m_s needs 3 finite values [e, n, u]"
    assert sim.set_fault("gps_jump_m", [5.0, -2.0, 0.0]) is None and sim.faults.gps_jump == (5.0, -2.0, 0.0)
    assert sim.set_fault("gps_jump_m", [1.0, math.nan, 0.0]) == "gps_jump_m needs 3 finite values [e, n, u]"
    assert sim.set_fault("gps_delay_s", 2.0) is None and sim.faults.gps_delay_s == 2.0
    assert sim.set_fault("gps_delay_s", 61.0) == "gps_delay_s must be in [0, 60]"
    assert sim.set_fault("gps_jam_dropout", 1.5) == "gps_jam_dropout must be in [0, 1]"
    assert sim.set_fault("gps_jam_sigma_factor", 0.5) == "gps_jam_sigma_factor must be in [1, 1000]"
    assert sim.set_fault("gps_jam_sigma_factor", 4.0) is None and sim.faults.gps_jam_sigma_factor == 4.0
    assert sim.set_fault("battery_drain_factor", -1.0) == "battery_drain_factor must be >= 0"
    assert sim.set_fault("no_such_fault", 1) is not None


def test_motor_command_and_esc_failsafe(config):
    sim = simulation(config)
    sim.command([0.9] * 3, True)  # wrong motor count: ignored
    assert not sim.armed
    sim.command([0.9] * 4, True)
    for k in range(200):
        sim.physics(k)
    assert sim.plant.state.position[2] > 0.0 and abs(sim.plant.state.t - 0.2) < 1e-9  # it lifts off
    sim.command_t -= ESC_TIMEOUT_S  # the command is now too old: the ESCs stop the motors
    sim.physics(400)  # a stall: the 200 skipped ticks are simulated too
    assert abs(sim.plant.state.t - 0.401) < 1e-9 and max(sim.plant.state.thrusts) < 0.02  # from ~8 N


def test_gnss_fix_is_released_after_its_latency(config):
    sim = simulation(config)
    assert sim.gps_fixes() == []  # measured at t = 0, due at t = 0.05 s
    for k in range(50):
        sim.physics(k)
    fixes = sim.gps_fixes()
    assert [f.stamp for f in fixes] == [0.0]


def test_imu_keeps_its_rate_and_stamps_through_a_stall(config):
    """Issue 14 item 7: after a stall the skipped physics steps are simulated and the IMU is sampled
    at each of its periods (own stamp, 2 ms apart), published late at once, none merged or lost."""
    sim = simulation(config)
    for k in range(10):
        sim.physics(k)
    assert [s.stamp for s in sim.imu.take()] == pytest.approx([0.002 * n for n in range(1, 6)])
    sim.physics(40)  # 30 ticks late: 15 IMU periods elapsed
    batch = sim.imu.take()
    assert [s.stamp for s in batch] == pytest.approx([0.002 * n for n in range(6, 21)])
    assert (sim.imu.sampled, sim.imu.late, sim.imu.dropped) == (20, 4 + 14, 0)


def test_an_imu_sample_is_never_taken_before_its_stamp(config):
    """Issue 16: the plant runs one physics period ahead of the tick that steps it; after a catch-up the
    newest sample can be stamped in the future. take(until) holds it back until its time comes."""
    sim = simulation(config)
    sim.physics(9)  # steps to t = 0.010: samples 0.002 .. 0.010
    batch = sim.imu.take(until=0.009)  # the present is 0.009 s: the 0.010 sample is not measured yet
    assert [s.stamp for s in batch] == pytest.approx([0.002, 0.004, 0.006, 0.008])
    assert [s.stamp for s in sim.imu.take(until=0.0101)] == pytest.approx([0.010])
    assert sim.imu.late == 3
    assert 0.0 <= sim.present() < 1.0  # real time: wall clock since tick 0 (anchored a moment ago)
    sim.anchor_epoch = False  # lockstep: simulated time is the present, nothing is held back
    assert sim.present() == math.inf


def test_imu_backlog_beyond_its_bound_is_dropped_and_counted(config):
    from c4d_ros.qos import Profile
    from c4d_sim.simulation import IMU_MAX_BACKLOG_S

    sim = simulation(config)
    bound = sim.imu.max_samples
    assert bound == round(IMU_MAX_BACKLOG_S * config.sensors.imu_rate_hz)
    assert Profile.IMU.value.depth >= bound  # a whole catch-up burst fits the subscribers' queues
    sim.physics(2 * 2 * bound - 1)  # a stall of two backlogs: the older half cannot be delivered
    batch = sim.imu.take()
    assert len(batch) == bound and sim.imu.dropped == bound and batch[-1].stamp == pytest.approx(sim.plant.state.t)
    sim.set_fault("imu_dropout", True)
    sim.physics(2 * 2 * bound + 9)
    assert sim.imu.take() == [] and sim.imu.sampled == 2 * bound  # a dropout samples nothing


def test_unusable_sim_config_files_are_one_line_errors(tmp_path):
    """The sim config is read by the shared loader: the same one-line errors as every c4d config."""
    cases = {"list.yaml": ("- 1\n- 2\n", "must be a mapping"),
             "typo.yaml": ("phyiscs_rate_hz: 1000\n", "unknown field(s) phyiscs_rate_hz"),
             "broken.yaml": ("start: [1, 2\n", "line 2")}
    for name, (text, expected) in cases.items():
        path = tmp_path / name
        path.write_text(text)
        with pytest.raises(SimConfigError) as err:
            load_sim_config(path)
        assert expected in str(err.value) and "\n" not in str(err.value), err.value
    with pytest.raises(SimConfigError, match="cannot read sim config"):
        load_sim_config(tmp_path / "missing.yaml")
