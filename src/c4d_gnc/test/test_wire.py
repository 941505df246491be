"""c4d_gnc.wire gives the core the same inputs and sends the same command as ros_conversions.

Why: the core reads navigation/state and the gyro and writes control/actuators in serialized
form (500 Hz, ~40 µs saved per message); any difference to the message path would change what
the controller sees or what the motors get.
"""

from __future__ import annotations

import math

import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu

from c4d_gnc import ros_conversions as conv
from c4d_gnc import wire
from c4d_gnc.gnc import Outputs
from c4d_interfaces.msg import ActuatorCommand, VehicleState


def _state(valid: int) -> VehicleState:
    s = VehicleState()
    s.header.stamp.sec, s.header.stamp.nanosec, s.header.frame_id, s.child_frame_id = 100, 250_000_000, "map", "base_link"
    s.valid = valid
    s.position.x, s.position.y, s.position.z = 1.0, -2.0, 3.0
    s.velocity.x, s.velocity.y, s.velocity.z = 0.5, 0.25, -0.125
    s.orientation.w, s.orientation.x, s.orientation.y, s.orientation.z = 0.9, 0.1, -0.2, 0.3
    s.angular_velocity.x, s.angular_velocity.y, s.angular_velocity.z = 0.01, 0.02, -0.03
    s.terrain_distance = 4.5
    s.origin.latitude, s.origin.longitude, s.origin.altitude = 43.5629, 1.4815, 146.0
    return s


@pytest.mark.parametrize("valid", [0, VehicleState.VALID_ATTITUDE, VehicleState.VALID_POSITION_XY,
                                   VehicleState.VALID_POSITION_XY | VehicleState.VALID_POSITION_Z
                                   | VehicleState.VALID_ATTITUDE | VehicleState.VALID_TERRAIN_DISTANCE,
                                   VehicleState.VALID_ATTITUDE | VehicleState.VALID_ORIGIN])
def test_state_from_cdr_equals_state_from_msg(valid: int) -> None:
    msg = _state(valid)
    got, want = wire.state_from_cdr(serialize_message(msg)), conv.state_from_msg(msg)
    assert got.origin == ((43.5629, 1.4815, 146.0) if valid & VehicleState.VALID_ORIGIN else None)
    assert math.isnan(got.terrain_distance) == math.isnan(want.terrain_distance)
    if not math.isnan(want.terrain_distance):
        assert got == want
    else:
        assert got.__dict__ | {"terrain_distance": 0} == want.__dict__ | {"terrain_distance": 0}


def test_gyro_from_cdr() -> None:
    m = Imu()
    m.header.stamp.sec, m.header.stamp.nanosec, m.header.frame_id = 5, 500_000_000, "base_link"
    m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = 0.1, -0.2, 0.3
    assert wire.gyro_from_cdr(serialize_message(m)) == ((0.1, -0.2, 0.3), 5.5)


@pytest.mark.parametrize("armed", [True, False])
def test_actuator_cdr_equals_actuator_msg(armed: bool) -> None:
    out = Outputs(commands=(0.1, 0.55, 0.9, 0.3), armed=armed, input_stamp=1_700_000_000.123_456)
    got = deserialize_message(wire.actuator_cdr(out, 1_700_000_000.125, 4242), ActuatorCommand)
    want = conv.actuator_msg(out, 1_700_000_000.125, 4242)
    assert got.header == want.header and got.armed == want.armed and got.tick == want.tick
    assert abs(got.input_stamp.nanosec - want.input_stamp.nanosec) <= 1 and got.input_stamp.sec == want.input_stamp.sec
    assert list(got.outputs) == list(want.outputs)
