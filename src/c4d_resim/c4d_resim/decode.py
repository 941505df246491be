"""The recorded input samples read straight from their CDR bytes, for the re-simulation loop.

Why: rclpy's deserialize_message costs ~6 µs per baro / mag / GNSS / range sample (~0.5 µs here)
and a generic c4d_ros.cdr unpack walks the layout for its string lengths on every call;
re-simulation reads ~600 input samples per second of flight. These messages' only variable field
is the header's frame_id, so the compiled Struct is found from that one length word (byte 12).
The values are those rclpy would give (a CDR double / float32 read into a Python float is the same
number either way); anything that is not little-endian plain CDR of the expected size goes
through CdrLayout.unpack (rclpy's own deserialization), never a wrong value.
"""

from __future__ import annotations

import struct

from sensor_msgs.msg import FluidPressure, Imu, MagneticField, NavSatFix, Range

from c4d_ros import cdr

_CDR_LE = cdr.CDR_LE[:2]


class HeaderOnly:
    """A CdrLayout whose only string / sequence is std_msgs/Header's frame_id: `unpack(raw)` as CdrLayout.unpack."""

    def __init__(self, layout: cdr.CdrLayout, msg_type: type) -> None:
        self.layout, self.msg_type = layout, msg_type
        self._by_length: dict[int, struct.Struct] = {}

    def __call__(self, raw: bytes) -> tuple:
        if raw[:2] == _CDR_LE and len(raw) >= 16:
            n = int.from_bytes(raw[12:16], "little")
            s = self._by_length.get(n)
            if s is None and 16 + n <= len(raw):
                s = self._by_length[n] = self.layout.struct((n,))
            if s is not None and len(raw) >= s.size:
                return s.unpack_from(raw)
        return self.layout.unpack(raw, self.msg_type)


# field indices after unpack: 0 encapsulation, 1-2 stamp, 3-4 frame_id, then the message's own fields
IMU = HeaderOnly(cdr.IMU, Imu)  # gyro cdr.IMU_GYRO, accel cdr.IMU_ACCEL
BARO = HeaderOnly(cdr.CdrLayout(cdr.HEADER + "dd"), FluidPressure)  # 5 fluid_pressure, 6 variance
MAG = HeaderOnly(cdr.CdrLayout(cdr.HEADER + "ddd" + "d" * 9), MagneticField)  # 5-7 magnetic_field
# status (int8 status, uint16 service), 7-9 latitude longitude altitude, 10-18 position_covariance, 19 its type
GNSS = HeaderOnly(cdr.CdrLayout(cdr.HEADER + "bH" + "ddd" + "d" * 9 + "B"), NavSatFix)
GNSS_LAT, GNSS_COV0, GNSS_COV8 = 7, 10, 18
# 5 radiation_type, 6 field_of_view, 7 min_range, 8 max_range, 9 range, 10 variance (float32)
RANGE = HeaderOnly(cdr.CdrLayout(cdr.HEADER + "B" + "fffff"), Range)
RANGE_VALUE = 9
