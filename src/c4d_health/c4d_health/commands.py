"""Which vehicle command carries a failsafe action, and to whom it goes.

What: `failsafe_command(action, via_mission)` gives the VehicleCommand (command id, mode) that
requests `action`, or None for actions that command nothing (none, warn).
Why the two routes: the mission node's vehicle/command serves every command incl. RTL (it
flies the return); when the mission is dead or refuses, health asks the core's gnc/command,
which cannot fly RTL — it lands instead.
"""

from __future__ import annotations

from dataclasses import dataclass

from c4d_common.vehicle import FailsafeAction, Mode, VehicleCommandId


@dataclass(frozen=True)
class FailsafeCommand:
    command: VehicleCommandId
    mode: Mode = Mode.UNKNOWN  # only for SET_MODE


_COMMANDS = {
    FailsafeAction.HOLD: FailsafeCommand(VehicleCommandId.HOLD),
    FailsafeAction.RTL: FailsafeCommand(VehicleCommandId.RETURN_TO_LAUNCH),
    FailsafeAction.LAND: FailsafeCommand(VehicleCommandId.LAND),
    FailsafeAction.TERMINATE: FailsafeCommand(VehicleCommandId.SET_MODE, Mode.KILL),
}


def failsafe_command(action: FailsafeAction, via_mission: bool) -> FailsafeCommand | None:
    """The command requesting `action` from the mission (via_mission) or from the core."""
    command = _COMMANDS.get(action)
    if command is not None and not via_mission and command.command == VehicleCommandId.RETURN_TO_LAUNCH:
        return _COMMANDS[FailsafeAction.LAND]  # RTL needs the mission node: land instead
    return command
