"""Deterministic closed loop (plant + GNC core + executive on a fake clock, sensor noise)."""

import math

import numpy as np
import pytest
from closed_loop import NO_NOISE

from c4d_common import quat
from c4d_gnc.gnc import Command, Landed, Level, Mode, Nav, Request, Setpoint
from c4d_gnc.setpoint_sources import owner


def hover(loop, altitude=5.0, settle=5.0):
    loop.take_off(altitude)
    loop.run(settle)
    return len(loop.trace.t)


def follow(loop, seconds, make_setpoint, every=0.02):
    for _ in range(round(seconds / every)):
        out = loop.core.out
        loop.core.receive_setpoint(owner(out.mode, out.nav), make_setpoint())  # as the mode's source would
        loop.run(every)


@pytest.mark.parametrize("airframe", ["quad_x", "hexa_x"])
def test_hover_holds_position_within_5_cm_rms(make_loop, airframe):
    loop = make_loop(airframe)
    n0 = hover(loop)
    loop.run(30.0)
    err = np.array(loop.trace.position[n0:]) - np.array([0.0, 0.0, 5.0])
    rms = math.sqrt((err ** 2).sum(axis=1).mean())
    assert rms <= 0.05, rms
    assert loop.core.out.landed == Landed.IN_AIR and loop.executive.profiler.overruns_total == 0


def test_takeoff_profile_then_land_and_disarm(make_loop):
    loop = make_loop()
    loop.take_off(3.0)
    z = [p[2] for p in loop.trace.position]
    assert max(z) < 3.0 * 1.1 and abs(loop.plant.state.position[2] - 3.0) < 0.2
    ok, _ = loop.core.request(Request(Command.LAND))
    assert ok
    assert loop.run_until(lambda: not loop.core.out.armed, timeout=15.0)
    assert loop.core.out.landed == Landed.ON_GROUND and loop.plant.state.position[2] < 0.01
    assert "landed" in loop.core.out.events
    loop.run(0.1)
    assert all(c == 0.0 for c in loop.core.out.commands)


@pytest.mark.parametrize("range_lost", [False, True])
def test_gnss_loss_then_land_descends_level_and_disarms(make_loop, range_lost):
    """Blind descent: with the horizontal estimate drifting at 0.5 m/s the core must not chase it
    (the vehicle stays within a metre), and touchdown is still detected, with or without range."""
    loop = make_loop()
    loop.take_off(5.0)
    loop.position_lost_at, loop.range_lost = loop.t, range_lost
    start, t_land, n0 = loop.plant.state.position, loop.t, len(loop.trace.t)
    ok, _ = loop.core.request(Request(Command.LAND))
    assert ok
    assert loop.run_until(lambda: not loop.core.out.armed, timeout=15.0)
    end = loop.plant.state.position
    assert end[2] < 0.01 and math.dist(start[:2], end[:2]) < 1.0, (start, end)
    # blind, it descends at max_descent_speed down to BLIND_SLOW_BELOW_M, then at land_speed (less time to drift):
    # from 5 m 5.3 s to the ground instead of 8.0 s (with the speed ramps), and the touchdown as soft as a normal one
    af = loop.core.af
    t = np.array(loop.trace.t[n0:])
    z = np.array([p[2] for p in loop.trace.position[n0:]])
    vz = np.gradient(z, t)
    grounded = t[np.argmax(z < 0.02)] - t_land
    assert grounded < 6.0, grounded  # 8.0 s at land_speed all the way
    assert vz.min() < -0.9 * af.max_descent_speed, vz.min()
    low = z < 0.5
    assert -vz[low].min() < af.land_speed * 1.3, (vz[low].min(), af.land_speed)


def test_position_step_5_m_settles_in_4_s_without_overshoot(make_loop):
    loop = make_loop()
    hover(loop)
    loop.core.request(Request(Command.SET_MODE, Mode.AUTO))
    loop.run(0.02)
    loop.core.out.nav = Nav.GOTO  # follow external guidance setpoints, as the mission node will
    n0, t0 = len(loop.trace.t), loop.t
    follow(loop, 8.0, lambda: Setpoint(loop.t, Level.POSITION, (5.0, 0.0, 5.0), (0.0, 0.0, 0.0), yaw=0.0))
    t = np.array(loop.trace.t[n0:]) - t0
    x = np.array(loop.trace.position[n0:])[:, 0]
    overshoot = (x.max() - 5.0) / 5.0
    outside = np.nonzero(np.abs(x - 5.0) > 0.1)[0]  # 2 % band
    settle = t[outside[-1]] if len(outside) else 0.0
    assert overshoot < 0.10 and settle < 4.0, (overshoot, settle)


def test_attitude_step_20_deg_rise_time_below_0_3_s(make_loop):
    loop = make_loop()
    hover(loop)
    loop.core.request(Request(Command.SET_MODE, Mode.ATTITUDE))
    target = quat.from_euler(math.radians(20), 0.0, 0.0)
    thrust = loop.core.af.hover_command / math.cos(math.radians(20))
    n0, t0 = len(loop.trace.t), loop.t
    follow(loop, 0.6, lambda: Setpoint(loop.t, Level.ATTITUDE, orientation=target, thrust=thrust), every=0.002)
    t = np.array(loop.trace.t[n0:]) - t0
    roll = np.degrees([quat.to_euler(q)[0] for q in loop.trace.orientation[n0:]])
    rise = t[np.argmax(roll >= 18.0)] - t[np.argmax(roll >= 2.0)]
    assert rise < 0.3 and abs(roll[-1] - 20.0) < 2.0, (rise, roll[-1])


def test_one_motor_saturated_attitude_still_controlled(make_loop):
    """Motor 1 weakened to half its thrust: during a full-speed climb it sits at command 1.0
    (saturated) much of the time; roll/pitch stay controlled and the climb completes."""
    loop = make_loop()
    hover(loop, settle=3.0)
    loop.plant.motor_health[0] = 0.5
    loop.run(3.0)
    loop.core.request(Request(Command.SET_MODE, Mode.AUTO))
    loop.run(0.02)
    loop.core.out.nav = Nav.GOTO
    n1 = len(loop.trace.t)
    follow(loop, 6.0, lambda: Setpoint(loop.t, Level.POSITION, (0.0, 0.0, 12.0), (0.0, 0.0, 0.0), yaw=0.0))
    commands = loop.trace.commands[n1:]
    saturated = sum(c[0] >= 0.999 for c in commands) / len(commands)
    tilts = [math.degrees(math.acos(max(-1.0, min(1.0, quat.body_z(q)[2])))) for q in loop.trace.orientation[n1:]]
    assert saturated > 0.2, saturated
    assert max(tilts) < 10.0, max(tilts)
    assert abs(loop.plant.state.position[2] - 12.0) < 0.2


def test_mode_switch_requested_mid_tick_applies_at_next_tick(make_loop, core_config):
    seen = []
    loop_ref = {}

    def inject(k):
        if k == 4000:
            loop_ref["loop"].core.request(Request(Command.SET_MODE, Mode.ATTITUDE))

    def probe(k):
        seen.append((k, loop_ref["loop"].core.out.mode))

    config = {**core_config, "tasks": core_config["tasks"] + [
        {"name": "inject", "group": "guidance", "rate_hz": 500, "budget_us": 10},
        {"name": "probe", "group": "default", "rate_hz": 500, "budget_us": 10}]}
    loop = make_loop(noise=NO_NOISE, config=config, extra_tasks={"inject": inject, "probe": probe})
    loop_ref["loop"] = loop
    hover(loop)
    modes = dict(seen)
    assert modes[3999] == modes[4000] == Mode.AUTO  # requested in tick 4000, after its latch: not yet
    assert modes[4001] == Mode.ATTITUDE  # applied at the next tick boundary


def test_kill_stops_motors_immediately(make_loop):
    loop = make_loop()
    hover(loop, altitude=2.0, settle=1.0)
    loop.core.request(Request(Command.SET_MODE, Mode.KILL))
    loop.run(0.004)
    assert not loop.core.out.armed and all(c == 0.0 for c in loop.core.out.commands)


def test_refuses_to_arm_with_stale_inputs(make_loop):
    loop = make_loop()
    loop.core.inputs.now += 1.0  # state and gyro are now a second old
    ok, reason = loop.core.request(Request(Command.ARM))
    assert not ok and "stale" in reason


def test_tilted_touchdown_is_levelled_at_a_rate_the_gyro_sees():
    """The ground levels a vehicle resting tilted; integrating the reported angular velocity
    (what a gyro-driven estimator does) must land on the same, level attitude."""
    from c4d_common.airframe import default_airframe_path, load_airframe
    from c4d_sim.plant import MultirotorPlant

    airframe = load_airframe(default_airframe_path("quad_x"))

    plant = MultirotorPlant(airframe, (0.0, 0.0, 0.0))
    tilted = quat.from_euler(math.radians(8), math.radians(-5), 0.7)
    plant.state.orientation = tilted
    integrated, dt = tilted, 0.001
    for _ in range(500):
        plant.step(dt, [0.0] * len(airframe.motors), False)
        integrated = quat.integrate(integrated, plant.state.angular_velocity, dt)
    roll, pitch, yaw = quat.to_euler(plant.state.orientation)
    assert abs(roll) < 1e-3 and abs(pitch) < 1e-3 and abs(yaw - 0.7) < 0.01
    assert math.degrees(quat.angle_between(integrated, plant.state.orientation)) < 0.05


@pytest.mark.parametrize("steps_per_imu_sample", [2, 7])  # 1 kHz physics / 500 Hz IMU; a stalled sim
def test_touchdown_is_braked_by_the_gear_and_seen_whole_by_the_imu(steps_per_imu_sample):
    """A 3 m/s free-fall touchdown: the landing gear stops it within a 16 g accelerometer's range
    and a few centimetres of travel, then the vehicle stands at z = 0; and the vertical velocity
    integrated from the IMU's specific force (the mean over each sample interval, whatever the
    physics steps per sample) comes back to zero as the truth does — an estimator integrating
    the IMU must not believe the vehicle still descends on the ground."""
    from c4d_common.airframe import default_airframe_path, load_airframe
    from c4d_sim.plant import GRAVITY, MultirotorPlant

    airframe = load_airframe(default_airframe_path("quad_x"))
    plant = MultirotorPlant(airframe, (0.0, 0.0, 0.5))
    plant.state.on_ground = False
    dt, velocity_from_imu, fastest, lowest, peak = 0.001, 0.0, 0.0, 0.0, 0.0
    plant.state.take_imu_means()
    for step in range(1, 1401):
        plant.step(dt, [0.0] * len(airframe.motors), False)
        fastest, lowest = min(fastest, plant.state.velocity[2]), min(lowest, plant.state.position[2])
        if step % steps_per_imu_sample == 0:
            force, rate = plant.state.take_imu_means()
            peak = max(peak, abs(force[2]))
            velocity_from_imu += (force[2] - GRAVITY) * steps_per_imu_sample * dt
            assert rate == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)
    assert plant.state.on_ground and plant.state.velocity == (0.0, 0.0, 0.0) and plant.state.position[2] == 0.0
    assert fastest < -3.0 and -0.15 < lowest < 0.0 and peak < 16 * GRAVITY
    assert velocity_from_imu == pytest.approx(0.0, abs=1e-9)
