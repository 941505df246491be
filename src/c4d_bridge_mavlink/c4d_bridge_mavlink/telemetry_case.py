"""The thesis telemetry case (Table 3.3) in MAVLink: the workload of the link-scheduling test and bench.

What: the 16 Paparazzi telemetry messages of the thesis' case study (§3.3.2: periods and payload
sizes, Pprzlink v2 framing = payload + 8 bytes) mapped to MAVLink 2 common messages whose frame
on the wire is of similar size (payload + 12 bytes), and `case_message(msg_id)`, a message of
that id whose every payload byte of the last field is non-zero, so that MAVLink 2 trailing-zero
truncation never shortens it: every frame has its largest size, the wcet GCD+ plans with.

Mapping rule: on-wire frame within ±4 bytes of the Pprzlink frame; among candidates, prefer a
semantic equivalent, then a message the bridge sends anyway; every id used once. Sizes come from
pymavlink (see docs/mavlink_telemetry.md for the table and why the four IMU messages map to small
status messages: MAVLink has no 8-byte IMU message).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

from .signing import make_mavlink, mavlink
from .telemetry import LinkBudget, Packer, TelemetryScheduler, frame_bytes

PPRZLINK_OVERHEAD = 8  # Pprzlink v2 header + checksum bytes (thesis §3.3.2)
CASE_BAUD = 57600
CASE_QUEUE_BYTES = 256  # bounded send queue of the case (a typical autopilot UART TX buffer)


@dataclass(frozen=True)
class CaseMessage:
    paparazzi: str
    period_s: float
    paparazzi_bytes: int  # payload, Table 3.3
    mavlink: str

    @property
    def msg_id(self) -> int:
        return getattr(mavlink, f"MAVLINK_MSG_ID_{self.mavlink}")

    @property
    def interval_us(self) -> int:
        return round(self.period_s * 1_000_000)

    @property
    def paparazzi_frame(self) -> int:
        return self.paparazzi_bytes + PPRZLINK_OVERHEAD

    @property
    def mavlink_frame(self) -> int:
        return frame_bytes(self.msg_id)


CASE: tuple[CaseMessage, ...] = (
    CaseMessage("ALIVE", 2, 17, "SYSTEM_TIME"),
    CaseMessage("ROTORCRAFT_FP", 1, 58, "HIL_STATE"),
    CaseMessage("INS_REF", 1, 32, "GLOBAL_POSITION_INT"),
    CaseMessage("ROTORCRAFT_NAV_STATUS", 1, 15, "CAMERA_TRIGGER"),
    CaseMessage("ENERGY", 1, 21, "NAMED_VALUE_FLOAT"),
    CaseMessage("DATALINK_REPORT", 1, 11, "RADIO_STATUS"),
    CaseMessage("DL_VALUE", 0.2, 5, "MISSION_ITEM_REACHED"),
    CaseMessage("ROTORCRAFT_STATUS", 0.2, 20, "UAVCAN_NODE_STATUS"),
    CaseMessage("STATE_FILTER_STATUS", 0.2, 4, "EXTENDED_SYS_STATE"),
    CaseMessage("AIR_DATA", 0.2, 28, "VFR_HUD"),
    CaseMessage("INS", 0.2, 36, "LOCAL_POSITION_NED"),
    CaseMessage("GPS_INT", 0.1, 57, "GPS_RAW_INT"),
    CaseMessage("IMU_GYRO_SCALED", 0.04, 12, "DEBUG"),
    CaseMessage("IMU_ACCEL_SCALED", 0.04, 12, "RELAY_STATUS"),
    CaseMessage("IMU_ACCEL_RAW", 0.02, 12, "POWER_STATUS"),
    CaseMessage("IMU_GYRO_RAW", 0.02, 12, "MISSION_CURRENT"),
)

_INT_BYTES = {"int8_t": 1, "uint8_t": 1, "int16_t": 2, "uint16_t": 2, "int32_t": 4, "uint32_t": 4, "int64_t": 8, "uint64_t": 8}


def _value(kind: str, length: int) -> object:
    """A field value without zero bytes (0x01 in every byte of an integer, 1.0 has a non-zero top byte)."""
    if kind == "char":
        return b"x" * max(1, length)
    one = 1.0 if kind in ("float", "double") else int.from_bytes(b"\x01" * _INT_BYTES[kind], "little")
    return [one] * length if length else one


def case_message(msg_id: int) -> mavlink.MAVLink_message:
    """A message of `msg_id` that packs to its largest frame (no trailing zero to truncate)."""
    cls = mavlink.mavlink_map[msg_id]
    lengths = dict(zip(cls.ordered_fieldnames, cls.array_lengths, strict=True))
    args = [_value(kind, lengths[name]) for name, kind in zip(cls.fieldnames, cls.fieldtypes, strict=True)]
    return cls(*args)


def case_scheduler(method: str, pack: Packer, queue_bytes: int = CASE_QUEUE_BYTES) -> TelemetryScheduler:
    """The case's 16 streams on a 57600-baud UART with phases by `method` (gcdplus, zero, paparazzi…),
    in Table 3.3 order (the order Paparazzi's phase rule depends on)."""
    scheduler = TelemetryScheduler(LinkBudget.serial(CASE_BAUD), pack, queue_bytes=queue_bytes, method=method)
    for message in CASE:
        scheduler.add_stream(message.msg_id, message.interval_us, partial(case_message, message.msg_id), name=message.mavlink)
    return scheduler


def simulate(method: str, seconds: float = 4.0, queue_bytes: int = CASE_QUEUE_BYTES) -> TelemetryScheduler:
    """Run the case in simulated time (two hyperperiods by default: the steady state repeats after)."""
    mav = make_mavlink(1, mavlink.MAV_COMP_ID_AUTOPILOT1)

    def pack(msg: mavlink.MAVLink_message) -> bytes:
        data = msg.pack(mav)
        mav.seq = (mav.seq + 1) % 256
        return data

    scheduler = case_scheduler(method, pack, queue_bytes)
    scheduler.start(0.0)
    scheduler.advance(seconds)
    return scheduler
