"""rosbag2-convention MCAP writer on top of `mcap.writer.Writer`, built to survive crashes.

Why: one flight must be one file that `ros2 bag info/play` (rosbag2_storage_mcap), Foxglove and
`rosbags` open unchanged. The conventions (checked against rosbag2's mcap_storage.cpp and
rosbags): profile `ros2`; one schema per type, named `pkg/msg/Type`, encoding `ros2msg`, data
= the full definition (msgdef.py); one channel per topic, message encoding `cdr`, channel
metadata `offered_qos_profiles` (YAML string) and `topic_type_hash`; log time = receive time,
publish time = source time; zstd-compressed chunks with message indexes, statistics and
summary; and at close a metadata record named `rosbag2` whose `serialized_metadata` is the
YAML of rosbag2's BagMetadata, version 9 (Jazzy).

Crash safety: the underlying stream (DurableFile) hands every record straight to the OS, so a
`kill -9` loses at most the chunk being built (bounded by size and by `max_chunk_age_s`,
applied by the caller through `flush_if_older`). A write that fails (disk full, file size
limit) truncates the file back to the end of the last complete record, so what was written
stays readable as an MCAP data section; `repair` adds the summary later.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from mcap.writer import CompressionType, Writer

METADATA_VERSION = 9
PROFILE = "ros2"
LIBRARY = "c4d_data (python mcap)"


class DurableFile:
    """Unbuffered, append-only binary stream: each write() reaches the OS before returning.
    On an OSError the file is cut back to the end of the previous complete write."""

    def __init__(self, path: Path, fsync: bool = False) -> None:
        self.fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        self.position = 0
        self.fsync = fsync

    def write(self, data) -> int:
        view = memoryview(data).cast("B")
        start = self.position
        try:
            done = 0
            while done < len(view):
                done += os.write(self.fd, view[done:])
        except OSError:
            try:
                os.ftruncate(self.fd, start)
            except OSError:
                pass
            raise
        self.position = start + len(view)
        return len(view)

    def tell(self) -> int:
        return self.position

    def flush(self) -> None:
        if self.fsync:
            os.fsync(self.fd)

    def close(self) -> None:
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1


@dataclass
class TopicRecord:
    name: str
    type_name: str
    offered_qos: list[dict[str, Any]]
    type_hash: str
    channel_id: int
    count: int = 0


@dataclass
class BagSummary:
    path: Path
    message_count: int
    start_ns: int
    end_ns: int
    counts: dict[str, int] = field(default_factory=dict)
    bytes: int = 0


class BagWriter:
    """Write one rosbag2-compatible MCAP file. Not thread-safe: use it from one thread."""

    def __init__(self, path: str | Path, *, chunk_size: int = 1 << 20, compression: str = "zstd",
                 fsync: bool = False, custom_data: dict[str, str] | None = None) -> None:
        self.path = Path(path)
        self.stream = DurableFile(self.path, fsync=fsync)
        kinds = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}
        if compression not in kinds:
            raise ValueError(f"compression must be one of {sorted(kinds)}, not {compression!r}")
        self.writer = Writer(self.stream, chunk_size=chunk_size, compression=kinds[compression])
        self.writer.start(profile=PROFILE, library=LIBRARY)
        self.custom_data = dict(custom_data or {})
        self.schemas: dict[str, int] = {}
        self.topics: dict[str, TopicRecord] = {}
        self.message_count = 0
        self.start_ns = 0
        self.end_ns = 0
        self.chunk_opened = 0.0
        self.closed = False

    def add_topic(self, name: str, type_name: str, definition: str, offered_qos: list[dict[str, Any]] | str,
                  type_hash: str = "") -> int:
        """Register a topic (schema once per type); returns its channel id. Idempotent per name."""
        if name in self.topics:
            return self.topics[name].channel_id
        if isinstance(offered_qos, str):
            qos_text, qos_list = offered_qos, (yaml.safe_load(offered_qos) or [] if offered_qos else [])
        else:
            from .qos import profiles_yaml

            qos_text, qos_list = profiles_yaml(offered_qos), offered_qos
        if type_name not in self.schemas:
            self.schemas[type_name] = self.writer.register_schema(type_name, "ros2msg", definition.encode())
        metadata = {"offered_qos_profiles": qos_text, "topic_type_hash": type_hash}
        channel_id = self.writer.register_channel(name, "cdr", self.schemas[type_name], metadata)
        self.topics[name] = TopicRecord(name, type_name, qos_list, type_hash, channel_id)
        return channel_id

    def write(self, topic: str, data: bytes, log_time_ns: int, publish_time_ns: int, sequence: int = 0) -> None:
        record = self.topics[topic]
        if self.message_count == 0:
            self.start_ns = self.end_ns = log_time_ns
            self.chunk_opened = time.monotonic()
        self.start_ns = min(self.start_ns, log_time_ns)
        self.end_ns = max(self.end_ns, log_time_ns)
        self.writer.add_message(record.channel_id, log_time_ns, data, publish_time_ns, sequence & 0xFFFFFFFF)
        record.count += 1
        self.message_count += 1

    def flush_if_older(self, max_age_s: float) -> bool:
        """Close the chunk in progress if it was opened more than max_age_s ago (crash window)."""
        if self.chunk_opened and time.monotonic() - self.chunk_opened > max_age_s:
            self.writer.flush()
            self.chunk_opened = time.monotonic()
            return True
        return False

    def bag_metadata(self) -> dict[str, Any]:
        """rosbag2 BagMetadata (v9) as rosbag2's YAML encoder lays it out."""
        duration = self.end_ns - self.start_ns if self.message_count else 0
        return {
            "version": METADATA_VERSION,
            "storage_identifier": "mcap",
            "duration": {"nanoseconds": duration},
            "starting_time": {"nanoseconds_since_epoch": self.start_ns},
            "message_count": self.message_count,
            "topics_with_message_count": [
                {"topic_metadata": {"name": t.name, "type": t.type_name, "serialization_format": "cdr",
                                    "offered_qos_profiles": t.offered_qos, "type_description_hash": t.type_hash},
                 "message_count": t.count}
                for t in self.topics.values()],
            "compression_format": "",
            "compression_mode": "",
            "relative_file_paths": [self.path.name],
            "files": [{"path": self.path.name, "starting_time": {"nanoseconds_since_epoch": self.start_ns},
                       "duration": {"nanoseconds": duration}, "message_count": self.message_count}],
            "custom_data": self.custom_data or None,
            "ros_distro": os.environ.get("ROS_DISTRO", "jazzy"),
        }

    def close(self) -> BagSummary:
        """Write the rosbag2 metadata record and the summary/footer; close the file."""
        if not self.closed:
            self.closed = True
            try:
                text = yaml.safe_dump(self.bag_metadata(), sort_keys=False, default_flow_style=False)
                self.writer.add_metadata("rosbag2", {"serialized_metadata": text})
                self.writer.finish()
                self.stream.flush()
            finally:
                self.stream.close()
        return self.summary()

    def abort(self) -> BagSummary:
        """Close without a summary (after a write error): the file keeps its complete records."""
        self.closed = True
        self.stream.close()
        return self.summary()

    def summary(self) -> BagSummary:
        return BagSummary(self.path, self.message_count, self.start_ns, self.end_ns,
                          {t.name: t.count for t in self.topics.values()}, self.stream.position)
