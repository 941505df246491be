"""`ros2 run c4d_bridge_mavlink bridge` — MAVLink 2 ground-station bridge (communication block).

One loop, one thread: poll the MAVLink endpoints (Router), hand protocol messages to the mission,
parameter and command handlers, release telemetry frames from one GCD+-phased scheduler per
endpoint, and take ROS work with a zero-timeout spin. The 500 Hz vehicle state is sampled
(LatestSampler), not spun. Every MAVLink action goes through the same ROS services a c4d tool
would use (vehicle/command, mission/upload, mission/control, <node>/set_parameters), so the
bridge adds no authority of its own.

MANUAL_CONTROL (pilot sticks) becomes an ATTITUDE / RATE-level guidance/setpoint while the core is
in that mode (manual.py). Parameters: endpoints (["udpin:127.0.0.1:14550"]), sysid (0 = SYSID_THISMAV),
airframe (quad_x: the thrust stick's centre is its hover command), udp_rate_bytes_s
(UDP link budget for the telemetry scheduler), config (stream intervals YAML), param_file
(persisted MAVLink parameters), signing_key_file ("" = signing off).
Topics out: bridge/gcs_heartbeat (std_msgs/Header per GCS heartbeat; health's link_topic),
bridge/link_stats (diagnostic_msgs/DiagnosticArray, 1 Hz).
"""

from __future__ import annotations

import signal
import sys
import time
from pathlib import Path

import yaml

from c4d_common.share import share_file

from . import encoders as enc
from .bridge_ros import RosSide
from .commands import Context, translate
from .link_monitor import LinkMonitor
from .mission_protocol import MissionServer
from .params import ParamServer
from .signing import SigningConfig, SigningError, mavlink
from .telemetry import LinkBudget, TelemetryScheduler
from .transport import Router, parse_endpoint_url

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
    "MISSION_CURRENT": lambda s, now: enc.mission_current(s),
}


def main(argv: list[str] | None = None) -> int:
    from c4d_ros import node_runtime

    rclpy = node_runtime.init(argv)
    node = rclpy.create_node("bridge")
    urls = list(node.declare_parameter("endpoints", ["udpin:127.0.0.1:14550"]).value)
    sysid_param = int(node.declare_parameter("sysid", 0).value)
    udp_rate = int(node.declare_parameter("udp_rate_bytes_s", 100_000).value)
    config = node.declare_parameter("config", "").value
    param_file = node.declare_parameter("param_file", str(Path.home() / ".local/share/c4d/bridge_params.yaml")).value
    key_file = node.declare_parameter("signing_key_file", "").value
    try:
        streams = load_streams(Path(config) if config else default_config())
        signing = SigningConfig.from_file(key_file) if key_file else None
        for url in urls:
            parse_endpoint_url(url)
        if udp_rate < 1000:
            raise ValueError("udp_rate_bytes_s must be >= 1000")
    except (ValueError, SigningError) as exc:
        return node_runtime.fail("bridge", str(exc), node)
    airframe = node.declare_parameter("airframe", "quad_x").value
    try:
        from c4d_common.airframe import AirframeError, default_airframe_path, load_airframe

        hover = load_airframe(default_airframe_path(airframe)).hover_command  # centre of the pilot's thrust stick
    except (AirframeError, OSError) as exc:
        return node_runtime.fail("bridge", f"airframe '{airframe}': {exc}", node)
    ros = RosSide(node)
    params = ParamServer(lambda m: router.send(m), Path(param_file) if param_file else None, apply=ros.set_node_parameter)
    for problem in params.load_errors:
        node.get_logger().warning(problem)
    sysid = sysid_param or int(params.get("SYSID_THISMAV"))
    try:
        router = Router(urls, sysid=sysid, signing=signing)
    except ValueError as exc:
        return node_runtime.fail("bridge", str(exc), node)
    snap = ros.snapshot
    monitor = LinkMonitor(params.get("COM_DL_LOSS_T"))
    missions = MissionServer(lambda m: router.send(m), on_upload=ros.upload_mission, on_clear=ros.clear_mission,
                             on_set_current=ros.set_current_item)
    ros.bind(router, missions, params)
    schedulers: dict[str, TelemetryScheduler] = {}
    now = time.monotonic()
    for name, endpoint in router.endpoints.items():
        url = parse_endpoint_url(name)
        budget = LinkBudget.serial(url.number) if url.kind == "serial" else LinkBudget.udp(udp_rate)
        sched = TelemetryScheduler(budget, pack=endpoint.pack, signed=signing is not None, queue_bytes=2048)
        for msg_id, interval in streams.items():
            encode = STREAM_ENCODERS[M.mavlink_map[msg_id].msgname]
            sched.add_stream(msg_id, interval, lambda e=encode: e(snap, time.monotonic()))
        sched.start(now)
        schedulers[name] = sched
    stopping: list[int] = []
    signal.signal(signal.SIGINT, lambda s, f: stopping.append(s))
    signal.signal(signal.SIGTERM, lambda s, f: stopping.append(s))
    node.get_logger().info(f"bridge: sysid {sysid}, endpoints {', '.join(urls)}, {len(streams)} telemetry streams"
                           f"{', signing on' if signing else ''}")

    def handle_command(msg) -> None:
        action = translate(msg, Context(snap.home, params.get("MIS_TAKEOFF_ALT"), snap.mission_state == 3))
        ack = lambda result, reason="": ros.ack(msg, result, reason)  # noqa: E731
        if action.kind == "ack":
            ack(action.result, action.reason)
        elif action.kind == "vehicle":
            ros.vehicle_command(action.fields, ack)
        elif action.kind == "mission":
            ros.mission_control(action.fields, ack)
        elif action.kind == "interval":
            try:
                for sched in schedulers.values():
                    sched.set_interval(action.fields["msg_id"], action.fields["interval_us"], time.monotonic())
                ack(M.MAV_RESULT_ACCEPTED)
            except ValueError as exc:
                ack(M.MAV_RESULT_DENIED, str(exc))
        elif action.kind == "request":
            reply = one_shot(action.fields["msg_id"])
            # DENIED without a STATUSTEXT: GCSs probe many optional messages; no log noise for each
            ack(M.MAV_RESULT_ACCEPTED if reply is not None else M.MAV_RESULT_DENIED)
            if reply is not None:
                router.send(reply)

    def one_shot(msg_id: int):
        if msg_id == M.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
            return enc.autopilot_version(sysid)
        if msg_id == M.MAVLINK_MSG_ID_MESSAGE_INTERVAL:
            return None
        name = M.mavlink_map[msg_id].msgname if msg_id in M.mavlink_map else ""
        encode = STREAM_ENCODERS.get(name)
        return encode(snap, time.monotonic()) if encode else None

    last_stats = 0.0
    try:
        while not stopping and rclpy.ok():
            ros.spin_once()
            now = time.monotonic()
            wait = min([max(0.0, s.next_event() - now) for s in schedulers.values()] + [0.004])
            for received in router.poll(wait):
                monitor.observe(received, time.monotonic())
                msg, kind = received.message, received.message.get_type()
                if kind == "HEARTBEAT" and msg.type == M.MAV_TYPE_GCS:
                    ros.gcs_heartbeat()
                elif kind.startswith("MISSION_"):
                    missions.handle(msg, time.monotonic())
                elif kind.startswith("PARAM_"):
                    params.handle(msg)
                elif kind in ("COMMAND_LONG", "COMMAND_INT"):
                    handle_command(msg)
                elif kind == "MANUAL_CONTROL" and msg.target == sysid:
                    ros.manual_control(msg, time.monotonic(), hover)
            now = time.monotonic()
            for name, sched in schedulers.items():
                for frame in sched.advance(now):
                    router.endpoints[name].write(frame.data)
            missions.poll(now)
            ros.tick(now)
            if now - last_stats >= 1.0:
                last_stats = now
                ros.publish_link_stats(router, schedulers, monitor.status(now), now)
                monitor.timeout_s = params.get("COM_DL_LOSS_T")
    finally:
        router.close()
        ros.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())

