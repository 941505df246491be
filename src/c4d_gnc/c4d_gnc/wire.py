"""The core's 500 Hz messages in serialized (CDR) form: gyro and navigation state in, actuator command out.

Why not ros_conversions: those build and read rclpy message objects, ~40 µs per message each
way on these machines, three times per 2 ms tick in the core. Here the same fields are read from
and written to the bytes rclpy takes and publishes (`c4d_ros.cdr`, ~1–2 µs). The results equal
ros_conversions' on the same message (src/c4d_gnc/test/test_wire.py checks both ways).
"""

from __future__ import annotations

import math

from sensor_msgs.msg import Imu

from c4d_interfaces.msg import VehicleState
from c4d_ros import cdr

from .gnc import Outputs, StateSample

BASE_LINK = cdr.text("base_link")
_XY, _Z, _VXY = VehicleState.VALID_POSITION_XY, VehicleState.VALID_POSITION_Z, VehicleState.VALID_VELOCITY_XY
_ATT, _TERRAIN = VehicleState.VALID_ATTITUDE, VehicleState.VALID_TERRAIN_DISTANCE
_ORIGIN = VehicleState.VALID_ORIGIN


def gyro_from_cdr(raw: bytes) -> tuple[tuple[float, float, float], float]:
    """(gyro [rad/s], sample time [s]) of a serialized sensor_msgs/Imu."""
    v = cdr.IMU.unpack(raw, Imu)
    return v[cdr.IMU_GYRO], v[1] + v[2] * 1e-9


def state_from_cdr(raw: bytes) -> StateSample:
    """A serialized c4d_interfaces/VehicleState as the core's StateSample (as ros_conversions.state_from_msg)."""
    v = cdr.VEHICLE_STATE.unpack(raw, VehicleState)
    # 1-2 stamp, 3-6 frame ids, 7 valid, 8 position, 11 velocity, 17 orientation x y z w, 21 angular velocity, 60 terrain,
    # 61 origin (latitude, longitude, altitude)
    valid = v[7]
    return StateSample(
        stamp=v[1] + v[2] * 1e-9, position=v[8:11], velocity=v[11:14], orientation=(v[20], v[17], v[18], v[19]),
        angular_velocity=v[21:24], valid_position=bool(valid & _XY) and bool(valid & _Z), valid_attitude=bool(valid & _ATT),
        valid_velocity=bool(valid & _VXY),
        terrain_distance=v[60] if valid & _TERRAIN else math.nan, origin=v[61:64] if valid & _ORIGIN else None)


def actuator_cdr(out: Outputs, now: float, tick: int) -> bytes:
    """The serialized c4d_interfaces/ActuatorCommand of `out` (as ros_conversions.actuator_msg)."""
    n = len(out.commands)
    outputs = out.commands if out.armed else (0.0,) * n
    return cdr.ACTUATOR_COMMAND.pack((BASE_LINK[0], n), *cdr.split_stamp(now), *BASE_LINK, out.armed, n, *outputs, tick,
                                     *cdr.split_stamp(out.input_stamp))
