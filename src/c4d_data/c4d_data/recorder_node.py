"""`ros2 run c4d_data recorder` — flight recorder: every topic (or an include/exclude selection)
as serialized CDR into one rosbag2-compatible MCAP file per flight.

Thin ROS adapter around recording.Recorder. Topics are discovered every `discovery_period_s`
(late topics join the open file); each is subscribed raw (no deserialisation) with the QoS that
matches all its publishers (qos.request_for_offers) and a deep history (`queue_depth`), and is
drained with non-blocking takes every `drain_period_s` — DDS timestamps (received, source) and
the publisher's sequence number go into the file, so processing delay never shifts log times.
The arm edge of `vehicle/status` starts a file, the disarm edge ends it; `recorder/start` and
`recorder/stop` (std_srvs/Trigger) do it by hand. `recorder/status` (DiagnosticStatus,
latched, 1 Hz and on change) reports state, file, written and dropped counts, errors.
Runs in its own process at a lower priority (`niceness`): it can drop (and count), never block.
"""

from __future__ import annotations

import importlib
import os
import re
import signal
import sys
import time
from pathlib import Path

from .msgdef import DefinitionCache, DefinitionError
from .qos import TRANSIENT_LOCAL, profile_dict, request_for_offers
from .recording import IDLE, Recorder, RecorderConfig, TopicInfo


def message_class(type_name: str):
    """Python class of 'pkg/msg/Type', or None if that package is not installed."""
    try:
        package, namespace, name = type_name.split("/")
        return getattr(importlib.import_module(f"{package}.{namespace}"), name)
    except (ValueError, ImportError, AttributeError):
        return None


def main(argv: list[str] | None = None) -> int:
    from c4d_ros import node_runtime
    from c4d_ros.drain import Drainer

    rclpy = node_runtime.init(argv)
    from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.serialization import deserialize_message
    from std_srvs.srv import Trigger

    from c4d_interfaces.msg import VehicleStatus

    node = rclpy.create_node("recorder")
    p = {name: node.declare_parameter(name, default).value for name, default in (
        ("output_dir", "flights"), ("prefix", "flight"), ("include", [""]), ("exclude", [""]),
        ("auto_arm", True), ("status_topic", "vehicle/status"), ("pre_roll_s", 1.0), ("post_roll_s", 1.0),
        ("max_queue_messages", 200000), ("max_queue_bytes", 256 << 20), ("chunk_size", 1 << 20),
        ("max_chunk_age_s", 1.0), ("compression", "zstd"), ("fsync", False), ("queue_depth", 5000),
        ("discovery_period_s", 0.5), ("drain_period_s", 0.005), ("niceness", 5))}
    try:
        include = [re.compile(x) for x in p["include"] if x]
        exclude = [re.compile(x) for x in p["exclude"] if x]
        if p["compression"] not in ("zstd", "lz4", "none"):
            raise ValueError(f"compression must be zstd, lz4 or none, not {p['compression']!r}")
        if p["queue_depth"] < 1 or p["max_queue_messages"] < 1 or p["drain_period_s"] <= 0:
            raise ValueError("queue_depth, max_queue_messages and drain_period_s must be positive")
        output_dir = Path(p["output_dir"]).expanduser()
        output_dir.mkdir(parents=True, exist_ok=True)
        if not os.access(output_dir, os.W_OK):
            raise ValueError(f"output_dir {output_dir} is not writable")
    except (re.error, ValueError, OSError) as exc:
        return node_runtime.fail("recorder", str(exc), node)
    if p["niceness"]:
        os.nice(int(p["niceness"]))
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a file-size limit must surface as EFBIG, not kill us
    logger = node.get_logger()

    def log(level: str, text: str) -> None:  # one call site per severity (rclpy's logger insists)
        if level == "info":
            logger.info(text)
        elif level == "warn":
            logger.warning(text)
        else:
            logger.error(text)
            print(f"recorder: error: {text}", file=sys.stderr, flush=True)

    config = RecorderConfig(output_dir, p["prefix"], p["pre_roll_s"], p["post_roll_s"], p["max_queue_messages"],
                            p["max_queue_bytes"], p["chunk_size"], p["max_chunk_age_s"], p["compression"], p["fsync"])
    recorder = Recorder(config, log)
    definitions = DefinitionCache()
    status_topic = node.resolve_topic_name(p["status_topic"])
    subs: dict[str, object] = {}  # topic -> subscription
    recorded: set[str] = set()
    ignored: set[str] = set()

    def wanted(name: str) -> bool:
        return (not include or any(r.search(name) for r in include)) and not any(r.search(name) for r in exclude)

    def discover() -> None:
        for name, types in node.get_topic_names_and_types():
            if name in subs or name in ignored:
                continue
            record = wanted(name)
            if not record and name != status_topic:
                ignored.add(name)
                continue
            offers = [i for i in node.get_publishers_info_by_topic(name)]
            if not offers:
                continue  # QoS is chosen from the publishers: wait for one
            if len(types) != 1:
                log("warn", f"topic {name} has several types {types}: not recorded")
                ignored.add(name)
                continue
            cls = message_class(types[0])
            if cls is None:
                log("warn", f"topic {name}: type {types[0]} is not installed here: not recorded")
                ignored.add(name)
                continue
            profiles = [i.qos_profile for i in offers]
            reliability, durability = request_for_offers(profiles)
            if record:
                try:
                    definition = definitions.get(types[0])
                except DefinitionError as exc:
                    log("warn", f"topic {name}: {exc}: not recorded")
                    record = False
                else:
                    recorder.add_topic(TopicInfo(name, types[0], definition, [profile_dict(q) for q in profiles],
                                                 str(offers[0].topic_type_hash), durability == TRANSIENT_LOCAL))
                    recorded.add(name)
            qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=p["queue_depth"],
                             reliability=ReliabilityPolicy(reliability), durability=DurabilityPolicy(durability))
            subs[name] = node.create_subscription(cls, name, lambda _: None, qos, raw=True)

    def drain() -> None:
        for name, sub in subs.items():
            handle, msg_type = sub.handle, sub.msg_type
            is_status, is_recorded = name == status_topic, name in recorded
            while True:
                with handle:
                    taken = handle.take_message(msg_type, True)
                if taken is None:
                    break
                data, info = taken
                recv = info["received_timestamp"] or time.time_ns()
                if is_status and p["auto_arm"]:
                    recorder.on_armed(deserialize_message(data, VehicleStatus).armed, recv)
                if is_recorded:
                    recorder.on_message(name, data, recv, info["source_timestamp"] or recv,
                                        info["publication_sequence_number"] or 0)

    def trigger(action):
        def handle(request, response):
            response.success, response.message = action("service")
            publish_status()
            return response
        return handle

    drainer = Drainer(node)
    drainer.service(Trigger, "recorder/start", trigger(recorder.start))
    drainer.service(Trigger, "recorder/stop", trigger(recorder.stop))
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    pub_status = node.create_publisher(DiagnosticStatus, "recorder/status", latched)
    last = {"status": None, "time": 0.0}

    def publish_status() -> None:
        s = recorder.status()
        level = DiagnosticStatus.ERROR if s["error"] else DiagnosticStatus.WARN if s["dropped"] else DiagnosticStatus.OK
        pub_status.publish(DiagnosticStatus(level=level, name="recorder", message=s["state"], hardware_id="c4d_data",
                                            values=[KeyValue(key=k, value=str(v)) for k, v in s.items()]))
        last["status"], last["time"] = s, time.monotonic()

    stopping: list[int] = []
    signal.signal(signal.SIGINT, lambda *_: stopping.append(1))
    signal.signal(signal.SIGTERM, lambda *_: stopping.append(1))
    log("info", f"recording into {output_dir} ({'on arm/disarm of ' + status_topic if p['auto_arm'] else 'manual'})")
    next_discovery = 0.0
    try:
        while not stopping and rclpy.ok():
            now = time.monotonic()
            if now >= next_discovery:
                discover()
                next_discovery = now + p["discovery_period_s"]
            drain()
            drainer.drain()
            recorder.poll()
            s = recorder.status()
            if now - last["time"] >= 1.0 or (last["status"] and (s["state"], s["files"], s["error"]) !=
                                              (last["status"]["state"], last["status"]["files"], last["status"]["error"])):
                publish_status()
            time.sleep(p["drain_period_s"])
    finally:
        drain()
        recorder.shutdown()
        if recorder.state == IDLE and last["status"] is not None:
            publish_status()
        node.destroy_node()
        rclpy.try_shutdown()
    return 1 if recorder.last_error else 0


if __name__ == "__main__":
    sys.exit(main())
