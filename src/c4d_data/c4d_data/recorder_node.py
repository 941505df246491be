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

import os
import signal
import sys
import time
from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from std_srvs.srv import Trigger

from c4d_interfaces.msg import VehicleStatus
from c4d_ros import lifecycle, manifest
from c4d_ros.component import ComponentError, Host, run_components
from c4d_ros.drain import Drainer
from c4d_ros.params import ParameterError, Spec, declare_all

from .message_types import message_class
from .msgdef import DefinitionCache, DefinitionError
from .qos import TRANSIENT_LOCAL, profile_dict, request_for_offers
from .recorder_settings import COMPRESSIONS, RecorderSettings
from .recording import IDLE, Recorder, TopicInfo

PARAMETERS: dict[str, Spec] = {  # all read once at start: a change needs a restart
    "output_dir": Spec("flights", "directory of the flight files, created if missing [path]", read_only=True),
    "prefix": Spec("flight", "file name prefix: <prefix>_<UTC start>.mcap [text]", read_only=True),
    "include": Spec([""], "regular expressions on fully qualified topic names to record; empty = every topic [regex]",
                    read_only=True),
    "exclude": Spec([""], "regular expressions of topics never recorded [regex]", read_only=True),
    "auto_arm": Spec(True, "start a file on the arm edge of status_topic, end it on the disarm edge [bool]", read_only=True),
    "status_topic": Spec(manifest.STATUS.name, "c4d_interfaces/VehicleStatus topic whose arm edges start and end files "
                                               "[topic]", read_only=True),
    "pre_roll_s": Spec(1.0, "keep samples received this long before the arm edge [s]", 0.0, 60.0, True),
    "post_roll_s": Spec(1.0, "and this long after the disarm edge [s]", 0.0, 60.0, True),
    "max_queue_messages": Spec(200000, "writer queue bound; beyond it samples are dropped and counted [messages]",
                               1, 100_000_000, True),
    "max_queue_bytes": Spec(256 << 20, "writer queue bound [bytes]", 1, 1 << 40, True),
    "chunk_size": Spec(1 << 20, "MCAP chunk size; a crash loses at most the open chunk [bytes]", 1, 1 << 30, True),
    "max_chunk_age_s": Spec(1.0, "a chunk is written at the latest this long after its first message [s]", 0.0, 3600.0, True),
    "compression": Spec("zstd", f"chunk compression: {' | '.join(COMPRESSIONS)} [name]", read_only=True),
    "fsync": Spec(False, "fsync after each chunk (power-loss safety; costs I/O) [bool]", read_only=True),
    "queue_depth": Spec(5000, "DDS history depth of each subscription (keep last): backlog a slow drain absorbs [messages]",
                        1, 1_000_000, True),
    "discovery_period_s": Spec(0.5, "new topics are picked up this often [s]", 0.0, 60.0, True),
    "drain_period_s": Spec(0.005, "subscriptions are drained this often [s]", 1e-4, 1.0, True),
    "niceness": Spec(5, "CPU priority below the flight-critical nodes (nice increment) [nice]", 0, 19, True),
}


def read_settings(node) -> RecorderSettings:
    """Declared parameters -> validated settings (output directory created); ValueError / OSError."""
    settings = RecorderSettings.from_parameters(declare_all(node, PARAMETERS))
    settings.make_output_dir()
    return settings


class RecorderNode:
    """The recorder's ROS face: discovers topics, subscribes raw with the QoS matching their
    publishers, drains them with non-blocking takes into `recording.Recorder`, feeds it the armed
    flag of the status topic, serves recorder/start and recorder/stop and publishes recorder/status."""

    def __init__(self, node, settings: RecorderSettings, own_process: bool = True) -> None:
        self.node, self.settings = node, settings
        self.logger = node.get_logger()
        if settings.niceness and own_process:  # before the writer thread starts: it inherits the priority
            os.nice(settings.niceness)
        elif settings.niceness:  # the niceness of a shared process is the system YAML's (compose group `nice`)
            self.log("info", f"niceness {settings.niceness} not applied: the recorder shares its process with other "
                             "nodes (set nice on the compose group in the system YAML)")
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a file-size limit must surface as EFBIG, not kill us
        self.recorder = Recorder(settings.recording, self.log)
        self.definitions = DefinitionCache()
        self.status_topic = node.resolve_topic_name(settings.status_topic)
        self.subscriptions: dict[str, Any] = {}  # topic -> raw subscription
        self.recorded: set[str] = set()
        self.ignored: set[str] = set()
        self.drainer = Drainer(node)
        self.drainer.service(Trigger, manifest.RECORDER_START.name, self.on_start)
        self.drainer.service(Trigger, manifest.RECORDER_STOP.name, self.on_stop)
        self.drainer.adopt_node_services()  # parameter services too (`ros2 param dump`): no executor spins this node
        self.pub_status = node.create_publisher(DiagnosticStatus, manifest.RECORDER_STATUS.name, manifest.RECORDER_STATUS.qos)
        self.last_status: dict[str, Any] | None = None  # as last published
        self.last_status_time = 0.0  # [s] monotonic
        self.next_discovery = 0.0  # [s] monotonic
        self.log("info", f"recording into {settings.recording.output_dir} "
                         f"({'on arm/disarm of ' + self.status_topic if settings.auto_arm else 'manual'})")

    def log(self, level: str, text: str) -> None:  # one call site per severity (rclpy's logger insists)
        if level == "info":
            self.logger.info(text)
        elif level == "warn":
            self.logger.warning(text)
        else:
            self.logger.error(text)
            print(f"recorder: error: {text}", file=sys.stderr, flush=True)

    def discover(self) -> None:
        """Subscribe to every new topic that is recorded (or is the status topic) and has a publisher."""
        for name, types in self.node.get_topic_names_and_types():
            if name in self.subscriptions or name in self.ignored:
                continue
            record = self.settings.wants(name)
            if not record and name != self.status_topic:
                self.ignored.add(name)
                continue
            offers = list(self.node.get_publishers_info_by_topic(name))
            if not offers:
                continue  # QoS is chosen from the publishers: wait for one
            if len(types) != 1:
                self.log("warn", f"topic {name} has several types {types}: not recorded")
                self.ignored.add(name)
                continue
            cls = message_class(types[0])
            if cls is None:
                self.log("warn", f"topic {name}: type {types[0]} is not installed here: not recorded")
                self.ignored.add(name)
                continue
            self.subscribe(name, types[0], cls, offers, record)

    def subscribe(self, name: str, type_name: str, cls: Any, offers: list[Any], record: bool) -> None:
        profiles = [i.qos_profile for i in offers]
        reliability, durability = request_for_offers(profiles)
        if record:
            try:
                definition = self.definitions.get(type_name)
            except DefinitionError as exc:
                self.log("warn", f"topic {name}: {exc}: not recorded")
            else:
                self.recorder.add_topic(TopicInfo(name, type_name, definition, [profile_dict(q) for q in profiles],
                                                  str(offers[0].topic_type_hash), durability == TRANSIENT_LOCAL))
                self.recorded.add(name)
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=self.settings.queue_depth,
                         reliability=ReliabilityPolicy(reliability), durability=DurabilityPolicy(durability))
        self.subscriptions[name] = self.node.create_subscription(cls, name, lambda _: None, qos, raw=True)

    def drain(self) -> None:
        """Take everything queued on every subscription (never waits) into the recorder."""
        recorder, auto_arm = self.recorder, self.settings.auto_arm
        for name, sub in self.subscriptions.items():
            handle, msg_type = sub.handle, sub.msg_type
            is_status, is_recorded = name == self.status_topic, name in self.recorded
            while True:
                with handle:
                    taken = handle.take_message(msg_type, True)
                if taken is None:
                    break
                data, info = taken
                recv = info["received_timestamp"] or time.time_ns()
                if is_status and auto_arm:
                    recorder.on_armed(deserialize_message(data, VehicleStatus).armed, recv)
                if is_recorded:
                    recorder.on_message(name, data, recv, info["source_timestamp"] or recv,
                                        info["publication_sequence_number"] or 0)

    def on_start(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        response.success, response.message = self.recorder.start("service")
        self.publish_status()
        return response

    def on_stop(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        response.success, response.message = self.recorder.stop("service")
        self.publish_status()
        return response

    def publish_status(self) -> None:
        s = self.recorder.status()
        level = DiagnosticStatus.ERROR if s["error"] else DiagnosticStatus.WARN if s["dropped"] else DiagnosticStatus.OK
        self.pub_status.publish(DiagnosticStatus(level=level, name="recorder", message=s["state"], hardware_id="c4d_data",
                                                 values=[KeyValue(key=k, value=str(v)) for k, v in s.items()]))
        self.last_status, self.last_status_time = s, time.monotonic()

    def status_due(self, now: float) -> bool:
        """1 Hz, and at once when the state, the file count or the error changed."""
        if now - self.last_status_time >= 1.0:
            return True
        last = self.last_status
        s = self.recorder.status()
        return bool(last) and (s["state"], s["files"], s["error"]) != (last["state"], last["files"], last["error"])

    # c4d_ros.component protocol: the recorder drains its node itself (no executor spins it)
    name = "recorder"
    nodes: tuple = ()
    events_executor = False
    rt_priority = 0

    @property
    def period_s(self) -> float:
        return self.settings.drain_period_s

    def step(self, budget_s: float = 0.0) -> None:
        """Discover (every discovery_period_s), drain, poll the writer, publish the status when due;
        then sleep `budget_s` (the drain period when the recorder has its process to itself)."""
        now = time.monotonic()
        if now >= self.next_discovery:
            self.discover()
            self.next_discovery = now + self.settings.discovery_period_s
        self.drain()
        self.drainer.drain()
        self.recorder.poll()
        if self.status_due(now):
            self.publish_status()
        if budget_s > 0:
            time.sleep(budget_s)

    def idle(self, budget_s: float) -> None:
        """Inactive (c4d_ros.lifecycle): only the services (lifecycle, parameters, start/stop) are served."""
        self.drainer.drain()
        if budget_s > 0:
            time.sleep(budget_s)

    def release(self) -> None:
        """Lifecycle cleanup: what is queued written, the file closed, the discovered subscriptions gone."""
        self.drain()
        self.recorder.shutdown()
        for sub, _ in self.drainer.subscriptions:
            self.node.destroy_subscription(sub)

    def close(self) -> int:
        """Take what is still queued, close the file, say so; 1 if a write failed, else 0."""
        self.drain()
        self.recorder.shutdown()
        if self.recorder.state == IDLE and self.last_status is not None:
            self.publish_status()
        self.node.destroy_node()
        return 1 if self.recorder.last_error else 0


def component(rclpy, host: Host) -> lifecycle.ManagedComponent:
    """The recorder as a component (c4d_ros.component). Stop requests are caught by the runner
    from before rclpy starts: a SIGINT during start-up (rclpy and DDS initialising, the writer
    thread starting) used to raise KeyboardInterrupt wherever it landed — an unclean exit, and a
    possible hang tearing down a half-built DDS participant (issue 14 item 15)."""
    node = lifecycle.create_node(rclpy, "recorder")
    try:
        settings = read_settings(node)
    except (ParameterError, ValueError, OSError) as exc:
        node.destroy_node()
        raise ComponentError(str(exc)) from None

    def build() -> RecorderNode:  # configure (c4d_ros.lifecycle): output directory, writer, services
        try:
            return RecorderNode(node, settings, own_process=not host.composed)
        except (ParameterError, ValueError, OSError) as exc:
            raise ComponentError(str(exc)) from None
    return lifecycle.ManagedComponent("recorder", node, build, period_s=settings.drain_period_s, spun=False)


def main(argv: list[str] | None = None) -> int:
    return run_components([("recorder", component)], argv, "recorder", composed=False)

if __name__ == "__main__":
    sys.exit(main())
