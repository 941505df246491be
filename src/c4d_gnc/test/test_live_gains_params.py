"""Live gains in the deterministic closed loop (plant + GncCore + the real executive, fake clock):
a change validated through the core's table and swapped in at a latch changes the flown roll-step
response the way the linear model (c4d_gnc.rate_loop_model) predicts; no tick runs a mixed set.
The SITL version of this (MAVLink PARAM_SET over the whole graph) is test/test_live_params.py."""

from __future__ import annotations

import math

from c4d_common import quat
from c4d_common.tunable import PendingChanges
from c4d_common.vehicle import CommandResult, Mode, SetpointSource
from c4d_gnc.core_commands import answer_command
from c4d_gnc.gnc import Command, Level, Setpoint
from c4d_gnc.live_gains import airframe_values, airframe_with, core_table
from c4d_gnc.rate_loop_model import step_metrics, step_response

STEP = math.radians(15.0)


def fly_steps(loop, yaw: float, hover: float) -> list[tuple[float, float]]:
    """0 → +STEP → 0 → −STEP → 0 at the attitude level, 0.7 s each; (overshoot, rise) of each."""
    target = [0.0]
    loop.input_hook = lambda now: loop.core.receive_setpoint(SetpointSource.OFFBOARD, Setpoint(
        now, Level.ATTITUDE, orientation=quat.from_euler(target[0], 0.0, yaw), thrust=hover / math.cos(target[0])))
    loop.run(1.2)
    result, why = answer_command(loop.core, Command.SET_MODE, Mode.OFFBOARD, 0.0, False)
    assert result == CommandResult.ACCEPTED, why
    loop.run(0.5)
    metrics, previous = [], 0.0
    for goal in (STEP, 0.0, -STEP, 0.0):
        target[0] = goal
        first = len(loop.trace.t)
        loop.run(0.7)
        trace = [(t, quat.to_euler(q)[0]) for t, q in zip(loop.trace.t[first:], loop.trace.orientation[first:], strict=True)]
        metrics.append(step_metrics(trace, previous, goal))
        previous = goal
    answer_command(loop.core, Command.SET_MODE, Mode.POSITION, 0.0, False)
    loop.input_hook = None
    loop.run(2.0)
    return metrics


def test_doubled_roll_rate_p_at_a_latch_matches_the_linear_model(make_loop):
    from closed_loop import NO_NOISE

    loop = make_loop(noise=NO_NOISE)
    af = loop.core.af
    loop.take_off(3.0)
    loop.run(2.0)
    yaw, hover = quat.yaw_of(loop.plant.state.orientation), af.hover_command
    before = fly_steps(loop, yaw, hover)

    pending = PendingChanges(core_table(af), airframe_values(af))
    assert "outside" in pending.submit({"gains.rate.roll.p": 400.0})
    assert pending.submit({"gains.rate.roll.p": 44.0}) == ""
    rates_seen: list[float] = []
    latch = loop.executive.latch

    def latch_with_changes(k: int) -> None:  # as core_node.latch: the queued change first, then the core's
        changes = pending.take()
        if changes:
            loop.core.retune(airframe_with(loop.core.af, changes))
        rates_seen.append(loop.core.rotation.rate_pid.gains.p[0])
        latch(k)

    loop.executive.latch = latch_with_changes
    loop.run(0.01)
    assert rates_seen[0] == 44.0 and set(rates_seen) == {44.0} and loop.core.af.rate.p == (44.0, 22.0, 12.0)
    after = fly_steps(loop, yaw, hover)

    (over_22, rise_22), (over_44, rise_44) = (step_metrics(step_response(kp, step=STEP), 0.0, STEP) for kp in (22.0, 44.0))
    m_over_22 = sorted(o for o, _ in before)[1]  # median-low of 4
    m_over_44 = sorted(o for o, _ in after)[1]
    m_rise_22 = sorted(r for _, r in before)[1]
    m_rise_44 = sorted(r for _, r in after)[1]
    report = (f"model: overshoot {over_22:.1%} -> {over_44:.1%}, rise {rise_22 * 1e3:.0f} -> {rise_44 * 1e3:.0f} ms; "
              f"closed loop: overshoot {m_over_22:.1%} -> {m_over_44:.1%}, rise {m_rise_22 * 1e3:.0f} -> "
              f"{m_rise_44 * 1e3:.0f} ms; {before} / {after}")
    print(report)
    assert m_over_44 < m_over_22 and m_rise_44 < m_rise_22, report
    assert abs((m_over_22 - m_over_44) - (over_22 - over_44)) < 0.5 * (over_22 - over_44), report
    assert abs(m_rise_44 / m_rise_22 - rise_44 / rise_22) < 0.15, report
