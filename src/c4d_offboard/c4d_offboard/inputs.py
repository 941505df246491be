"""Messages of the public inputs ↔ gateway Setpoints (the only ROS-typed part of the rules).

offboard/trajectory_setpoint (GuidanceSetpoint) maps field for field; offboard/pose
(PoseStamped) is a POSITION setpoint with the quaternion's heading as yaw (an all-zero
quaternion: yaw unset); offboard/twist (TwistStamped) is a VELOCITY setpoint with angular.z as
yaw rate, in `map` (ENU) as is or in `base_link` (FLU) rotated by the estimated heading.
"""

from __future__ import annotations

import math

from c4d_common.quat import yaw_of
from c4d_interfaces.msg import GuidanceSetpoint

from .gateway import BODY_FRAME, NAN, WORLD_FRAME, Level, Reject, Setpoint, body_to_world


def _stamp_s(header) -> float:
    return float(header.stamp.sec + header.stamp.nanosec * 1e-9)


def _vec(v) -> tuple[float, float, float]:
    return (float(v.x), float(v.y), float(v.z))


def from_trajectory(msg: GuidanceSetpoint) -> Setpoint:
    q = msg.orientation
    return Setpoint(int(msg.control_level), msg.header.frame_id, _stamp_s(msg.header), _vec(msg.position),
                    _vec(msg.velocity), _vec(msg.acceleration), float(msg.yaw), float(msg.yaw_rate),
                    (float(q.w), float(q.x), float(q.y), float(q.z)), _vec(msg.body_rate), float(msg.thrust),
                    float(msg.max_horizontal_speed), float(msg.max_vertical_speed))


def from_pose(msg) -> Setpoint:
    """geometry_msgs/PoseStamped → POSITION with yaw (NaN for an all-zero quaternion)."""
    q = msg.pose.orientation
    quat = (float(q.w), float(q.x), float(q.y), float(q.z))
    yaw = NAN if quat == (0.0, 0.0, 0.0, 0.0) or not all(math.isfinite(c) for c in quat) else yaw_of(quat)
    if any(math.isinf(c) for c in quat):
        yaw = math.inf  # an inf anywhere is refused, not silently dropped
    return Setpoint(Level.POSITION, msg.header.frame_id, _stamp_s(msg.header), _vec(msg.pose.position), yaw=yaw)


def from_twist(msg, heading: float | None) -> Setpoint | Reject:
    """geometry_msgs/TwistStamped → VELOCITY + yaw rate in `map`. A `base_link` twist is rotated
    by `heading` (the estimated yaw; None: not known yet → NO_HEADING)."""
    velocity = _vec(msg.twist.linear)
    frame = msg.header.frame_id
    if frame == BODY_FRAME:
        if heading is None:
            return Reject.NO_HEADING
        velocity, frame = body_to_world(velocity, heading), WORLD_FRAME
    return Setpoint(Level.VELOCITY, frame, _stamp_s(msg.header), velocity=velocity,
                    yaw_rate=float(msg.twist.angular.z))


def to_msg(sp: Setpoint, stamp) -> GuidanceSetpoint:
    """The GuidanceSetpoint published on guidance/offboard (`stamp`: the input's header stamp)."""
    out = GuidanceSetpoint(control_level=int(sp.level), yaw=sp.yaw, yaw_rate=sp.yaw_rate, thrust=sp.thrust,
                           max_horizontal_speed=sp.max_horizontal_speed, max_vertical_speed=sp.max_vertical_speed)
    out.header.stamp, out.header.frame_id = stamp, WORLD_FRAME
    out.position.x, out.position.y, out.position.z = sp.position
    out.velocity.x, out.velocity.y, out.velocity.z = sp.velocity
    out.acceleration.x, out.acceleration.y, out.acceleration.z = sp.acceleration
    q = out.orientation
    q.w, q.x, q.y, q.z = sp.orientation
    out.body_rate.x, out.body_rate.y, out.body_rate.z = sp.body_rate
    return out

