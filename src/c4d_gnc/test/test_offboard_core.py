"""OFFBOARD in the core, closed loop on a fake clock: entry needs a live stream, the mode picks the
setpoint owner, a vehicle on the ground takes off on a setpoint above it, a stale stream holds where a
brake ends, and a 3 m/s lemniscate with feed-forward is tracked (the controller's share of the
whole-graph bound in test/test_offboard_flight.py)."""

import math

import numpy as np

from c4d_common.vehicle import CommandResult, SetpointSource
from c4d_gnc.core_commands import answer_command
from c4d_gnc.gnc import Command, Landed, Level, Mode, Request, Setpoint
from c4d_gnc.setpoint_sources import OFFBOARD_MAX_GAP_S, StreamLiveness, owner

EVERY = 0.02  # 50 Hz, as an external node streams


def stream(loop, seconds, make_setpoint, source=SetpointSource.OFFBOARD, every=EVERY):
    for _ in range(round(seconds / every)):
        loop.core.receive_setpoint(source, make_setpoint())
        loop.run(every)


def set_offboard(loop):
    return answer_command(loop.core, Command.SET_MODE, Mode.OFFBOARD, 0.0, False)


def speed(loop):
    return math.hypot(*loop.plant.state.velocity)


def hover_point(loop, p=(0.0, 0.0, 5.0)):
    return lambda: Setpoint(loop.t, Level.POSITION, p, (0.0, 0.0, 0.0), yaw=0.0)


def test_stream_liveness_needs_gaps_below_half_a_second():
    live = StreamLiveness()
    assert live.live_for(0.0) == 0.0
    for k in range(11):
        live.arrived(0.1 * k)
    assert math.isclose(live.live_for(1.0), 1.0)
    assert live.live_for(1.0 + OFFBOARD_MAX_GAP_S + 0.01) == 0.0  # stopped: not live
    live.arrived(2.0)  # a new stream starts from its first sample
    assert live.live_for(2.0) == 0.0


def test_owner_follows_the_mode():
    from c4d_common.vehicle import Nav
    assert owner(Mode.OFFBOARD, Nav.NONE) == SetpointSource.OFFBOARD
    assert owner(Mode.ATTITUDE, Nav.NONE) == owner(Mode.RATE, Nav.NONE) == SetpointSource.PILOT
    assert owner(Mode.AUTO, Nav.MISSION) == owner(Mode.AUTO, Nav.RTL) == SetpointSource.MISSION
    assert owner(Mode.AUTO, Nav.HOLD) == owner(Mode.POSITION, Nav.NONE) == SetpointSource.CORE


def test_offboard_entry_is_refused_without_a_live_stream_then_accepted(make_loop):
    loop = make_loop()
    loop.take_off(5.0)
    result, why = set_offboard(loop)
    assert result == CommandResult.TEMPORARILY_REJECTED and "OFFBOARD" in why
    stream(loop, 0.5, hover_point(loop))
    assert set_offboard(loop)[0] == CommandResult.TEMPORARILY_REJECTED  # live 0.5 s only
    stream(loop, 0.3, hover_point(loop), every=0.6)  # a gap > 0.5 s restarts the stream
    assert set_offboard(loop)[0] == CommandResult.TEMPORARILY_REJECTED
    stream(loop, 1.1, hover_point(loop))
    assert set_offboard(loop)[0] == CommandResult.ACCEPTED
    loop.run(0.002)  # the next tick's latch names the new owner (the status goes out in that tick)
    assert loop.core.out.source == SetpointSource.OFFBOARD
    loop.run(0.05)
    assert loop.core.out.mode == Mode.OFFBOARD and loop.core.out.source == SetpointSource.OFFBOARD


def test_in_offboard_only_the_offboard_stream_steers_and_others_are_counted(make_loop):
    loop = make_loop()
    loop.take_off(5.0)
    stream(loop, 1.2, hover_point(loop))
    assert set_offboard(loop)[0] == CommandResult.ACCEPTED
    before = loop.core.inputs.setpoints.ignored
    for _ in range(300):  # 6 s: offboard says (4, 0, 5), a stray mission publisher says (-4, 0, 5)
        loop.core.receive_setpoint(SetpointSource.MISSION, Setpoint(loop.t, Level.POSITION, (-4.0, 0.0, 5.0)))
        loop.core.receive_setpoint(SetpointSource.OFFBOARD, Setpoint(loop.t, Level.POSITION, (4.0, 0.0, 5.0),
                                                                     (0.0, 0.0, 0.0), yaw=0.0))
        loop.run(EVERY)
    assert loop.core.inputs.setpoints.ignored - before == 300
    assert math.dist(loop.plant.state.position, (4.0, 0.0, 5.0)) < 0.2


def test_armed_in_offboard_on_the_ground_takes_off_on_a_setpoint_above(make_loop):
    loop = make_loop()
    loop.run(0.5)
    stream(loop, 1.2, hover_point(loop, (0.0, 0.0, 0.0)))  # on the ground: a ground-level setpoint
    assert set_offboard(loop)[0] == CommandResult.ACCEPTED  # entering OFFBOARD disarmed is allowed
    loop.command(Request(Command.ARM))
    stream(loop, 2.0, hover_point(loop, (0.0, 0.0, 0.0)))
    assert loop.core.out.landed == Landed.ON_GROUND and loop.plant.state.position[2] < 0.05  # idles, stays down
    stream(loop, 8.0, hover_point(loop, (0.0, 0.0, 4.0)))
    assert loop.core.out.landed == Landed.IN_AIR and abs(loop.plant.state.position[2] - 4.0) < 0.2


def test_stale_stream_holds_where_a_brake_ends(make_loop):
    loop = make_loop()
    loop.take_off(5.0)
    stream(loop, 1.2, hover_point(loop))
    assert set_offboard(loop)[0] == CommandResult.ACCEPTED
    stream(loop, 4.0, lambda: Setpoint(loop.t, Level.VELOCITY, velocity=(3.0, 0.0, 0.0), yaw=0.0))
    assert speed(loop) > 2.5
    lost = loop.t
    x_lost = loop.plant.state.position[0]
    assert loop.run_until(lambda: loop.t - lost > 0.5 + 1.0, timeout=5.0)  # timeout + 1 s
    assert speed(loop) < 0.3, speed(loop)
    loop.run(3.0)
    assert abs(loop.plant.state.position[0] - x_lost) < 4.0 and speed(loop) < 0.1
    assert loop.core.out.mode == Mode.OFFBOARD and loop.core.out.source == SetpointSource.CORE


def lemniscate(t, period=28.0, a=10.0, b=5.0, z0=6.0, dz=2.0):
    """Gerono lemniscate 20 m x 10 m with a 4 m altitude swing: position, velocity, acceleration (ENU)."""
    w = 2 * math.pi / period
    p = (a * math.sin(w * t), b * math.sin(2 * w * t), z0 + dz * math.sin(w * t))
    v = (a * w * math.cos(w * t), 2 * b * w * math.cos(2 * w * t), dz * w * math.cos(w * t))
    acc = (-a * w * w * math.sin(w * t), -4 * b * w * w * math.sin(2 * w * t), -dz * w * w * math.sin(w * t))
    return p, v, acc


def test_lemniscate_with_feed_forward_is_tracked_within_0_3_m_rms(make_loop):
    loop = make_loop()
    loop.take_off(6.0)
    stream(loop, 1.2, hover_point(loop, (0.0, 0.0, 6.0)))
    assert set_offboard(loop)[0] == CommandResult.ACCEPTED
    t0, errors, peak = loop.t, [], 0.0
    while loop.t - t0 < 56.0:  # two laps
        p, v, a = lemniscate(loop.t - t0)
        peak = max(peak, math.hypot(*v))
        loop.core.receive_setpoint(SetpointSource.OFFBOARD, Setpoint(loop.t, Level.POSITION, p, v, a))
        loop.run(EVERY)
        if loop.t - t0 > 5.0:  # after the entry transient
            errors.append(math.dist(loop.plant.state.position, lemniscate(loop.t - t0)[0]))
    rms, worst = float(np.sqrt(np.mean(np.square(errors)))), max(errors)
    print(f"lemniscate peak speed {peak:.2f} m/s: RMS {rms:.3f} m, max {worst:.3f} m")
    assert peak > 2.8 and rms < 0.3 and worst < 0.8, (peak, rms, worst)
