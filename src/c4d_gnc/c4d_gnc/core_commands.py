"""The core's command service without ROS: a VehicleCommand request's numbers in, a typed
(CommandResult, message) out.

Why here: the service callback then only copies fields, and what the core answers (which
commands it serves, which refusals are worth retrying) is unit-tested without DDS.
"""

from __future__ import annotations

from c4d_common.vehicle import Command, CommandResult, Mode

from .gnc import GncCore, Request


def answer_command(core: GncCore, command: int, mode: int, altitude: float, force: bool) -> tuple[CommandResult, str]:
    """Decode and submit one request to `core` (applied at its next latch). A command the core
    does not serve is UNSUPPORTED; a refusal the estimate's freshness or validity could lift is
    TEMPORARILY_REJECTED; every other refusal (and an unknown mode) is DENIED."""
    try:
        cmd = Command(command)
    except ValueError:
        return CommandResult.UNSUPPORTED, f"command {command} is not served by the core"
    try:
        target = Mode(mode) if cmd == Command.SET_MODE else Mode.UNKNOWN
    except ValueError:
        return CommandResult.DENIED, f"unknown mode {mode}"
    verdict = core.submit(Request(cmd, target, float(altitude), bool(force)))
    if verdict.accepted:
        return CommandResult.ACCEPTED, verdict.reason
    return (CommandResult.TEMPORARILY_REJECTED if verdict.retry else CommandResult.DENIED), verdict.reason
