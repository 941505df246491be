"""Failsafe actions → vehicle commands: through the mission, or the core (which lands for RTL)."""

import pytest

from c4d_common.vehicle import FailsafeAction, Mode, VehicleCommandId
from c4d_health.commands import FailsafeCommand, failsafe_command


@pytest.mark.parametrize("action,via_mission,expected", [
    (FailsafeAction.HOLD, True, FailsafeCommand(VehicleCommandId.HOLD)),
    (FailsafeAction.RTL, True, FailsafeCommand(VehicleCommandId.RETURN_TO_LAUNCH)),
    (FailsafeAction.RTL, False, FailsafeCommand(VehicleCommandId.LAND)),
    (FailsafeAction.LAND, False, FailsafeCommand(VehicleCommandId.LAND)),
    (FailsafeAction.TERMINATE, True, FailsafeCommand(VehicleCommandId.SET_MODE, Mode.KILL)),
    (FailsafeAction.TERMINATE, False, FailsafeCommand(VehicleCommandId.SET_MODE, Mode.KILL)),
])
def test_command_per_action_and_route(action, via_mission, expected):
    assert failsafe_command(action, via_mission) == expected


@pytest.mark.parametrize("action", [FailsafeAction.NONE, FailsafeAction.WARN])
def test_none_and_warn_command_nothing(action):
    assert failsafe_command(action, True) is None and failsafe_command(action, False) is None
