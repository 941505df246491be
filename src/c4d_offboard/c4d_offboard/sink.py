"""The gateway's side of the action servers: how an action steers the vehicle.

Why a protocol: the action servers (c4d_offboard.action_servers) live in the offboard node next
to the gateway and must publish on guidance/offboard through the same validation and the same
single publisher as external input, and silence external input while they steer. They get an
object implementing this protocol (the node's gateway adapter) and never touch the publisher.
"""

from __future__ import annotations

from typing import Protocol

from c4d_interfaces.msg import GuidanceSetpoint


class SetpointSink(Protocol):
    def publish_action_setpoint(self, sp: GuidanceSetpoint) -> None:
        """Publish `sp` on guidance/offboard. The caller stamps it (header.stamp = now, frame
        `map`); it is validated like external input except the stamp check (level, NaN/inf in
        required fields, frame, thrust, geofence clamp), never rate-limited. A refused setpoint is
        not published: it is counted per reason in offboard/status and logged (rate-limited)."""
        ...

    def claim(self, owner: str | None) -> None:
        """Take (`owner` = the action's name, e.g. "goto") or release (None) the setpoint stream.
        While claimed, external input (offboard/trajectory_setpoint, pose, twist) is refused and
        counted as reason `action_active`; offboard/status shows the owner."""
        ...
