"""MAVLink parameter microservice (https://mavlink.io/en/services/parameter.html), vehicle side.

What: a fixed table of parameters (≤ 16-character ids, REAL32 or INT32, bounds, default, doc),
PX4's names where PX4 has the parameter (MC_ROLLRATE_P, MPC_XY_VEL_P_ACC, ...; c4d's units, see
docs/parameters.md), C4D_* names otherwise. Each is either owned by the bridge (e.g. geofence
limits and cruise speed applied to missions a GCS uploads; persisted in the bridge's YAML file)
or mapped onto ROS parameters of a node (`node`/`ros_names`: set through that node's
set_parameters service). A `live` mapping is one of the node's live tunables (c4d_ros.live_params):
the node validates, applies at its boundary and persists the value per vehicle; the bridge reads
the values in force from the node (`node_values`: at start and from /parameter_events, so a
`ros2 param set` shows up in the GCS too) and echoes in PARAM_VALUE only what the node accepted.

PARAM_REQUEST_LIST streams every value with param_count / param_index, PARAM_REQUEST_READ
answers by id or index, PARAM_SET checks id, type, finiteness and bounds first: rejected ones
get PARAM_ERROR (DOES_NOT_EXIST / VALUE_OUT_OF_RANGE / READ_ONLY) plus, as older GCSs expect, a
PARAM_VALUE with the unchanged value. Node-mapped sets are coalesced (newest value per id) and
sent at most `rate_hz` times a second per node with one request in flight, so a flood of
PARAM_SETs costs the node a few service calls, not thousands; a node's refusal or silence is a
PARAM_ERROR plus the unchanged value (and the reason via `on_refused`, a STATUSTEXT).

Why the bridge owns a table instead of exposing every ROS parameter: MAVLink ids are limited to 16
characters, typed as float/int and expected to be stable across versions; an explicit table keeps
that contract and documents bounds in one place (test/test_live_params_table.py checks it
against the nodes' own tables).
"""

from __future__ import annotations

import math
import os
import struct
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import yaml

from .signing import mavlink

M = mavlink
INT_TYPES = (M.MAV_PARAM_TYPE_INT32, M.MAV_PARAM_TYPE_UINT32, M.MAV_PARAM_TYPE_INT16, M.MAV_PARAM_TYPE_UINT16,
             M.MAV_PARAM_TYPE_INT8, M.MAV_PARAM_TYPE_UINT8)


@dataclass(frozen=True)
class ParamSpec:
    name: str
    default: float
    minimum: float
    maximum: float
    integer: bool = False
    node: str = ""  # ROS node whose parameter this is ("" = the bridge's own)
    ros_names: tuple[str, ...] = ()  # the node's parameter(s) this sets (several: e.g. MPC_XY_P = x and y)
    doc: str = ""
    live: bool = False  # a live tunable of `node`: the node applies and persists it, the bridge reads it back

    @property
    def mav_type(self) -> int:
        return M.MAV_PARAM_TYPE_INT32 if self.integer else M.MAV_PARAM_TYPE_REAL32


def _core(name: str, ros: str | tuple[str, ...], default: float, low: float, high: float, doc: str) -> ParamSpec:
    return ParamSpec(name, default, low, high, node="core", ros_names=(ros,) if isinstance(ros, str) else ros, doc=doc,
                     live=True)


def _rate_axis(px4: str, lim: str, axis: str, p: float, i: float, d: float, i_lim: float) -> tuple[ParamSpec, ...]:
    g = f"gains.rate.{axis}"
    return (_core(f"MC_{px4}RATE_P", f"{g}.p", p, 0.0, 200.0, f"[1/s] {axis} rate P (angular accel. per rate error)"),
            _core(f"MC_{px4}RATE_I", f"{g}.i", i, 0.0, 200.0, f"[1/s^2] {axis} rate I"),
            _core(f"MC_{px4}RATE_D", f"{g}.d", d, 0.0, 10.0, f"[1] {axis} rate D (on the filtered gyro)"),
            _core(f"MC_{lim}_INT_LIM", f"{g}.i_limit", i_lim, 0.0, 500.0, f"[rad/s^2] {axis} rate integrator clamp"))


def _velocity(px4: str, axes: tuple[str, ...], p: float, i: float, d: float, i_lim: float) -> tuple[ParamSpec, ...]:
    def names(term: str) -> tuple[str, ...]:
        return tuple(f"gains.velocity.{a}.{term}" for a in axes)
    what = "horizontal" if px4 == "XY" else "vertical"
    return (_core(f"MPC_{px4}_VEL_P_ACC", names("p"), p, 0.0, 50.0, f"[1/s] {what} velocity P (accel. per speed error)"),
            _core(f"MPC_{px4}_VEL_I_ACC", names("i"), i, 0.0, 50.0, f"[1/s^2] {what} velocity I"),
            _core(f"MPC_{px4}_VEL_D_ACC", names("d"), d, 0.0, 10.0, f"[1] {what} velocity D"),
            _core(f"C4D_{px4}_VEL_I_LIM", names("i_limit"), i_lim, 0.0, 20.0, f"[m/s^2] {what} velocity integrator clamp"))


# The core's defaults below are the bundled quad_x airframe's; the bridge shows the values the core
# reports once it is reachable (another airframe, stored changes).
CORE_TABLE: tuple[ParamSpec, ...] = (
    *_rate_axis("ROLL", "RR", "roll", 22.0, 8.0, 0.5, 40.0),
    *_rate_axis("PITCH", "PR", "pitch", 22.0, 8.0, 0.5, 40.0),
    *_rate_axis("YAW", "YR", "yaw", 12.0, 4.0, 0.0, 10.0),
    _core("IMU_DGYRO_CUTOFF", "gains.rate.d_cutoff_hz", 40.0, 1.0, 250.0, "[Hz] low-pass cutoff of the rate loop's D term"),
    _core("MC_ROLL_P", "gains.attitude.roll.p", 9.0, 0.0, 50.0, "[1/s] roll attitude P (body rate per angle error)"),
    _core("MC_PITCH_P", "gains.attitude.pitch.p", 9.0, 0.0, 50.0, "[1/s] pitch attitude P"),
    _core("MC_YAW_P", "gains.attitude.yaw.p", 4.0, 0.0, 50.0, "[1/s] yaw attitude P"),
    _core("MC_ROLLRATE_MAX", "limits.max_rate_deg_s.roll", 220.0, 5.0, 2000.0, "[deg/s] roll rate limit"),
    _core("MC_PITCHRATE_MAX", "limits.max_rate_deg_s.pitch", 220.0, 5.0, 2000.0, "[deg/s] pitch rate limit"),
    _core("MC_YAWRATE_MAX", "limits.max_rate_deg_s.yaw", 120.0, 5.0, 2000.0, "[deg/s] yaw rate limit"),
    _core("MPC_XY_P", ("gains.position.x.p", "gains.position.y.p"), 1.5, 0.0, 20.0,
          "[1/s] horizontal position P (speed per position error)"),
    _core("MPC_Z_P", "gains.position.z.p", 1.5, 0.0, 20.0, "[1/s] vertical position P"),
    *_velocity("XY", ("x", "y"), 3.5, 0.3, 0.1, 2.0),
    *_velocity("Z", ("z",), 5.0, 1.5, 0.0, 3.0),
    _core("MPC_XY_VEL_MAX", "limits.max_horizontal_speed_m_s", 8.0, 0.1, 30.0, "[m/s] horizontal speed limit"),
    _core("MPC_Z_VEL_MAX_UP", "limits.max_climb_speed_m_s", 3.0, 0.1, 15.0, "[m/s] climb speed limit"),
    _core("MPC_Z_VEL_MAX_DN", "limits.max_descent_speed_m_s", 1.5, 0.1, 10.0, "[m/s] descent speed limit"),
    _core("MPC_TILTMAX_AIR", "limits.max_tilt_deg", 35.0, 5.0, 80.0, "[deg] tilt limit"),
    _core("MPC_THR_MIN", "limits.min_thrust_ratio", 0.08, 0.0, 1.0, "[1] lowest collective thrust in flight"),
    _core("MPC_THR_MAX", "limits.max_thrust_ratio", 0.95, 0.05, 1.0, "[1] highest collective thrust"),
    _core("C4D_IDLE_CMD", "motor.idle_command", 0.05, 0.0, 0.5, "[1] mixer: command of an armed motor at zero demand"),
    _core("MPC_TKO_SPEED", "guidance.takeoff_speed_m_s", 1.5, 0.1, 10.0, "[m/s] take-off climb speed"),
    _core("MPC_LAND_SPEED", "guidance.land_speed_m_s", 0.7, 0.1, 5.0, "[m/s] landing descent speed"),
)


def _live(node: str, name: str, ros: str, default: float, low: float, high: float, doc: str) -> ParamSpec:
    return ParamSpec(name, default, low, high, node=node, ros_names=(ros,), doc=doc, live=True)


# The navigation node's EKF noises and gates (c4d_gnc.live_navigation; defaults: EkfConfig's, the drag
# coefficients the bundled quad_x's drag over mass as the node's default airframe). PX4's
# EKF2_* names where PX4 has the parameter (c4d's units: the bias walks are per sqrt(s), see docs).
NAVIGATION_TABLE: tuple[ParamSpec, ...] = tuple(_live("navigation", *row) for row in (
    ("EKF2_GYR_NOISE", "ekf.gyro_noise", 0.003, 1e-5, 1.0, "[rad/s] gyro noise, 1 sigma per sample"),
    ("EKF2_ACC_NOISE", "ekf.accel_noise", 0.05, 1e-4, 10.0, "[m/s^2] accelerometer noise, 1 sigma per sample"),
    ("EKF2_GYR_B_NOISE", "ekf.gyro_bias_walk", 2e-4, 0.0, 0.1, "[rad/s/sqrt(s)] gyro bias random walk"),
    ("EKF2_ACC_B_NOISE", "ekf.accel_bias_walk", 1e-3, 0.0, 1.0, "[m/s^2/sqrt(s)] accelerometer bias random walk"),
    ("EKF2_GPS_P_GATE", "ekf.gps_gate", 5.0, 1.0, 100.0, "[sigma] GNSS position innovation gate"),
    ("EKF2_BARO_NOISE", "ekf.baro_noise", 0.15, 0.01, 50.0, "[m] barometric altitude noise"),
    ("EKF2_HEAD_NOISE", "ekf.mag_heading_noise", 0.05235987755982988, 1e-3, 3.0, "[rad] magnetometer heading noise"),
    ("C4D_EKF_POS_TOUT", "ekf.position_valid_s", 1.0, 0.05, 60.0, "[s] position valid this long after a fix"),
    ("C4D_EKF_GPS_RST", "ekf.gps_reset_after_s", 3.0, 0.1, 600.0, "[s] GNSS outage after which a gated fix resets"),
    ("C4D_EKF_ZVEL_SIG", "ekf.zero_velocity_sigma", 0.05, 1e-3, 10.0, "[m/s] zero-velocity update sigma on the ground"),
    ("C4D_EKF_NOAID_V", "ekf.unaided_velocity_sigma", 1.0, 0.0, 100.0, "[m/s] unaided-flight velocity sigma (0 = off)"),
    ("C4D_EKF_HDG_TOUT", "ekf.heading_valid_s", 2.0, 0.05, 600.0, "[s] heading valid this long after a mag sample"),
    ("EKF2_MCOEF", "ekf.drag_horizontal_per_s", 0.25 / 1.5, 0.0, 10.0, "[1/s] horizontal drag per mass (0 = no drag fusion)"),
    ("C4D_EKF_DRAG_V", "ekf.drag_vertical_per_s", 0.35 / 1.5, 0.0, 10.0, "[1/s] vertical drag per unit mass"),
    ("C4D_EKF_DRAG_NS", "ekf.drag_noise", 0.02, 1e-4, 10.0, "[m/s^2] drag fusion specific force sigma (0.1 s mean)"),
    ("EKF2_WIND_NSD", "ekf.wind_walk", 0.1, 0.0, 10.0, "[m/s/sqrt(s)] horizontal wind random walk"),
))

# The health node's failsafe thresholds and timeouts (c4d_health.live_policy; defaults: the bundled
# config/failsafe.yaml). The per-event delays (events.<event>.delay_s) are ROS parameters only.
HEALTH_TABLE: tuple[ParamSpec, ...] = tuple(_live("health", *row) for row in (
    ("BAT_LOW_THR", "battery_low_threshold", 0.30, 0.01, 0.99, "[1] state of charge below this: battery_low"),
    ("BAT_CRIT_THR", "battery_critical_threshold", 0.15, 0.01, 0.99, "[1] state of charge below this: battery_critical"),
    ("COM_OF_LOSS_T", "offboard_loss_timeout_s", 0.5, 0.05, 30.0, "[s] OFFBOARD setpoints silent this long: offboard_loss"),
    ("C4D_NODE_TOUT", "node_timeout_s", 0.6, 0.1, 30.0, "[s] a monitored node silent this long: dead or stalled"),
    ("C4D_STALL_MS", "core_stall_ms", 20.0, 2.0, 1000.0, "[ms] worst core tick of a window above this: core_stall"),
    ("C4D_STALL_SKIP", "core_stall_skipped_ticks", 25.0, 0.0, 100000.0, "[ticks] skipped core ticks: core_stall"),
    ("C4D_STATS_TOUT", "core_stats_timeout_s", 1.5, 0.2, 60.0, "[s] no executor statistics this long: core_stall"),
    ("C4D_STALL_REP_N", "core_stall_repeat_count", 3.0, 1.0, 1000.0, "[1] this many stalls in the window: repeated"),
    ("C4D_STALL_REP_T", "core_stall_repeat_window_s", 10.0, 0.1, 3600.0, "[s] window of C4D_STALL_REP_N"),
    ("C4D_OBST_DET_R", "obstacle_detection_range_m", 2.0, 0.05, 100.0, "[m] obstacle nearer: obstacle_near"),
    ("C4D_OBST_PROT_R", "obstacle_protection_radius_m", 0.5, 0.01, 50.0, "[m] obstacle nearer: collision risk"),
))

TABLE: tuple[ParamSpec, ...] = (
    ParamSpec("SYSID_THISMAV", 1, 1, 250, True, doc="MAVLink system id of the vehicle (applies at the next start)"),
    ParamSpec("MIS_TAKEOFF_ALT", 5.0, 1.0, 100.0, doc="[m] take-off altitude when NAV_TAKEOFF gives none"),
    ParamSpec("MPC_XY_CRUISE", 5.0, 0.5, 8.0, doc="[m/s] cruise speed of missions uploaded over MAVLink"),
    ParamSpec("RTL_RETURN_ALT", 15.0, 2.0, 120.0, doc="[m] RTL altitude of missions uploaded over MAVLink"),
    ParamSpec("GF_MAX_HOR_DIST", 0.0, 0.0, 10000.0, doc="[m] geofence radius from home (0 = none) for uploaded missions"),
    ParamSpec("GF_MAX_VER_DIST", 0.0, 0.0, 500.0, doc="[m] geofence ceiling above home (0 = none) for uploaded missions"),
    ParamSpec("COM_DL_LOSS_T", 5.0, 1.0, 60.0, doc="[s] no GCS heartbeat this long = data link lost"),
    ParamSpec("SIM_WIND_GUST", 0.0, 0.0, 15.0, node="sim", ros_names=("fault.wind_gust_m_s",),
              doc="[m/s] SITL: extra wind gust amplitude"),
    ParamSpec("SIM_BAT_DRAIN", 1.0, 0.0, 1000.0, node="sim", ros_names=("fault.battery_drain_factor",),
              doc="SITL: battery drain multiplier"),
    *CORE_TABLE,
    *NAVIGATION_TABLE,
    *HEALTH_TABLE,
)

# apply(node, [(spec, value), ...], done): set them on `node`; done(results) with one (ok, reason) per
# entry, or done(None) when the node did not answer
Apply = Callable[[str, list[tuple[ParamSpec, float]], Callable[[list[tuple[bool, str]] | None], None]], None]


def param_id(name: str) -> bytes:
    return name.encode()[:16]


def decode_id(raw) -> str:
    if isinstance(raw, bytes):
        raw = raw.decode("ascii", errors="replace")
    return str(raw).split("\x00", 1)[0]


class ParamServer:
    def __init__(self, send: Callable[[object], None], store: Path | None, apply: Apply | None = None,
                 table: tuple[ParamSpec, ...] = TABLE, rate_hz: float = 20.0,
                 on_refused: Callable[[str], None] | None = None) -> None:
        """`store`: YAML file of the bridge's persisted values (None: nothing persists); `apply` pushes
        node-mapped values to their node (the bridge node does it asynchronously); `rate_hz`: at most
        this many set requests a second per node; `on_refused(text)`: a node's refusal, one line."""
        self.send, self.store, self.apply, self.table = send, store, apply, table
        self.on_refused = on_refused
        self.index = {p.name: k for k, p in enumerate(table)}
        self.by_ros = {(p.node, r): p for p in table if p.node for r in p.ros_names}
        self.values = {p.name: float(p.default) for p in table}
        self.load_errors: list[str] = []
        self.min_interval_s = 1.0 / rate_hz
        self.outgoing: dict[str, dict[str, tuple[float, object]]] = {}  # node -> name -> (value, the PARAM_SET)
        self.in_flight: set[str] = set()
        self.next_send: dict[str, float] = {}
        self.dirty = False  # the bridge's own values changed since the last write
        self.coalesced = 0  # PARAM_SETs superseded by a newer one before they were sent
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
            if not reason and self.table[self.index[str(name)]].live:
                reason = "kept by its node, not by the bridge"
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
                                                self.index.get(name, getattr(msg, "param_index", -1)), error))

    def _refuse(self, msg, name: str, error: int) -> None:
        self._error(msg, name, error)
        self.send(self._value_message(name))  # the unchanged value: what older GCSs wait for

    def _set(self, msg) -> None:
        name = decode_id(msg.param_id)
        if name not in self.index:
            return self._error(msg, name, M.MAV_PARAM_ERROR_DOES_NOT_EXIST)
        spec = self.table[self.index[name]]
        value = float(msg.param_value)
        if spec.integer and msg.param_type in INT_TYPES:
            value = float(struct.unpack("<i", struct.pack("<f", msg.param_value))[0])
        if self.check(name, value):
            return self._refuse(msg, name, M.MAV_PARAM_ERROR_VALUE_OUT_OF_RANGE)
        if spec.node:
            if self.apply is None:
                return self._refuse(msg, name, M.MAV_PARAM_ERROR_COMPONENT_NOT_FOUND)
            queue = self.outgoing.setdefault(spec.node, {})
            self.coalesced += name in queue
            queue[name] = (value, msg)  # echoed once the node answered (pump)
            return
        self.values[name] = value
        self.dirty = True
        self.send(self._value_message(name))

    # ------------------------------------------------------------------ node-mapped values
    def pump(self, now: float) -> None:
        """Send each node's coalesced changes (one request in flight per node, at most rate_hz a
        second) and write the bridge's own changed values (at most once per call)."""
        if self.dirty:
            self.dirty = False
            self._persist()
        for node, queue in self.outgoing.items():
            if not queue or node in self.in_flight or now < self.next_send.get(node, -math.inf) or self.apply is None:
                continue
            batch, self.outgoing[node] = dict(queue), {}
            self.in_flight.add(node)
            self.next_send[node] = now + self.min_interval_s
            entries = [(self.table[self.index[name]], value) for name, (value, _) in batch.items()]
            self.apply(node, entries, lambda results, node=node, batch=batch: self._answered(node, batch, results))

    def _answered(self, node: str, batch: dict[str, tuple[float, object]], results) -> None:
        self.in_flight.discard(node)
        for k, (name, (value, msg)) in enumerate(batch.items()):
            spec = self.table[self.index[name]]
            if results is None:
                self._refuse(msg, name, M.MAV_PARAM_ERROR_COMPONENT_NOT_FOUND)
                self._refused(f"{name} not applied: {node} not reachable")
                continue
            ok, reason = results[k]
            if not ok:
                self._refuse(msg, name, M.MAV_PARAM_ERROR_VALUE_OUT_OF_RANGE)
                self._refused(f"{name} refused by {node}: {reason}")
                continue
            self.values[name] = value
            if not spec.live:
                self.dirty = True  # e.g. the sim's fault parameters: kept by the bridge, pushed at start
            self.send(self._value_message(name))

    def _refused(self, text: str) -> None:
        if self.on_refused is not None:
            self.on_refused(text)

    def node_values(self, node: str, values: Mapping[str, object], announce: bool = False) -> None:
        """Values `node` reports (get_parameters at start, /parameter_events later): the live
        parameters mapped onto them take them; `announce` sends PARAM_VALUE for each change (a GCS
        sees a `ros2 param set` as PX4's GCSs see any change)."""
        for ros_name, value in values.items():
            spec = self.by_ros.get((node, ros_name))
            if spec is None or not spec.live or ros_name != spec.ros_names[0] or self.check(spec.name, value):
                continue
            changed = self.values[spec.name] != float(value)  # type: ignore[arg-type]
            self.values[spec.name] = float(value)  # type: ignore[arg-type]
            if changed and announce:
                self.send(self._value_message(spec.name))

    def live_names(self, node: str) -> list[str]:
        """The ROS parameters of `node` the live MAVLink parameters read their value from."""
        return [p.ros_names[0] for p in self.table if p.node == node and p.live]

    def _persist(self) -> None:
        if self.store is None:
            return
        self.store.parent.mkdir(parents=True, exist_ok=True)
        changed = {p.name: (int(self.values[p.name]) if p.integer else self.values[p.name])
                   for p in self.table if not p.live and self.values[p.name] != p.default}
        tmp = self.store.with_suffix(".tmp")
        tmp.write_text(yaml.safe_dump(changed, sort_keys=True))
        os.replace(tmp, self.store)  # atomic: a crash never leaves a half-written file
