"""Vehicle enums shared by every block: modes, navigation states, landed states, setpoint
levels and the core's command numbers.

Their values are the constants of c4d_interfaces (VehicleStatus.MODE_*, NAV_*, LANDED_*,
GuidanceSetpoint.LEVEL_*, VehicleCommand.Request.CMD_*); `c4d_ros/test/test_contracts.py`
asserts they stay equal, so ROS-free code can use them without importing ROS.
"""

from __future__ import annotations

from enum import IntEnum


class Mode(IntEnum):
    UNKNOWN = 0
    RATE = 1
    ATTITUDE = 2
    POSITION = 3
    AUTO = 4
    KILL = 5
    OFFBOARD = 6  # follow the offboard gateway's stream (guidance/offboard); entry needs a live stream


class SetpointSource(IntEnum):  # VehicleStatus.SOURCE_*: who owns the setpoint stream (chosen by the mode)
    CORE = 0  # the core's own targets: hold, take-off, land, stale input
    MISSION = 1  # guidance/setpoint (AUTO: MISSION, GOTO, RTL)
    OFFBOARD = 2  # guidance/offboard (OFFBOARD)
    PILOT = 3  # guidance/pilot (RATE, ATTITUDE)


class Nav(IntEnum):
    NONE = 0
    TAKEOFF = 1
    MISSION = 2
    HOLD = 3
    GOTO = 4
    RTL = 5
    LAND = 6


class Landed(IntEnum):
    UNDEFINED = 0
    ON_GROUND = 1
    IN_AIR = 2
    TAKEOFF = 3
    LANDING = 4


class Level(IntEnum):  # GuidanceSetpoint.LEVEL_*
    POSITION = 1
    VELOCITY = 2
    ACCELERATION = 3
    ATTITUDE = 4
    RATE = 5


class Command(IntEnum):  # VehicleCommand.CMD_* subset served by the core
    ARM = 1
    DISARM = 2
    TAKEOFF = 3
    LAND = 4
    RETURN_TO_LAUNCH = 5  # as GOTO, reported as AUTO / RTL: the mission node flies the return's setpoints
    HOLD = 6
    SET_MODE = 7
    GOTO = 8  # follow the external guidance setpoint stream (AUTO / GOTO), holding if it goes stale


class FailsafeAction(IntEnum):  # VehicleStatus.FAILSAFE_*; order = severity
    NONE = 0
    WARN = 1
    HOLD = 2
    RTL = 3
    LAND = 4
    TERMINATE = 5


class VehicleCommandId(IntEnum):  # VehicleCommand.Request.CMD_* (the full set the mission node serves)
    ARM = 1
    DISARM = 2
    TAKEOFF = 3
    LAND = 4
    RETURN_TO_LAUNCH = 5
    HOLD = 6
    SET_MODE = 7
    GOTO = 8


class CommandResult(IntEnum):  # VehicleCommand / MissionControl RESULT_* (= MAVLink MAV_RESULT)
    ACCEPTED = 0
    TEMPORARILY_REJECTED = 1
    DENIED = 2
    UNSUPPORTED = 3
    FAILED = 4
    IN_PROGRESS = 5


class MissionStatus(IntEnum):  # MissionState.STATE_*
    NO_PLAN = 0
    READY = 1
    ACTIVE = 2
    PAUSED = 3
    COMPLETED = 4
    ABORTED = 5


class MissionAction(IntEnum):  # MissionControl.Request.ACTION_*
    START = 1
    PAUSE = 2
    RESUME = 3
    CLEAR = 4
    SET_CURRENT = 5


class UploadRefusal(IntEnum):  # UploadMission.Response REFUSAL_*: why a plan was refused
    NONE = 0
    INVALID = 1  # the plan fails validation: fix it
    NO_HOME = 2  # the estimator has no origin yet: retry
    BATTERY_UNKNOWN = 3  # no battery state yet, endurance unknown: retry
    MISSION_ACTIVE = 4  # the running plan cannot be replaced

    @property
    def retry(self) -> bool:
        """The vehicle cannot judge the plan yet: the same upload may be accepted later."""
        return self in (UploadRefusal.NO_HOME, UploadRefusal.BATTERY_UNKNOWN)
