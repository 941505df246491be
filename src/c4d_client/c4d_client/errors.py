"""Typed failures of c4d_client calls; each carries the vehicle's own one-line reason."""

from __future__ import annotations


class VehicleError(Exception):
    """Base class: anything c4d_client raises about the vehicle (`reason` is the one-line why)."""

    def __init__(self, what: str, reason: str) -> None:
        super().__init__(f"{what}: {reason}")
        self.what, self.reason = what, reason


class NotConnected(VehicleError):
    """The c4d graph (a service, an action server, the status or the estimate) did not show up in time."""


class CommandRefused(VehicleError):
    """vehicle/command answered with something else than ACCEPTED; `result` is the
    VehicleCommand RESULT_* code (MAVLink MAV_RESULT numbering), `reason` the vehicle's message."""

    def __init__(self, what: str, reason: str, result: int) -> None:
        super().__init__(what, reason)
        self.result = result


class GoalRejected(VehicleError):
    """An action goal was rejected before it started (not flying, outside the geofence, another
    goal running, ...); `reason` is the offboard node's logged reason when it could be read from
    /rosout, else a pointer to that log."""


class ActionFailed(VehicleError):
    """An accepted action goal ended without success (aborted, or cancelled by someone else);
    `reason` is the result's message, `status` the action_msgs GoalStatus code."""

    def __init__(self, what: str, reason: str, status: int) -> None:
        super().__init__(what, reason)
        self.status = status


class VehicleTimeout(VehicleError, TimeoutError):
    """A blocking call did not finish in its timeout (a running goal is cancelled first)."""
