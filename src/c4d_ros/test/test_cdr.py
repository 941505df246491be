"""c4d_ros.cdr reads and writes the same bytes rclpy does, for the hot-path messages.

Why: the 500 Hz paths (sim → perception → navigation → core) skip rclpy's message conversion and
read/write CDR with struct. A wrong alignment or field order would silently feed the estimator
wrong numbers; here every layout is checked against rclpy's own (de)serialization, with string
lengths that move the alignment, in both directions.
"""

from __future__ import annotations

import math
import random
import struct

import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu

from c4d_interfaces.msg import ActuatorCommand, VehicleState
from c4d_ros import cdr


def _imu(frame: str) -> Imu:
    rng = random.Random(frame)
    m = Imu()
    m.header.stamp.sec, m.header.stamp.nanosec, m.header.frame_id = 1_700_000_123, 987_654_321, frame
    m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w = (rng.uniform(-1, 1) for _ in range(4))
    m.orientation_covariance = [rng.uniform(-1, 1) for _ in range(9)]
    m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = 0.125, -2.5, 3.75
    m.angular_velocity_covariance = [rng.uniform(0, 1) for _ in range(9)]
    m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z = -0.5, 0.25, 9.80665
    m.linear_acceleration_covariance = [rng.uniform(0, 1) for _ in range(9)]
    return m


@pytest.mark.parametrize("frame", ["base_link", "", "imu", "a_much_longer_frame_name_x"])
def test_imu_fields_read_and_written_as_rclpy_does(frame: str) -> None:
    msg = _imu(frame)
    raw = serialize_message(msg)
    v = cdr.IMU.unpack(raw)
    assert v[0] == cdr.CDR_LE
    assert (v[1], v[2]) == (1_700_000_123, 987_654_321) == cdr.header_stamp(raw)
    assert v[4] == frame.encode() + b"\x00"
    assert v[cdr.IMU_GYRO] == (0.125, -2.5, 3.75)
    assert v[cdr.IMU_ACCEL] == (-0.5, 0.25, 9.80665)
    values = list(v)
    values[cdr.IMU_GYRO] = (1.0, 2.0, 3.0)
    back = deserialize_message(cdr.IMU.pack((values[3],), *values[1:]), Imu)
    msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = 1.0, 2.0, 3.0
    assert back == msg


def test_vehicle_state_layout_matches_rclpy() -> None:
    s = VehicleState()
    s.header.stamp.sec, s.header.stamp.nanosec, s.header.frame_id, s.child_frame_id = 7, 8, "map", "base_link"
    s.valid = 0xABC
    s.position.x, s.velocity.y, s.acceleration.z = 1.5, -2.5, 3.5
    s.orientation.x, s.orientation.y, s.orientation.z, s.orientation.w = 0.1, 0.2, 0.3, 0.9
    s.angular_velocity.z, s.angular_acceleration.x = 0.7, -0.8
    s.position_covariance = [float(i) for i in range(9)]
    s.attitude_covariance = [float(-i) for i in range(9)]
    s.gyro_bias.y, s.accel_bias.z, s.terrain_distance = 0.01, -0.02, 2.5
    s.origin.latitude, s.geodetic.altitude = 43.5, 146.25
    v = cdr.VEHICLE_STATE.unpack(serialize_message(s))
    assert v[7] == 0xABC and v[8] == 1.5 and v[12] == -2.5 and v[16] == 3.5
    assert v[17:21] == (0.1, 0.2, 0.3, 0.9) and v[23] == 0.7 and v[24] == -0.8
    assert v[60] == 2.5 and v[61] == 43.5 and v[66] == 146.25
    assert deserialize_message(cdr.VEHICLE_STATE.pack((v[3], v[5]), *v[1:]), VehicleState) == s


@pytest.mark.parametrize("outputs", [[], [0.25], [0.1, 0.2, 0.3, 0.4, 0.5, 0.6]])
def test_actuator_command_with_its_variable_sequence(outputs: list[float]) -> None:
    a = ActuatorCommand()
    a.header.frame_id, a.armed, a.outputs, a.tick = "base_link", True, outputs, 2**40 + 3
    a.input_stamp.sec, a.input_stamp.nanosec = 11, 12
    v = cdr.ACTUATOR_COMMAND.unpack(serialize_message(a))
    n = len(outputs)
    assert v[5] is True and v[6] == n and v[7 + n] == 2**40 + 3 and v[8 + n:] == (11, 12)
    assert [round(x, 6) for x in v[7:7 + n]] == outputs
    assert deserialize_message(cdr.ACTUATOR_COMMAND.pack((v[3], n), *v[1:]), ActuatorCommand) == a


def test_big_endian_payload_is_read_too() -> None:
    raw = serialize_message(_imu("base_link"))
    v = cdr.IMU.unpack(raw)
    s = cdr.IMU.struct((v[3],), ">")
    big = s.pack(cdr.CDR_BE, *v[1:])
    assert cdr.IMU.unpack(big)[1:] == v[1:]


def test_unreadable_bytes_raise_or_fall_back_to_rclpy() -> None:
    raw = serialize_message(_imu("base_link"))
    with pytest.raises(cdr.CdrError, match="truncated|needs"):
        cdr.IMU.unpack(raw[:100])
    other = b"\x00\x07\x00\x00" + raw[4:]  # an encapsulation this reader does not know (XCDR2)
    with pytest.raises(cdr.CdrError, match="not a plain CDR"):
        cdr.IMU.unpack(other)
    with pytest.raises(ValueError, match="unsupported"):
        cdr.CdrLayout("iZ")
    assert cdr.IMU.unpack(raw, Imu) == cdr.IMU.unpack(raw)  # readable: no fallback needed


@pytest.mark.parametrize("t", [0.0, 1.5, 1_700_000_000.999_999_9999, 12.000_000_000_4, 3.999_999_999_7])
def test_split_stamp_is_a_valid_time(t: float) -> None:
    sec, nanosec = cdr.split_stamp(t)
    assert 0 <= nanosec < 1_000_000_000
    assert math.isclose(sec + nanosec * 1e-9, t, abs_tol=1e-6)
    struct.pack("<iI", sec, nanosec)  # fits the Time fields
