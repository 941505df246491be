"""The ROS-free enums of c4d_common.vehicle equal the constants of the generated interfaces.

Why: ROS-free logic decides with these enums; the messages carry the generated constants. A
renumbered .msg/.srv must fail here, not in flight.
"""

from __future__ import annotations

from enum import IntEnum

import pytest

from c4d_common import vehicle
from c4d_interfaces.msg import GuidanceSetpoint, MissionState, VehicleStatus
from c4d_interfaces.srv import MissionControl, UploadMission, VehicleCommand

CONTRACTS = [
    (vehicle.Mode, VehicleStatus, "MODE_", True),
    (vehicle.Nav, VehicleStatus, "NAV_", True),
    (vehicle.Landed, VehicleStatus, "LANDED_", True),
    (vehicle.FailsafeAction, VehicleStatus, "FAILSAFE_", True),
    (vehicle.SetpointSource, VehicleStatus, "SOURCE_", True),
    (vehicle.Level, GuidanceSetpoint, "LEVEL_", True),
    (vehicle.VehicleCommandId, VehicleCommand.Request, "CMD_", True),
    (vehicle.Command, VehicleCommand.Request, "CMD_", False),  # the core's subset
    (vehicle.CommandResult, VehicleCommand.Response, "RESULT_", True),
    (vehicle.CommandResult, MissionControl.Response, "RESULT_", True),
    (vehicle.MissionStatus, MissionState, "STATE_", True),
    (vehicle.MissionAction, MissionControl.Request, "ACTION_", True),
    (vehicle.UploadRefusal, UploadMission.Response, "REFUSAL_", True),
]


def constants(cls: type, prefix: str) -> dict[str, int]:
    return {name[len(prefix):]: getattr(cls, name) for name in dir(cls)
            if name.startswith(prefix) and name[len(prefix):].isupper() and isinstance(getattr(cls, name), int)}


@pytest.mark.parametrize(("enum", "cls", "prefix", "complete"), CONTRACTS,
                         ids=[f"{e.__name__}-{c.__qualname__}" for e, c, _, _ in CONTRACTS])
def test_enum_matches_interface(enum: type[IntEnum], cls: type, prefix: str, complete: bool) -> None:
    generated = constants(cls, prefix)
    assert generated, f"{cls.__qualname__} has no {prefix}* constants"
    ours = {member.name: int(member) for member in enum}
    for name, value in ours.items():
        assert generated.get(name) == value, \
            f"{enum.__name__}.{name} = {value}, {cls.__qualname__}.{prefix}{name} = {generated.get(name)}"
    if complete:
        assert set(ours) == set(generated), f"{enum.__name__} misses {sorted(set(generated) - set(ours))}"
