"""`ros2 run c4d_bridge_mavlink bridge` — MAVLink 2 ground-station bridge (communication block).

One loop, one thread: poll the MAVLink endpoints (Router), hand protocol messages to the mission,
parameter and command handlers, release telemetry frames from one GCD+-phased scheduler per
endpoint, and take ROS work with a zero-timeout spin. The 500 Hz vehicle state is sampled
(LatestSampler), not spun. Every MAVLink action goes through the same ROS services a c4d tool
would use (vehicle/command, mission/upload, mission/control, <node>/set_parameters), so the
bridge adds no authority of its own.

MANUAL_CONTROL (pilot sticks) becomes an ATTITUDE / RATE-level guidance/setpoint while the core is
in that mode (manual.py). Parameters: PARAMETERS below (endpoints, sysid, airframe, udp_rate_bytes_s,
config, param_file, signing_key_file; all read-only: they are taken at start).
Topics out: bridge/gcs_heartbeat (std_msgs/Header per GCS heartbeat; health's link_topic),
bridge/link_stats (diagnostic_msgs/DiagnosticArray, 1 Hz).
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from c4d_common import quat
from c4d_common.airframe import AirframeError, default_airframe_path, load_airframe
from c4d_common.share import share_file
from c4d_ros import lifecycle
from c4d_ros.component import ComponentError, Host, run_components
from c4d_ros.params import ParameterError, Spec, declare_all

from . import encoders as enc
from .bridge_ros import RosSide
from .commands import Action, Context, Kind, translate, translate_set_mode
from .external_inputs import MESSAGES as EXTERNAL_MESSAGES
from .external_inputs import Clocks, ExternalInputs, GnssSample, OdometrySample
from .link_monitor import LinkMonitor
from .manual import PilotInput
from .mission_protocol import MissionServer
from .offboard import OffboardDecoder, VehicleFrame
from .params import ParamServer
from .signing import SigningConfig, mavlink
from .telemetry import LinkBudget, TelemetryScheduler
from .transport import Received, Router, parse_endpoint_url

M = mavlink


def default_config() -> Path:
    """The installed config/bridge.yaml of c4d_bridge_mavlink (the source tree's copy when not installed)."""
    return share_file("c4d_bridge_mavlink", "config", "bridge.yaml")


def load_streams(path: Path) -> dict[int, int]:
    """Stream intervals from the config: {MESSAGE_NAME: rate_hz} → {msg_id: interval_us}."""
    try:
        doc = yaml.safe_load(path.read_text()) or {}
    except (OSError, yaml.YAMLError) as exc:
        raise ValueError(f"config {path}: {exc.__class__.__name__}") from None
    streams = doc.get("streams") if isinstance(doc, dict) else None
    if not isinstance(streams, dict) or not streams:
        raise ValueError(f"config {path}: 'streams' must map message names to rates in Hz")
    out = {}
    for name, hz in streams.items():
        msg_id = getattr(M, f"MAVLINK_MSG_ID_{name}", None)
        if msg_id is None or name not in STREAM_ENCODERS:
            raise ValueError(f"config {path}: unknown telemetry stream '{name}'")
        if isinstance(hz, bool) or not isinstance(hz, int | float) or not 0 <= hz <= 100:
            raise ValueError(f"config {path}: stream {name} rate must be in [0, 100] Hz")
        out[msg_id] = int(round(1e6 / hz)) if hz > 0 else -1
    return out


STREAM_ENCODERS = {
    "HEARTBEAT": lambda s, now: enc.heartbeat(s), "SYS_STATUS": lambda s, now: enc.sys_status(s),
    "BATTERY_STATUS": lambda s, now: enc.battery_status(s), "ATTITUDE": enc.attitude,
    "ATTITUDE_QUATERNION": enc.attitude_quaternion, "GLOBAL_POSITION_INT": enc.global_position_int,
    "LOCAL_POSITION_NED": enc.local_position_ned, "GPS_RAW_INT": enc.gps_raw_int, "VFR_HUD": lambda s, now: enc.vfr_hud(s),
    "HOME_POSITION": enc.home_position, "EXTENDED_SYS_STATE": lambda s, now: enc.extended_sys_state(s),
    "MISSION_CURRENT": lambda s, now: enc.mission_current(s), "POSITION_TARGET_LOCAL_NED": enc.position_target,
    "FENCE_STATUS": enc.fence_status, "OBSTACLE_DISTANCE": enc.obstacle_distances,
    "ESTIMATOR_STATUS": enc.estimator_status,
}


PARAMETERS: dict[str, Spec] = {
    "endpoints": Spec(["udpin:127.0.0.1:14550"], "MAVLink endpoints, each udpin:[HOST:]PORT, udpout:HOST:PORT or "
                      "serial:DEVICE:BAUD [URL list]", read_only=True),
    "sysid": Spec(0, "MAVLink system id of the vehicle; 0 = the SYSID_THISMAV parameter [id]", 0, 255, read_only=True),
    "airframe": Spec("quad_x", "airframe whose hover command is the centre of the pilot's thrust stick [name]", read_only=True),
    "udp_rate_bytes_s": Spec(100_000, "UDP link budget of the telemetry scheduler [bytes/s]", 1000, 1_000_000_000,
                             read_only=True),
    "config": Spec("", "telemetry stream rates YAML; '' = the installed config/bridge.yaml [path]", read_only=True,
                   empty=default_config),
    "param_file": Spec("", "YAML file the MAVLink parameters of this vehicle persist in; '' = not persisted. Per vehicle, "
                           "never one shared per-user file: `c4d up` gives each run ${run}/bridge/params.yaml [path]",
                       read_only=True),
    "signing_key_file": Spec("", "MAVLink 2 signing key file; '' = signing off [path]", read_only=True),
    "external_frame_id": Spec("odom", "frame_id of navigation/external/{pose,odometry} made from MAVLink "
                              "VISION_POSITION_ESTIMATE / ATT_POS_MOCAP / ODOMETRY (one of the navigation's "
                              "external_frame_ids) [name]", read_only=True),
    "external_max_rate_hz": Spec(250.0, "MAVLink position inputs forwarded per message and sender at most at this rate; "
                                 "the excess is dropped and counted [Hz]", 1.0, 1000.0, read_only=True),
    "external_max_age_s": Spec(0.5, "MAVLink position inputs whose sample is older than this at arrival are dropped "
                               "and counted [s]", 0.01, 10.0, read_only=True),
}


class SettingsError(ValueError):
    """The bridge cannot start with this configuration (one line)."""


@dataclass(frozen=True)
class BridgeSettings:
    """The checked start configuration of the bridge (from PARAMETERS and the files they name)."""

    urls: tuple[str, ...]
    sysid: int  # 0 = SYSID_THISMAV
    udp_rate: int  # [bytes/s]
    streams: dict[int, int]  # msg_id → interval [us] (-1 = off)
    param_file: Path | None
    signing: SigningConfig | None
    hover: float  # the airframe's hover command: centre of the thrust stick
    external_frame_id: str = "odom"  # frame_id of the external pose / odometry made from MAVLink
    external_max_rate_hz: float = 250.0  # [Hz] per message and sender
    external_max_age_s: float = 0.5  # [s]

    @classmethod
    def from_parameters(cls, values: dict[str, Any]) -> BridgeSettings:
        """Settings from the declared parameter values; SettingsError names what is unusable."""
        urls, config, key_file = tuple(values["endpoints"]), values["config"], values["signing_key_file"]
        try:
            streams = load_streams(Path(config) if config else default_config())
            signing = SigningConfig.from_file(key_file) if key_file else None
            for url in urls:
                parse_endpoint_url(url)
        except ValueError as exc:  # SigningError is one
            raise SettingsError(str(exc)) from None
        try:
            hover = load_airframe(default_airframe_path(values["airframe"])).hover_command
        except (AirframeError, OSError) as exc:
            raise SettingsError(f"airframe '{values['airframe']}': {exc}") from None
        param_file = values["param_file"]
        if not values["external_frame_id"].strip():
            raise SettingsError("external_frame_id must not be empty")
        return cls(urls, values["sysid"], values["udp_rate_bytes_s"], streams, Path(param_file) if param_file else None,
                   signing, hover, values["external_frame_id"].strip(), values["external_max_rate_hz"],
                   values["external_max_age_s"])


class BridgeNode:
    """The bridge loop's parts and one step of it: MAVLink in → protocol servers / ROS services,
    telemetry out on every endpoint's scheduler, ROS topics into the snapshot, link statistics."""

    def __init__(self, node, settings: BridgeSettings) -> None:
        self.ros = RosSide(node)
        self.snap = self.ros.snapshot
        self.params = ParamServer(self._send, settings.param_file, apply=self.ros.set_node_parameters,
                                  on_refused=lambda text: self.ros.statustext(M.MAV_SEVERITY_WARNING, text))
        for problem in self.params.load_errors:
            node.get_logger().warning(problem)
        node.get_logger().info(f"bridge: MAVLink parameters persist in {settings.param_file}" if settings.param_file
                               else "bridge: MAVLink parameters are not persisted (param_file '')")
        self.sysid = settings.sysid or int(self.params.get("SYSID_THISMAV"))
        try:
            self.router = Router(list(settings.urls), sysid=self.sysid, signing=settings.signing)
        except ValueError as exc:
            self.ros.executor.shutdown()  # before the context goes: no traceback from its finalizer
            raise SettingsError(str(exc)) from None
        self.monitor = LinkMonitor(self.params.get("COM_DL_LOSS_T"))
        self.missions = MissionServer(self._send, on_upload=self.ros.upload_mission, on_clear=self.ros.clear_mission,
                                      on_set_current=self.ros.set_current_item)
        self.ros.bind(self.router, self.missions, self.params)
        self.pilot = PilotInput(settings.hover)
        self.offboard = OffboardDecoder(self.sysid, self.router.compid)
        self.external = ExternalInputs(self.sysid, self.router.compid, settings.external_max_rate_hz,
                                       settings.external_max_age_s)
        self.ros.external_frame_id = settings.external_frame_id
        self.schedulers = self._schedulers(settings, time.monotonic())
        self.last_stats = 0.0
        node.get_logger().info(f"bridge: sysid {self.sysid}, endpoints {', '.join(settings.urls)}, "
                               f"{len(settings.streams)} telemetry streams{', signing on' if settings.signing else ''}")

    def _send(self, msg) -> None:
        self.router.send(msg)

    def _schedulers(self, settings: BridgeSettings, now: float) -> dict[str, TelemetryScheduler]:
        """One telemetry scheduler per endpoint, budgeted by its link (serial baud rate or the UDP budget)."""
        schedulers: dict[str, TelemetryScheduler] = {}
        for name, endpoint in self.router.endpoints.items():
            url = parse_endpoint_url(name)
            budget = LinkBudget.serial(url.number) if url.kind == "serial" else LinkBudget.udp(settings.udp_rate)
            sched = TelemetryScheduler(budget, pack=endpoint.pack, signed=settings.signing is not None, queue_bytes=2048)
            for msg_id, interval in settings.streams.items():
                encode = STREAM_ENCODERS[M.mavlink_map[msg_id].msgname]
                sched.add_stream(msg_id, interval, lambda e=encode: e(self.snap, time.monotonic()))
            sched.start(now)
            schedulers[name] = sched
        return schedulers

    # c4d_ros.component protocol: the bridge spins its own node (a private executor, spin_once(0)
    # per step) and polls its sockets, so a shared process's executor does not spin it
    name = "bridge"
    nodes: tuple = ()
    events_executor = False
    rt_priority = 0
    period_s = 0.004  # [s] socket poll and telemetry granularity

    def close(self) -> int:
        """Close the endpoints and the ROS side (its executor and node; the rclpy context is the runner's)."""
        self.router.close()
        self.ros.shutdown()
        return 0

    def idle(self, budget_s: float) -> None:
        """Inactive (c4d_ros.lifecycle): ROS callbacks and services only; no MAVLink in or out."""
        self.ros.spin_once()
        if budget_s > 0:
            time.sleep(budget_s)

    def release(self) -> None:
        """Lifecycle cleanup: the endpoints closed and the private executor stopped; the node stays."""
        self.router.close()
        self.ros.executor.shutdown()

    def step(self, budget_s: float = 0.004) -> None:
        """One loop pass: ROS callbacks, MAVLink input (waiting at most `budget_s` for it, less when a
        telemetry frame is due sooner), telemetry out, protocol time-outs, link statistics."""
        self.ros.spin_once()
        now = time.monotonic()
        wait = min([max(0.0, s.next_event() - now) for s in self.schedulers.values()] + [budget_s])
        for received in self.router.poll(wait):
            self.on_message(received)
        now = time.monotonic()
        for name, sched in self.schedulers.items():
            for frame in sched.advance(now):
                self.router.endpoints[name].write(frame.data)
        self.missions.poll(now)
        self.ros.tick(now)
        if now - self.last_stats >= 1.0:
            self.last_stats = now
            self.ros.publish_link_stats(self.router, self.schedulers, self.monitor.status(now), now, self.offboard,
                                        self.external)
            self.monitor.timeout_s = self.params.get("COM_DL_LOSS_T")
            for line in self.external.take_warnings(now):
                self.ros.node.get_logger().warning(line)
                self.ros.statustext(M.MAV_SEVERITY_WARNING, line)
            request = self.external.timesync_request(now)
            if request is not None:
                self.router.send(request)

    def on_message(self, received: Received) -> None:
        self.monitor.observe(received, time.monotonic())
        msg, kind = received.message, received.message.get_type()
        if kind in EXTERNAL_MESSAGES:
            self.on_external(msg)
        elif kind == "HEARTBEAT" and msg.type == M.MAV_TYPE_GCS:
            self.external.note_gcs(msg.get_srcSystem())
            self.ros.gcs_heartbeat()
        elif kind == "TIMESYNC":
            reply = self.external.on_timesync(msg, time.monotonic())
            if reply is not None:
                self.router.send(reply)
        elif kind.startswith("MISSION_"):
            self.missions.handle(msg, time.monotonic())
        elif kind.startswith("PARAM_"):
            self.params.handle(msg)
        elif kind in ("COMMAND_LONG", "COMMAND_INT"):
            self.on_command(msg)
        elif kind in OffboardDecoder.MESSAGES:
            self.on_offboard(msg)
        elif kind == "SET_MODE" and msg.target_system == self.sysid:
            self.execute(translate_set_mode(msg, self.context()),
                         lambda result, reason="": self.ros.ack(msg, result, reason, M.MAV_CMD_DO_SET_MODE))
        elif kind == "MANUAL_CONTROL" and msg.target == self.sysid:
            sp = self.pilot.setpoint(msg.x, msg.y, msg.z, msg.r, self.snap.flight_mode, self.snap.orientation,
                                     time.monotonic())
            if sp is not None:
                self.ros.publish_pilot(sp)

    def on_external(self, msg) -> None:
        """VISION_POSITION_ESTIMATE / ATT_POS_MOCAP / ODOMETRY / GPS_INPUT → navigation/external/*
        (external_inputs.py converts, stamps, validates and counts)."""
        sample = self.external.handle(msg, Clocks(time.monotonic(), time.time(), self.ros.ros_now()))
        if sample is None:
            return
        if isinstance(sample, GnssSample):
            self.ros.publish_external_gnss(sample)
        elif isinstance(sample, OdometrySample):
            self.ros.publish_external_odometry(sample)
        else:
            self.ros.publish_external_pose(sample)

    def on_offboard(self, msg) -> None:
        """SET_POSITION_TARGET_* / SET_ATTITUDE_TARGET → offboard/trajectory_setpoint (offboard.py);
        a dropped frame is counted there, each kind of drop announced once as STATUSTEXT."""
        snap = self.snap
        yaw = quat.yaw_of(snap.orientation) if snap.orientation is not None else math.nan
        position = snap.position if snap.valid_position else (math.nan, math.nan, math.nan)
        target = self.offboard.decode(msg, VehicleFrame(position, yaw, snap.home))
        if target is not None:
            self.ros.publish_offboard(target)
        for text in self.offboard.take_warnings():
            self.ros.statustext(M.MAV_SEVERITY_WARNING, text)

    def context(self) -> Context:
        snap = self.snap
        return Context(snap.home, self.params.get("MIS_TAKEOFF_ALT"), snap.mission_state == M.MISSION_STATE_ACTIVE)

    def on_command(self, msg) -> None:
        """COMMAND_LONG / COMMAND_INT: translate, execute, COMMAND_ACK (commands.py)."""
        self.execute(translate(msg, self.context()), lambda result, reason="": self.ros.ack(msg, result, reason))

    def execute(self, action: Action, ack) -> None:
        """Carry out a translated command; `ack(result, reason)` answers the GCS."""
        if action.kind == Kind.ACK:
            ack(action.result, action.reason)
        elif action.kind == Kind.VEHICLE:
            self.ros.vehicle_command(action.fields, ack)
        elif action.kind == Kind.MISSION:
            self.ros.mission_control(action.fields, ack)
        elif action.kind == Kind.INTERVAL:
            try:
                for sched in self.schedulers.values():
                    sched.set_interval(action.fields["msg_id"], action.fields["interval_us"], time.monotonic())
                ack(M.MAV_RESULT_ACCEPTED)
            except ValueError as exc:
                ack(M.MAV_RESULT_DENIED, str(exc))
        elif action.kind == Kind.REQUEST:
            msg_id = action.fields["msg_id"]
            reply = self.one_shot(msg_id)
            # without a STATUSTEXT: GCSs probe many optional messages; no log noise for each. A message
            # we send once its data exists (HOME_POSITION before home is set) is TEMPORARILY_REJECTED
            ack(M.MAV_RESULT_ACCEPTED if reply is not None else
                M.MAV_RESULT_TEMPORARILY_REJECTED if self.can_send(msg_id) else M.MAV_RESULT_DENIED)
            if reply is not None:
                self.router.send(reply)

    @staticmethod
    def can_send(msg_id: int) -> bool:
        """True for a message the bridge sends when it has the data (a telemetry stream's)."""
        return msg_id in M.mavlink_map and M.mavlink_map[msg_id].msgname in STREAM_ENCODERS

    def one_shot(self, msg_id: int):
        """The reply to REQUEST_MESSAGE for `msg_id`, or None when it cannot be sent."""
        if msg_id == M.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
            return enc.autopilot_version(self.sysid)
        if msg_id == M.MAVLINK_MSG_ID_MESSAGE_INTERVAL:
            return None
        name = M.mavlink_map[msg_id].msgname if msg_id in M.mavlink_map else ""
        encode = STREAM_ENCODERS.get(name)
        return encode(self.snap, time.monotonic()) if encode else None


def component(rclpy, host: Host) -> lifecycle.ManagedComponent:
    """The bridge as a component (c4d_ros.component): alone (its step waits on the sockets) or
    composed with others (stepped every 4 ms by the shared loop, without waiting)."""
    node = lifecycle.create_node(rclpy, "bridge")
    try:
        settings = BridgeSettings.from_parameters(declare_all(node, PARAMETERS))
    except (ParameterError, SettingsError) as exc:
        node.destroy_node()
        raise ComponentError(str(exc)) from None

    def build() -> BridgeNode:  # configure (c4d_ros.lifecycle): parameter file, endpoints opened, ROS side
        try:
            return BridgeNode(node, settings)
        except SettingsError as exc:
            raise ComponentError(str(exc)) from None
    return lifecycle.ManagedComponent("bridge", node, build, period_s=BridgeNode.period_s, spun=False)


def main(argv: list[str] | None = None) -> int:
    return run_components([("bridge", component)], argv, "bridge", composed=False)


if __name__ == "__main__":
    sys.exit(main())
