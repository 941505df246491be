"""The core node's ROS-free parts: command answers (typed results) and the status cadence."""

import math

import pytest

from c4d_common.airframe import default_airframe_path, load_airframe
from c4d_common.vehicle import Command, CommandResult, Landed, Mode, Nav
from c4d_gnc.core_commands import answer_command
from c4d_gnc.gnc import GncCore, Outputs, StateSample
from c4d_gnc.status_cadence import StatusCadence


@pytest.fixture
def core():
    return GncCore(load_airframe(default_airframe_path("quad_x")), 0.002)


def feed(core, now=10.0, valid_position=True):
    core.inputs.now = now
    core.inputs.state = StateSample(now, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0),
                                    valid_position=valid_position, valid_velocity=valid_position)
    core.inputs.gyro, core.inputs.gyro_stamp = (0.0, 0.0, 0.0), now


def test_unserved_command_is_unsupported_and_unknown_mode_denied(core):
    assert answer_command(core, 42, 0, 0.0, False)[0] == CommandResult.UNSUPPORTED
    result, message = answer_command(core, Command.SET_MODE, 42, 0.0, False)
    assert result == CommandResult.DENIED and "42" in message


def test_refusals_for_a_stale_or_invalid_estimate_are_temporary(core):
    result, message = answer_command(core, Command.ARM, 0, 0.0, False)
    assert result == CommandResult.TEMPORARILY_REJECTED and "stale" in message
    feed(core, valid_position=False)
    assert answer_command(core, Command.TAKEOFF, 0, 2.0, False)[0] == CommandResult.TEMPORARILY_REJECTED
    assert answer_command(core, Command.LAND, 0, 0.0, False)[0] == CommandResult.DENIED  # not armed: not temporary


def test_accepted_request_applies_at_the_next_latch(core):
    feed(core)
    assert answer_command(core, Command.ARM, 0, 0.0, False)[0] == CommandResult.ACCEPTED
    assert not core.out.armed
    core.latch()
    assert core.out.armed


def test_return_to_launch_follows_the_setpoints_and_reports_rtl(core):
    """Issue 14.11: the mission node flies an RTL through the core; the status must say RTL (was GOTO,
    which a GCS shows as HOLD)."""
    feed(core)
    assert answer_command(core, Command.RETURN_TO_LAUNCH, 0, 0.0, False)[0] == CommandResult.DENIED  # not armed
    core.out.armed, core.out.landed = True, Landed.ON_GROUND
    assert answer_command(core, Command.RETURN_TO_LAUNCH, 0, 0.0, False)[0] == CommandResult.DENIED  # on the ground
    core.out.landed = Landed.IN_AIR
    assert answer_command(core, Command.RETURN_TO_LAUNCH, 0, 0.0, False)[0] == CommandResult.ACCEPTED
    core.latch()
    assert (core.out.mode, core.out.nav) == (Mode.AUTO, Nav.RTL)


def test_status_on_change_and_at_the_period_with_the_arm_time():
    cadence, out = StatusCadence(period_s=0.2), Outputs()
    assert cadence.due(out, 1.0)  # first
    assert not cadence.due(out, 1.1)
    assert cadence.due(out, 1.2 + 1e-9)  # period
    out.armed = True
    assert cadence.due(out, 1.25) and cadence.arm_time_ns == 1_250_000_000
    out.mode, out.nav, out.landed = Mode.AUTO, Nav.TAKEOFF, Landed.TAKEOFF
    assert cadence.due(out, 1.26) and cadence.arm_time_ns == 1_250_000_000
    assert not math.isnan(cadence.period_s)
