"""Serialized (CDR) form of the messages on c4d's 500 Hz paths, read and written with `struct`.

Why: on these machines rclpy spends ~40 µs turning one received sensor_msgs/Imu into a Python
message and ~15 µs turning one back into bytes, for a message whose payload is six floats; a
500 Hz stream crosses three such edges (sim → perception → navigation, core). A subscription
created with `raw=True` hands over the serialized bytes and `Publisher.publish(bytes)` sends
bytes as they are: reading the few fields a node needs with one precompiled `struct.Struct`
and writing a message in one `pack` costs about a microsecond (bench/loop_latency_cpu.py,
docs/performance.md § hot paths). The wire format is the standard one (XCDR1, what rmw_fastrtps
writes), so every other ROS tool on the topic sees ordinary messages.

A `CdrLayout` is a flat list of fields: struct codes ('i', 'I', 'Q', 'd', 'f', '?'), 'S' for a
string, 'F' for a float32 sequence. Each distinct set of string lengths / sequence counts gets
its own compiled Struct (cached), with the CDR alignment padding written as pad bytes. The
unpacked tuple holds, per field in order: one value; for 'S' the length (with the terminating
NUL) and the bytes; for 'F' the count and the values. Anything that is not a little- or
big-endian plain CDR payload of the expected size raises CdrError (callers fall back to rclpy's
own deserialization), never a wrong value.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence

SIZES = {"?": 1, "b": 1, "B": 1, "h": 2, "H": 2, "i": 4, "I": 4, "f": 4, "q": 8, "Q": 8, "d": 8}
VARIABLE = "SF"
CDR_LE = b"\x00\x01\x00\x00"  # encapsulation header: plain CDR, little endian, no options
CDR_BE = b"\x00\x00\x00\x00"
_U32 = {"<": struct.Struct("<I"), ">": struct.Struct(">I")}
_STAMP = {"<": struct.Struct("<iI"), ">": struct.Struct(">iI")}


class CdrError(ValueError):
    """The bytes are not a CDR payload this layout can read (other encoding, truncated)."""


class CdrLayout:
    """A message's CDR layout (see the module docstring); `pack` writes little-endian CDR."""

    def __init__(self, fields: str | Sequence[str]) -> None:
        self.fields = tuple(fields)
        unknown = [f for f in self.fields if f not in SIZES and f not in VARIABLE]
        if unknown:
            raise ValueError(f"unsupported CDR field code(s): {unknown}")
        self._structs: dict[tuple[str, tuple[int, ...]], struct.Struct] = {}
        self._var_offsets: dict[tuple[int, ...], int] = {}  # known lengths so far -> offset of the next length

    def _walk(self, lengths: Sequence[int], stop_at_var: int | None = None) -> tuple[str, int]:
        """Format (without byte order) for `lengths`, and the payload offset reached (or that of
        variable field number `stop_at_var`'s length word)."""
        fmt, offset, var = [], 0, 0
        for code in self.fields:
            if code in VARIABLE:
                pad = -offset % 4
                if var == stop_at_var:
                    return "", offset + pad
                n = lengths[var]
                var += 1
                fmt.append("x" * pad + "I" + (f"{n}s" if code == "S" else "f" * n))
                offset += pad + 4 + (n if code == "S" else 4 * n)
            else:
                size = SIZES[code]
                pad = -offset % size
                fmt.append("x" * pad + code)
                offset += pad + size
        return "".join(fmt), offset

    def struct(self, lengths: tuple[int, ...] = (), order: str = "<") -> struct.Struct:
        """The compiled Struct (4-byte encapsulation header first) for these string lengths
        (with NUL) / sequence counts."""
        key = (order, lengths)
        s = self._structs.get(key)
        if s is None:
            s = self._structs[key] = struct.Struct(order + "4s" + self._walk(lengths)[0])
        return s

    def lengths(self, buf: bytes, order: str = "<") -> tuple[int, ...]:
        """The string lengths / sequence counts stored in `buf`."""
        out: tuple[int, ...] = ()
        u32 = _U32[order]
        n_var = sum(1 for f in self.fields if f in VARIABLE)
        while len(out) < n_var:
            offset = self._var_offsets.get(out)
            if offset is None:
                offset = self._var_offsets[out] = self._walk(out, stop_at_var=len(out))[1]
            if 4 + offset + 4 > len(buf):
                raise CdrError("CDR payload truncated")
            out += (u32.unpack_from(buf, 4 + offset)[0],)
        return out

    def unpack(self, buf: bytes, msg_type: type | None = None) -> tuple:
        """All fields of `buf` (first item: the encapsulation header). Unreadable bytes: with
        `msg_type`, rclpy deserializes them and the message is read again in plain CDR (another
        vendor's encoding costs time, never a wrong value); without, CdrError."""
        try:
            return self._unpack(buf)
        except CdrError:
            if msg_type is None:
                raise
            from rclpy.serialization import deserialize_message, serialize_message

            return self._unpack(serialize_message(deserialize_message(bytes(buf), msg_type)))

    def _unpack(self, buf: bytes) -> tuple:
        order = byte_order(buf)
        s = self.struct(self.lengths(buf, order), order)
        if len(buf) < s.size:
            raise CdrError(f"CDR payload of {len(buf)} bytes, the layout needs {s.size}")
        return s.unpack_from(buf)

    def pack(self, lengths: tuple[int, ...], *values) -> bytes:
        """Little-endian CDR bytes of `values` (in field order, as unpack returns them after the header)."""
        return self.struct(lengths).pack(CDR_LE, *values)


def byte_order(buf: bytes) -> str:
    """'<' or '>' from the encapsulation header; CdrError for anything but plain CDR."""
    head = bytes(buf[:4])
    if head[:2] == CDR_LE[:2]:
        return "<"
    if head[:2] == CDR_BE[:2] and len(buf) >= 4:
        return ">"
    raise CdrError(f"not a plain CDR payload (encapsulation {head.hex()})")


def header_stamp(buf: bytes) -> tuple[int, int]:
    """(sec, nanosec) of a message that starts with a std_msgs/Header (most stamped messages)."""
    order = byte_order(buf)
    if len(buf) < 12:
        raise CdrError("CDR payload truncated")
    sec, nanosec = _STAMP[order].unpack_from(buf, 4)
    return sec, nanosec


def text(s: str) -> tuple[int, bytes]:
    """(length with the NUL, bytes) of a string field as pack expects them."""
    b = s.encode()
    return len(b) + 1, b


def split_stamp(t: float) -> tuple[int, int]:
    """(sec, nanosec) of a time in seconds (as c4d_ros.stamps.s_to_stamp, without a message)."""
    sec = int(t // 1)
    nanosec = int(round((t - sec) * 1e9))
    if nanosec >= 1_000_000_000:
        sec, nanosec = sec + 1, nanosec - 1_000_000_000
    return sec, nanosec


# --- the hot-path messages -------------------------------------------------------------------
HEADER = "iIS"  # builtin_interfaces/Time stamp, string frame_id

# sensor_msgs/Imu: header, orientation (x y z w), covariance[9], angular_velocity, covariance[9],
# linear_acceleration, covariance[9]
IMU = CdrLayout(HEADER + "dddd" + "d" * 9 + "ddd" + "d" * 9 + "ddd" + "d" * 9)
IMU_GYRO = slice(18, 21)  # in IMU.unpack's tuple (0: encapsulation, 1-2 stamp, 3-4 frame_id, 5-8 orientation, ...)
IMU_ACCEL = slice(30, 33)

# c4d_interfaces/VehicleState (see its .msg): header, child_frame_id, valid, position, velocity,
# acceleration, orientation (x y z w), angular_velocity, angular_acceleration, 3 covariances[9],
# gyro_bias, accel_bias, terrain_distance (float32), origin and geodetic (GeoPoint: lat lon alt)
VEHICLE_STATE = CdrLayout(HEADER + "S" + "I" + "ddd" * 3 + "dddd" + "ddd" * 2 + "d" * 27 + "ddd" * 2 + "f" + "ddd" * 2 + "BB")

# c4d_interfaces/ActuatorCommand: header, armed, outputs (float32[]), tick, input_stamp
ACTUATOR_COMMAND = CdrLayout(HEADER + "?" + "F" + "Q" + "iI")
