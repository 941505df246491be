"""`ros2 run c4d_gnc navigation` — state estimation (NavigationEkf via NavigationFilter) as a node.

Subscribes perception/{imu,gps,baro,mag,range_down}; each IMU sample runs one EKF prediction
and publishes navigation/state (c4d_interfaces/VehicleState, stamped with the IMU sample time)
— so the state comes at IMU rate — and navigation/odometry (nav_msgs/Odometry,
`odometry_rate_hz`, default 50 Hz to spare CPU) with navigation/pose (PoseStamped in `map`, for
external nodes) and, where tf2_msgs is installed, TF map → base_link on /tf at the same rate
(not there: one info line, no TF). Validity flags follow the filter: attitude
after alignment, heading while the magnetometer is fused, position/velocity while GNSS fixes
keep coming, origin/global once home is set, terrain distance from a fresh range reading.
A missing sensor clears its flags; nothing stops. While the core reports the vehicle
disarmed (vehicle/status), zero-velocity updates at 10 Hz keep a vehicle standing without GNSS
from drifting; GNSS back after an outage resets the position if dead reckoning left the gate.
Issue 19 (docs/navigation.md): external pose inputs navigation/external/odometry (nav_msgs/Odometry)
and navigation/external/pose (PoseWithCovarianceStamped) — a flood is rate-limited on the raw
message's stamp before it is deserialised —, fixes from navigation/external/gnss when
`gnss_input: external`; primary / secondary sources per axis group; navigation/status
(EstimatorStatus) at 5 Hz and at once on a change (sources, switches, external health, GNSS verdict).
Topic names and QoS: c4d_ros.manifest. Parameters: PARAMS below (read-only); a string
parameter outside its choices, or a partial geodetic origin: one line, exit 2. The EKF's noises,
gates and validity times are live parameters `ekf.*` (c4d_gnc.live_navigation, docs/parameters.md):
checked when set (a refusal says why), applied before the next IMU sample (the node is
single-threaded: never inside an update), logged with that sample's time, journaled for `resim`
(N_RETUNE) and, with `vehicle` set, persisted per vehicle (navigation.yaml).
"""

from __future__ import annotations

import array
import math
import pickle
import struct
import sys
from collections.abc import Callable
from dataclasses import replace

import numpy as np
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped, TransformStamped, Vector3
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import FluidPressure, Imu, MagneticField, NavSatFix, NavSatStatus, Range
from std_msgs.msg import UInt8MultiArray

from c4d_common.airframe import AirframeError, airframe_by_ref
from c4d_common.tunable import TunableError, VehicleStore
from c4d_interfaces.msg import EstimatorStatus, GnssIntegrity, VehicleState, VehicleStatus
from c4d_ros import cdr, gc_policy, lifecycle, node_runtime
from c4d_ros.component import ComponentError, Host, SpunNode, run_components
from c4d_ros.live_params import LiveParameters, describe
from c4d_ros.manifest import (
    EXTERNAL_GNSS,
    EXTERNAL_ODOMETRY,
    EXTERNAL_POSE,
    NAV_JOURNAL,
    NAV_ODOMETRY,
    NAV_POSE,
    NAV_STATE,
    NAV_STATUS,
    P_BARO,
    P_GPS,
    P_IMU,
    P_MAG,
    P_RANGE_DOWN,
    STATUS,
)
from c4d_ros.params import ParameterError, Spec, declare_all
from c4d_ros.stamps import stamp_to_s

from . import journal as jr
from .ekf import EkfConfig, NavigationEkf, drag_config, rotation_matrix
from .external_pose import ExternalConfig, ExternalSample, Rejection
from .gnss_integrity import IntegrityState
from .live_navigation import ekf_with, navigation_table
from .navigation_filter import NavigationConfig, NavigationFilter
from .source_selection import HEIGHT_CHOICES, HORIZONTAL_CHOICES, NAMES
from .state_wire import state_cdr

NAME = "navigation"
PARAMS = {
    "odometry_rate_hz": Spec(50.0, "navigation/odometry publication rate [Hz]", 0.01, 1000.0, read_only=True),
    "mag_declination_deg": Spec(0.0, "magnetic declination, east positive [deg]", -180.0, 180.0, read_only=True),
    "rt_priority": node_runtime.RT_PRIORITY,
    "events_executor": Spec(True, "spin with rclpy's EventsExecutor (less CPU) instead of the default executor [bool]",
                            read_only=True),
    # --- sources (issue 19, docs/navigation.md) ---
    "gnss_input": Spec("perception", "GNSS fixes from [perception | external]: perception/gps or navigation/external/gnss",
                       read_only=True),
    "horizontal_primary": Spec("gnss", "horizontal position source [gnss | external]", read_only=True),
    "horizontal_secondary": Spec("external", "horizontal source when the primary is lost [external | gnss | none]",
                                 read_only=True),
    "height_primary": Spec("baro", "height source [baro | gnss | external | range]", read_only=True),
    "height_secondary": Spec("none", "height source when the primary is lost [baro | gnss | external | range | none]",
                             read_only=True),
    "source_timeout_s": Spec(1.0, "no sample of the active source fused this long: lost, switch [s]", 0.05, 60.0,
                             read_only=True),
    "source_recovery_s": Spec(5.0, "the primary healthy this long: back to it [s]", 0.0, 600.0, read_only=True),
    "switch_blend_s": Spec(10.0, "time constant of the switch offset's decay (no step at a switch) [s]", 0.1, 600.0,
                           read_only=True),
    "external_frame_ids": Spec(["odom"], "accepted frame_id of external poses [string list]", read_only=True),
    "external_max_age_s": Spec(0.5, "older external samples (sample time vs IMU) are stale [s]", 0.01, 1.0,
                               read_only=True),
    "external_max_rate_hz": Spec(250.0, "external samples above this rate are dropped [Hz]", 1.0, 1000.0,
                                 read_only=True),
    "external_position_sigma_m": Spec(0.05, "external position 1σ when the message's covariance is all zero [m]",
                                      0.001, 100.0, read_only=True),
    "external_yaw_sigma_deg": Spec(2.0, "external yaw 1σ when the message's covariance is all zero [deg]", 0.01, 180.0,
                                   read_only=True),
    "external_gate": Spec(5.0, "innovation gate of external samples [σ]", 1.0, 100.0, read_only=True),
    "external_alignment": Spec("estimate", "external frame in map [estimate | configured]", read_only=True),
    "external_yaw_offset_deg": Spec(0.0, "configured yaw of the external frame in map (ENU) [deg]", -180.0, 180.0,
                                    read_only=True),
    "external_origin_m": Spec([0.0, 0.0, 0.0], "configured origin of the external frame in map [m, m, m]",
                              read_only=True),
    "external_fuse_yaw": Spec(False, "fuse the external yaw as a heading measurement (indoors) [bool]",
                              read_only=True),
    "origin_latitude_deg": Spec(math.nan, "configured geodetic origin of map [deg]; NaN: home from GNSS",
                                read_only=True),
    "origin_longitude_deg": Spec(math.nan, "configured geodetic origin of map [deg]; NaN: home from GNSS",
                                 read_only=True),
    "origin_altitude_m": Spec(math.nan, "configured geodetic origin of map, AMSL [m]; NaN: home from GNSS",
                              read_only=True),
    "gnss_integrity_action": Spec("cut", "on a SPOOFED GNSS verdict [cut | monitor]: stop fusing GNSS and undo its "
                                  "corrections since the onset, or only report the verdict", read_only=True),
    "dead_reckoning_valid_s": Spec(3.0, "position kept valid this long after a SPOOFED GNSS cut-off [s]", 0.0, 120.0,
                                   read_only=True),
    "airframe": Spec("quad_x", "airframe whose drag per unit mass is drag fusion's default (ekf.drag_*) "
                     "[bundled name or YAML path]", read_only=True),
    "vehicle": Spec("", "vehicle whose changed ekf.* parameters persist in $XDG_DATA_HOME/c4d/vehicles/<vehicle>/"
                    "navigation.yaml and are restored at start; empty: not persisted [name]", read_only=True),
}
STATUS_PERIOD_S = 0.2  # navigation/status at 5 Hz (+ at once on a change)
STATUS_CHECK_EVERY = 10  # IMU samples between change checks (50 Hz at 500 Hz)
STAMP = struct.Struct("<iI")  # header.stamp right after the 4-byte CDR encapsulation (little endian)
REJECTION_FIELDS = {r: f"external_rejected_{r.value}" for r in Rejection}


def _choice(params: dict, name: str, choices: tuple[str, ...]) -> int:
    value = params[name]
    if value not in choices:
        raise ComponentError(f"parameter '{name}': {value!r} is not one of {', '.join(choices)}")
    return NAMES[value]


def navigation_config(params: dict) -> NavigationConfig:
    """The filter's configuration from the parameters; ComponentError (one line) for a bad value."""
    if params["gnss_input"] not in ("perception", "external"):
        raise ComponentError(f"parameter 'gnss_input': {params['gnss_input']!r} is not one of perception, external")
    if params["external_alignment"] not in ("estimate", "configured"):
        raise ComponentError(f"parameter 'external_alignment': {params['external_alignment']!r} is not one of "
                             "estimate, configured")
    origin_m = list(params["external_origin_m"])
    if len(origin_m) != 3 or not all(math.isfinite(x) for x in origin_m):
        raise ComponentError("parameter 'external_origin_m': needs 3 finite values")
    frames = tuple(params["external_frame_ids"])
    if not frames or not all(frames):
        raise ComponentError("parameter 'external_frame_ids': needs at least one non-empty frame id")
    geo = (params["origin_latitude_deg"], params["origin_longitude_deg"], params["origin_altitude_m"])
    nan = [math.isnan(x) for x in geo]
    if any(nan) and not all(nan):
        raise ComponentError("parameters 'origin_latitude_deg', 'origin_longitude_deg', 'origin_altitude_m': "
                             "all three or none (NaN)")
    if not any(nan) and not (abs(geo[0]) <= 90.0 and abs(geo[1]) <= 180.0 and math.isfinite(geo[2])):
        raise ComponentError(f"parameter 'origin_latitude_deg' / 'origin_longitude_deg': {geo[0]}, {geo[1]} "
                             "outside [-90, 90] / [-180, 180]")
    if params["gnss_integrity_action"] not in ("cut", "monitor"):
        raise ComponentError(f"parameter 'gnss_integrity_action': {params['gnss_integrity_action']!r} is not one of "
                             "cut, monitor")
    h1 = _choice(params, "horizontal_primary", HORIZONTAL_CHOICES)
    h2 = _choice(params, "horizontal_secondary", (*HORIZONTAL_CHOICES, "none"))
    z1 = _choice(params, "height_primary", HEIGHT_CHOICES)
    z2 = _choice(params, "height_secondary", (*HEIGHT_CHOICES, "none"))
    external = ExternalConfig(frame_ids=frames, max_age_s=params["external_max_age_s"],
                              max_rate_hz=params["external_max_rate_hz"],
                              position_sigma_m=params["external_position_sigma_m"],
                              yaw_sigma_rad=math.radians(params["external_yaw_sigma_deg"]))
    return NavigationConfig(
        horizontal_primary=h1, horizontal_secondary=h2 if h2 != h1 else 0, height_primary=z1,
        height_secondary=z2 if z2 != z1 else 0, source_timeout_s=params["source_timeout_s"],
        source_recovery_s=params["source_recovery_s"], switch_blend_s=params["switch_blend_s"], external=external,
        external_gate=params["external_gate"], external_alignment=params["external_alignment"],
        external_yaw_offset=math.radians(params["external_yaw_offset_deg"]),
        external_origin=(origin_m[0], origin_m[1], origin_m[2]), external_fuse_yaw=bool(params["external_fuse_yaw"]),
        origin=None if all(nan) else geo, dead_reckoning_valid_s=params["dead_reckoning_valid_s"],
        integrity_cut=params["gnss_integrity_action"] == "cut")
LOG_PERIOD_S = 5.0
JOURNAL_PERIOD_S = 0.1


def tf_sender(node) -> Callable[[Odometry], None] | None:
    """Publishes an odometry's pose as TF map → base_link on /tf (tf2_msgs/TFMessage, depth 100 as
    tf2_ros' TransformBroadcaster); None, with one info line, where tf2_msgs is not installed
    (the PyPI wheels do not carry it)."""
    try:
        from tf2_msgs.msg import TFMessage
    except ImportError:
        node.get_logger().info("tf2_msgs not installed: no TF map -> base_link (navigation/pose and "
                               "navigation/odometry carry the same pose)")
        return None
    publisher = node.create_publisher(TFMessage, "/tf", 100)

    def send(odometry: Odometry) -> None:
        p, transform = odometry.pose.pose.position, TransformStamped(header=odometry.header,
                                                                     child_frame_id=odometry.child_frame_id)
        transform.transform.translation = Vector3(x=p.x, y=p.y, z=p.z)
        transform.transform.rotation = odometry.pose.pose.orientation
        publisher.publish(TFMessage(transforms=[transform]))
    return send


class NavigationNode:
    """Maps the perception topics onto NavigationFilter and publishes its estimate."""

    def __init__(self, node, odometry_rate_hz: float, mag_declination_deg: float,
                 config: NavigationConfig | None = None, gnss_input: str = "perception",
                 live: LiveParameters | None = None, ekf_base: EkfConfig | None = None) -> None:
        self.node, self.live = node, live
        ekf_cfg = replace(ekf_base or EkfConfig(), mag_declination=math.radians(mag_declination_deg))
        self.filter = NavigationFilter(NavigationEkf(ekf_with(ekf_cfg, live.values) if live else ekf_cfg), config)
        self.ekf = self.filter.ekf
        self.gnss_external = gnss_input == "external"
        self.status_key: tuple[object, ...] | None = None
        self.status_t = -math.inf
        self.logged_verdict = IntegrityState.UNKNOWN  # the GNSS integrity state last logged
        self.imu_stamp = (0, 0)
        self.pub_status = node.create_publisher(EstimatorStatus, NAV_STATUS.name, NAV_STATUS.qos)
        self.odometry_period = 1.0 / odometry_rate_hz - 1e-6
        self.odometry_t = -math.inf
        self.pub_state = node.create_publisher(VehicleState, NAV_STATE.name, NAV_STATE.qos)
        self.pub_odometry = node.create_publisher(Odometry, NAV_ODOMETRY.name, NAV_ODOMETRY.qos)
        self.pub_pose = node.create_publisher(PoseStamped, NAV_POSE.name, NAV_POSE.qos)
        self.send_tf = tf_sender(node)
        # input consumption journal for `resim` (c4d_gnc.journal): batches at 10 Hz, a snapshot at arm
        self.journal, self.params = jr.JournalWriter(), {}
        self.pub_journal = node.create_publisher(UInt8MultiArray, NAV_JOURNAL.name, NAV_JOURNAL.qos)
        node.create_timer(JOURNAL_PERIOD_S, self.flush_journal)
        node.create_timer(LOG_PERIOD_S, self.log_status)
        gc_policy.install(node)  # 500 Hz callbacks: no automatic full collection (c4d_ros.gc_policy)
        node.create_subscription(Imu, P_IMU.name, self.on_imu, P_IMU.qos, raw=True)  # 500 Hz: serialized (c4d_ros.cdr)
        node.create_subscription(NavSatFix, P_GPS.name, lambda m: self.on_gps(m, False), P_GPS.qos)
        node.create_subscription(NavSatFix, EXTERNAL_GNSS.name, lambda m: self.on_gps(m, True), EXTERNAL_GNSS.qos)
        node.create_subscription(Odometry, EXTERNAL_ODOMETRY.name, lambda raw: self.on_external(raw, Odometry),
                                 EXTERNAL_ODOMETRY.qos, raw=True)
        node.create_subscription(PoseWithCovarianceStamped, EXTERNAL_POSE.name,
                                 lambda raw: self.on_external(raw, PoseWithCovarianceStamped), EXTERNAL_POSE.qos, raw=True)
        node.create_subscription(FluidPressure, P_BARO.name, self.on_baro, P_BARO.qos)
        node.create_subscription(MagneticField, P_MAG.name, self.on_mag, P_MAG.qos)
        node.create_subscription(Range, P_RANGE_DOWN.name, self.on_range, P_RANGE_DOWN.qos)
        node.create_subscription(VehicleStatus, STATUS.name, self.on_status, STATUS.qos)

    def flush_journal(self) -> None:
        for payload in self.journal.flush():
            self.pub_journal.publish(UInt8MultiArray(data=array.array("B", payload)))

    def on_status(self, msg: VehicleStatus) -> None:
        if msg.armed and self.filter.on_ground:  # the arm edge: resim's start point
            self.journal.queue_snapshot({"filter": self.filter, "params": self.params})
        self.filter.on_ground = not msg.armed
        self.filter.station_keeping = msg.failsafe_action in (VehicleStatus.FAILSAFE_HOLD, VehicleStatus.FAILSAFE_LAND)
        self.journal.status((0 if self.filter.on_ground else jr.STATUS_ARMED)
                            | (jr.STATUS_STATION_KEEPING if self.filter.station_keeping else 0))

    def on_mag(self, msg: MagneticField) -> None:
        f = msg.magnetic_field
        self.journal.stamp(jr.N_MAG, jr.stamp_ns(msg.header.stamp.sec, msg.header.stamp.nanosec))
        self.filter.magnetometer((f.x, f.y, f.z))

    def on_gps(self, msg: NavSatFix, external: bool) -> None:
        if external != self.gnss_external or msg.status.status < NavSatStatus.STATUS_FIX:
            return
        cov = msg.position_covariance
        self.journal.gnss(external, jr.stamp_ns(msg.header.stamp.sec, msg.header.stamp.nanosec))
        self.filter.gnss(msg.latitude, msg.longitude, msg.altitude, cov[0], cov[8], stamp_to_s(msg.header.stamp))

    def on_external(self, raw: bytes, kind: type) -> None:
        """An external pose: rate-limited on its stamp before deserialising (a 1 kHz flood costs little),
        then validated and fused by the filter; a malformed message is counted as invalid."""
        validator = self.filter.validator
        try:
            sec, nanosec = STAMP.unpack_from(raw, 4)
        except struct.error:
            self.journal.external(int(kind is PoseWithCovarianceStamped), None)
            validator.counts[Rejection.INVALID] += 1
            return
        self.journal.external(int(kind is PoseWithCovarianceStamped), jr.stamp_ns(sec, nanosec))
        if validator.rate_limited(sec + nanosec * 1e-9):
            return
        try:
            msg = deserialize_message(raw, kind)
        except Exception:  # whatever the middleware raises for bytes it cannot read: counted
            validator.counts[Rejection.INVALID] += 1
            return
        pose = msg.pose.pose
        p, o = pose.position, pose.orientation
        self.filter.external(ExternalSample(
            t=stamp_to_s(msg.header.stamp), position=np.array([p.x, p.y, p.z]), quaternion=(o.w, o.x, o.y, o.z),
            covariance=np.asarray(msg.pose.covariance, dtype=float).reshape(6, 6), frame_id=msg.header.frame_id,
            child_frame_id=msg.child_frame_id if kind is Odometry else "base_link"))

    def on_baro(self, msg: FluidPressure) -> None:
        self.journal.stamp(jr.N_BARO, jr.stamp_ns(msg.header.stamp.sec, msg.header.stamp.nanosec))
        self.filter.baro(msg.fluid_pressure, stamp_to_s(msg.header.stamp))

    def on_range(self, msg: Range) -> None:
        self.journal.stamp(jr.N_RANGE, jr.stamp_ns(msg.header.stamp.sec, msg.header.stamp.nanosec))
        self.filter.range_down(msg.range, stamp_to_s(msg.header.stamp))

    def retune(self, t: float) -> None:
        """Live changes validated since the last IMU sample, in force from the sample at `t` on: the
        frozen EkfConfig swapped whole (no update ever sees half a change), journaled before that
        sample's record so `resim` applies them at the same point."""
        changes = self.live.take() if self.live is not None else {}
        if changes:
            self.journal.blob(jr.N_RETUNE, pickle.dumps(changes))
            self.ekf.cfg = ekf_with(self.ekf.cfg, changes)
            self.node.get_logger().info(f"parameters applied at IMU sample t={t:.6f} s: {describe(changes)}")

    def on_imu(self, raw: bytes) -> None:
        v = cdr.IMU.unpack(raw, Imu)
        sec, nanosec = v[1], v[2]
        t = sec + nanosec * 1e-9
        if self.live is not None and self.live.pending.queued:
            self.retune(t)
        self.journal.stamp(jr.N_IMU, sec * 1_000_000_000 + nanosec)
        if self.filter.imu(t, v[cdr.IMU_GYRO], v[cdr.IMU_ACCEL]):
            self.imu_stamp = (sec, nanosec)
            self.pub_state.publish(self.state_cdr(sec, nanosec, t))
            if self.filter.imu_count % STATUS_CHECK_EVERY == 0:
                key = self.filter.status_key()
                if key != self.status_key or t - self.status_t >= STATUS_PERIOD_S:
                    self.log_verdict_change()
                    self.status_key, self.status_t = key, t
                    self.pub_status.publish(self.status_msg())
            if t - self.odometry_t >= self.odometry_period:
                self.odometry_t = t
                odometry = self.odometry_msg(sec, nanosec)
                self.pub_odometry.publish(odometry)
                self.pub_pose.publish(PoseStamped(header=odometry.header, pose=odometry.pose.pose))
                if self.send_tf is not None:
                    self.send_tf(odometry)

    def state_cdr(self, sec: int, nanosec: int, t: float) -> bytes:
        """navigation/state stamped with the IMU sample time, straight to CDR (c4d_gnc.state_wire, shared with resim)."""
        return state_cdr(self.filter, sec, nanosec, t)

    def status_msg(self) -> EstimatorStatus:
        """navigation/status from the filter's status (stamped with the IMU sample time)."""
        s, cfg = self.filter.status(), self.filter.cfg
        msg = EstimatorStatus()
        msg.header.stamp.sec, msg.header.stamp.nanosec = self.imu_stamp
        msg.header.frame_id = "map"
        msg.horizontal_source, msg.height_source = s.horizontal_source, s.height_source
        msg.horizontal_primary, msg.horizontal_secondary = cfg.horizontal_primary, cfg.horizontal_secondary
        msg.height_primary, msg.height_secondary = cfg.height_primary, cfg.height_secondary
        msg.source_switches, msg.last_switch_step_m, msg.last_switch_age_s = (
            s.source_switches, s.last_switch_step_m, s.last_switch_age_s)
        msg.external_healthy, msg.external_aligned = s.external_healthy, s.external_aligned
        msg.external_age_s, msg.external_rate_hz, msg.external_latency_s = (
            s.external_age_s, s.external_rate_hz, s.external_latency_s)
        msg.external_yaw_offset_deg = s.external_yaw_offset_deg
        msg.external_origin = Vector3(x=float(s.external_origin[0]), y=float(s.external_origin[1]),
                                      z=float(s.external_origin[2]))
        msg.external_fused = s.external_fused
        for reason, name in REJECTION_FIELDS.items():
            setattr(msg, name, s.rejected[reason])
        g, v = GnssIntegrity(), s.gnss
        g.state, g.score, g.alarms, g.warnings = int(v.state), v.score, int(v.alarms), int(v.warnings)
        g.innovation_nis, g.jump_m, g.inertial_mismatch_m, g.drift_cusum = (
            v.innovation_nis, v.jump_m, v.inertial_mismatch_m, v.drift_cusum)
        g.external_distance_m, g.fix_rate_hz, g.accuracy_ratio, g.alarm_age_s = (
            v.external_distance_m, v.fix_rate_hz, v.accuracy_ratio, v.alarm_age_s)
        msg.gnss = g
        return msg

    def odometry_msg(self, sec: int, nanosec: int) -> Odometry:
        ekf, odom = self.ekf, Odometry()
        odom.header.stamp.sec, odom.header.stamp.nanosec = sec, nanosec
        odom.header.frame_id, odom.child_frame_id = "map", "base_link"
        p, o = odom.pose.pose.position, odom.pose.pose.orientation
        p.x, p.y, p.z = ekf.p.tolist()
        o.w, o.x, o.y, o.z = ekf.q
        v_body = rotation_matrix(ekf.q).T @ ekf.v  # Odometry twist is in the child (body) frame
        odom.twist.twist.linear.x, odom.twist.twist.linear.y, odom.twist.twist.linear.z = v_body.tolist()
        odom.twist.twist.angular.x, odom.twist.twist.angular.y, odom.twist.twist.angular.z = self.filter.omega.tolist()
        cov = np.zeros((6, 6))
        cov[0:3, 0:3], cov[3:6, 3:6] = ekf.P[0:3, 0:3], ekf.P[6:9, 6:9]
        odom.pose.covariance = cov.ravel().tolist()
        return odom

    def log_verdict_change(self) -> None:
        """One line per GNSS integrity state change, with the tests in alarm and their statistics."""
        v = self.filter.verdict
        alarm = IntegrityState.SPOOFED, IntegrityState.JAMMED
        if v.state == self.logged_verdict or (v.state not in alarm and self.logged_verdict not in alarm):
            return  # OK <-> SUSPECT flicker in nominal flight is not logged (navigation/status carries it)
        self.logged_verdict = v.state
        text = (f"GNSS integrity {v.state.name} (alarms {v.alarms!r}, warnings {v.warnings!r}, score {v.score:.2f}; "
                f"nis {v.innovation_nis:.1f}, jump {v.jump_m:.2f} m, inertial {v.inertial_mismatch_m:.2f} m, cusum "
                f"{v.drift_cusum:.2f}, external {v.external_distance_m:.2f} m, rate {v.fix_rate_hz:.1f} Hz, "
                f"accuracy x{v.accuracy_ratio:.1f})")
        if v.state in (IntegrityState.SPOOFED, IntegrityState.JAMMED):  # one call site per severity (rclpy's rule)
            self.node.get_logger().warning(text)
        else:
            self.node.get_logger().info(text)

    def log_status(self) -> None:
        ekf = self.ekf
        self.node.get_logger().info(
            f"aligned {ekf.aligned}, home {'set' if ekf.origin else 'pending'}, position valid {ekf.position_valid}, "
            f"heading valid {ekf.heading_valid}, rejected {ekf.rejected}, p = {[round(float(x), 2) for x in ekf.p]}, "
            f"sources {self.filter.status_key()}")


def component(rclpy, host: Host) -> lifecycle.ManagedComponent:
    """The navigation node as a component (c4d_ros.component): alone or composed with others."""
    node = lifecycle.create_node(rclpy, NAME)
    try:
        params = declare_all(node, PARAMS)
    except ParameterError as exc:
        node.destroy_node()
        raise ComponentError(str(exc)) from None

    def build() -> SpunNode:  # configure (c4d_ros.lifecycle): the EKF configuration loaded and checked, entities created
        try:
            ekf_base = drag_config(airframe_by_ref(params["airframe"]))
            store = VehicleStore.of(params["vehicle"], NAME) if params["vehicle"] else None
            live = LiveParameters(node, navigation_table(ekf_base), store, node.get_logger().info)
        except (TunableError, ParameterError, AirframeError) as exc:
            raise ComponentError(f"parameter 'airframe': {exc}" if isinstance(exc, AirframeError) else str(exc)) from None
        owner = NavigationNode(node, params["odometry_rate_hz"], params["mag_declination_deg"], navigation_config(params),
                               params["gnss_input"], live, ekf_base)
        owner.params = {name: (value, PARAMS[name].low, PARAMS[name].high) for name, value in params.items()}
        return SpunNode(NAME, node, bool(params["events_executor"]), params["rt_priority"], owner)
    return lifecycle.ManagedComponent(NAME, node, build, events_executor=bool(params["events_executor"]),
                                      rt_priority=params["rt_priority"])


def main(argv: list[str] | None = None) -> int:
    return run_components([(NAME, component)], argv, NAME, composed=False)


if __name__ == "__main__":
    sys.exit(main())

