"""MAVLink parameter microservice (https://mavlink.io/en/services/parameter.html), vehicle side.

What: a fixed table of parameters (≤ 16-character ids, REAL32 or INT32, bounds, default, doc),
each either owned by the bridge (e.g. geofence limits and cruise speed applied to missions a GCS
uploads) or mapped onto a ROS node parameter (`node`/`ros_name`: set through that node's
set_parameters service by the bridge node). PARAM_REQUEST_LIST streams every value,
PARAM_REQUEST_READ answers by id or index, PARAM_SET checks type, finiteness and bounds: accepted
values are persisted to a YAML file (so they survive restarts) and echoed in PARAM_VALUE;
rejected ones get PARAM_ERROR (VALUE_OUT_OF_RANGE / DOES_NOT_EXIST) plus, as older GCSs expect,
a PARAM_VALUE with the unchanged current value.

Why the bridge owns a table instead of exposing every ROS parameter: MAVLink ids are limited to 16
characters, typed as float/int and expected to be stable across versions; an explicit table keeps
that contract and documents bounds in one place.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import yaml

from .signing import mavlink

M = mavlink


@dataclass(frozen=True)
class ParamSpec:
    name: str
    default: float
    minimum: float
    maximum: float
    integer: bool = False
    node: str = ""  # ROS node whose parameter this is ("" = the bridge's own)
    ros_name: str = ""
    doc: str = ""

    @property
    def mav_type(self) -> int:
        return M.MAV_PARAM_TYPE_INT32 if self.integer else M.MAV_PARAM_TYPE_REAL32


TABLE: tuple[ParamSpec, ...] = (
    ParamSpec("SYSID_THISMAV", 1, 1, 250, True, doc="MAVLink system id of the vehicle (applies at the next start)"),
    ParamSpec("MIS_TAKEOFF_ALT", 5.0, 1.0, 100.0, doc="[m] take-off altitude when NAV_TAKEOFF gives none"),
    ParamSpec("MPC_XY_CRUISE", 5.0, 0.5, 8.0, doc="[m/s] cruise speed of missions uploaded over MAVLink"),
    ParamSpec("RTL_RETURN_ALT", 15.0, 2.0, 120.0, doc="[m] RTL altitude of missions uploaded over MAVLink"),
    ParamSpec("GF_MAX_HOR_DIST", 0.0, 0.0, 10000.0, doc="[m] geofence radius from home (0 = none) for uploaded missions"),
    ParamSpec("GF_MAX_VER_DIST", 0.0, 0.0, 500.0, doc="[m] geofence ceiling above home (0 = none) for uploaded missions"),
    ParamSpec("COM_DL_LOSS_T", 5.0, 1.0, 60.0, doc="[s] no GCS heartbeat this long = data link lost"),
    ParamSpec("SIM_WIND_GUST", 0.0, 0.0, 15.0, node="sim", ros_name="fault.wind_gust_m_s",
              doc="[m/s] SITL: extra wind gust amplitude"),
    ParamSpec("SIM_BAT_DRAIN", 1.0, 0.0, 1000.0, node="sim", ros_name="fault.battery_drain_factor",
              doc="SITL: battery drain multiplier"),
)


def param_id(name: str) -> bytes:
    return name.encode()[:16]


def decode_id(raw) -> str:
    if isinstance(raw, bytes):
        raw = raw.decode("ascii", errors="replace")
    return str(raw).split("\x00", 1)[0]


class ParamServer:
    def __init__(self, send: Callable[[object], None], store: Path | None,
                 apply: Callable[[ParamSpec, float], None] | None = None, table: tuple[ParamSpec, ...] = TABLE) -> None:
        """`store`: YAML file of persisted values (None: nothing persists); `apply(spec, value)`
        pushes a mapped parameter to its node (the bridge node does it asynchronously)."""
        self.send, self.store, self.apply, self.table = send, store, apply, table
        self.index = {p.name: k for k, p in enumerate(table)}
        self.values = {p.name: float(p.default) for p in table}
        self.load_errors: list[str] = []
        if store is not None and store.exists():
            self._load(store)

    def _load(self, store: Path) -> None:
        try:
            doc = yaml.safe_load(store.read_text()) or {}
        except (OSError, yaml.YAMLError) as exc:
            self.load_errors.append(f"{store}: unreadable ({exc.__class__.__name__}); defaults used")
            return
        if not isinstance(doc, dict):
            self.load_errors.append(f"{store}: not a mapping; defaults used")
            return
        for name, value in doc.items():
            reason = self.check(str(name), value)
            if reason:
                self.load_errors.append(f"{store}: {name}: {reason}; ignored")
            else:
                self.values[str(name)] = float(value)

    def check(self, name: str, value) -> str:
        """Why `value` cannot be set for `name` ("" = it can)."""
        if name not in self.index:
            return "no such parameter"
        spec = self.table[self.index[name]]
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            return "not a finite number"
        if spec.integer and value != int(value):
            return "must be an integer"
        if not spec.minimum <= value <= spec.maximum:
            return f"{value:g} outside [{spec.minimum:g}, {spec.maximum:g}]"
        return ""

    def get(self, name: str) -> float:
        return self.values[name]

    def _value_message(self, name: str):
        k = self.index[name]
        spec = self.table[k]
        value = self.values[name]
        if spec.integer:  # INT32 travels bytewise in the float field (MAVLink "bytewise" encoding)
            import struct

            value = struct.unpack("<f", struct.pack("<i", int(value)))[0]
        return M.MAVLink_param_value_message(param_id(name), value, spec.mav_type, len(self.table), k)

    def handle(self, msg) -> None:
        kind = msg.get_type()
        if kind == "PARAM_REQUEST_LIST":
            for spec in self.table:
                self.send(self._value_message(spec.name))
        elif kind == "PARAM_REQUEST_READ":
            name = decode_id(msg.param_id) if msg.param_index < 0 else (
                self.table[msg.param_index].name if msg.param_index < len(self.table) else "")
            if name in self.index:
                self.send(self._value_message(name))
            else:
                self._error(msg, name, M.MAV_PARAM_ERROR_DOES_NOT_EXIST)
        elif kind == "PARAM_SET":
            self._set(msg)

    def _error(self, msg, name: str, error: int) -> None:
        self.send(M.MAVLink_param_error_message(msg.get_srcSystem(), msg.get_srcComponent(), param_id(name),
                                                getattr(msg, "param_index", -1), error))

    def _set(self, msg) -> None:
        name = decode_id(msg.param_id)
        if name not in self.index:
            return self._error(msg, name, M.MAV_PARAM_ERROR_DOES_NOT_EXIST)
        spec = self.table[self.index[name]]
        value = float(msg.param_value)
        if spec.integer and msg.param_type in (M.MAV_PARAM_TYPE_INT32, M.MAV_PARAM_TYPE_UINT32, M.MAV_PARAM_TYPE_INT16,
                                               M.MAV_PARAM_TYPE_UINT16, M.MAV_PARAM_TYPE_INT8, M.MAV_PARAM_TYPE_UINT8):
            import struct

            value = float(struct.unpack("<i", struct.pack("<f", msg.param_value))[0])
        if self.check(name, value):
            self._error(msg, name, M.MAV_PARAM_ERROR_VALUE_OUT_OF_RANGE)
            self.send(self._value_message(name))  # the unchanged value: what older GCSs wait for
            return
        self.values[name] = value
        self._persist()
        if spec.node and self.apply is not None:
            self.apply(spec, value)
        self.send(self._value_message(name))

    def _persist(self) -> None:
        if self.store is None:
            return
        self.store.parent.mkdir(parents=True, exist_ok=True)
        changed = {p.name: (int(self.values[p.name]) if p.integer else self.values[p.name])
                   for p in self.table if self.values[p.name] != p.default}
        tmp = self.store.with_suffix(".tmp")
        tmp.write_text(yaml.safe_dump(changed, sort_keys=True))
        os.replace(tmp, self.store)  # atomic: a crash never leaves a half-written file
