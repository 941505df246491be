"""Robust reading of rosbag2 MCAP files: validation, contents, messages, decoding.

Why: replay, repair and analysis must accept exactly the files that rosbag2 accepts and turn
everything else into one clear sentence (BagError): not an MCAP file, a profile other than
`ros2`, a schema that is not `ros2msg`, corrupt or truncated data. A recording interrupted by a
crash or a full disk has no summary; it is read linearly (mcap's StreamReader) up to the last
complete record and reported as incomplete, so its data is never lost. Complete files are read
through the chunk index in log-time order (mcap's SeekingReader). Decoding uses the schema
text stored in the file (mcap_ros2), not the installed packages.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
import zstandard
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Channel, Header, Message, Metadata, Schema
from mcap.stream_reader import StreamReader

MAGIC = b"\x89MCAP0\r\n"
_READ_ERRORS = (McapError, struct.error, EOFError, ValueError, OSError, UnicodeDecodeError, zstandard.ZstdError)


class BagError(Exception):
    """The file cannot be used; str() is the one-line reason."""


@dataclass
class Topic:
    name: str
    type_name: str
    channel_id: int
    offered_qos: str
    type_hash: str
    schema: Schema | None
    count: int = 0


@dataclass
class BagContents:
    path: Path
    profile: str
    library: str
    complete: bool
    topics: dict[str, Topic]
    message_count: int
    start_ns: int
    end_ns: int
    problem: str = ""  # why the file is incomplete, empty when complete
    rosbag2: dict[str, Any] = field(default_factory=dict)  # serialized_metadata, parsed
    metadata: list[Metadata] = field(default_factory=list)

    @property
    def duration_s(self) -> float:
        return (self.end_ns - self.start_ns) * 1e-9


def _check_file(path: Path) -> None:
    if not path.is_file():
        raise BagError(f"{path}: no such file")
    with path.open("rb") as f:
        head = f.read(len(MAGIC))
    if head != MAGIC:
        raise BagError(f"{path}: not an MCAP file (bad magic)")


def _check_profile(path: Path, header: Header) -> None:
    if header.profile != "ros2":
        raise BagError(f"{path}: MCAP profile is {header.profile!r}, expected 'ros2' (not a ROS 2 recording)")


def _topic(channel: Channel, schema: Schema | None) -> Topic:
    return Topic(channel.topic, schema.name if schema else "", channel.id,
                 channel.metadata.get("offered_qos_profiles", ""), channel.metadata.get("topic_type_hash", ""), schema)


def _complete_contents(path: Path) -> BagContents | None:
    """Contents from the summary section, or None when the file has none (interrupted)."""
    with path.open("rb") as f:
        reader = make_reader(f)
        try:
            summary = reader.get_summary()
        except _READ_ERRORS:
            return None
        if summary is None or summary.statistics is None:
            return None
        header = reader.get_header()
        _check_profile(path, header)
        topics = {}
        for channel in summary.channels.values():
            topic = _topic(channel, summary.schemas.get(channel.schema_id))
            topic.count = summary.statistics.channel_message_counts.get(channel.id, 0)
            topics[channel.topic] = topic
        metadata = list(reader.iter_metadata())
    stats = summary.statistics
    return BagContents(path, header.profile, header.library, True, topics, stats.message_count,
                       stats.message_start_time, stats.message_end_time, metadata=metadata)


def _scan(path: Path) -> Iterator[tuple[str, Any]]:
    """Linear read of every record up to the first damaged one: ('header'|'schema'|'channel'|
    'message'|'metadata'|'end'|'problem', record)."""
    with path.open("rb") as f:
        records = StreamReader(f, validate_crcs=True, record_size_limit=1 << 30).records
        while True:
            try:
                record = next(records)
            except StopIteration:
                yield "end", None
                return
            except _READ_ERRORS as exc:
                offset = f.tell()
                yield "problem", (f"file ends without a summary at byte {offset} (interrupted recording)"
                                  if isinstance(exc, (McapError, EOFError, struct.error)) and "magic" not in str(exc)
                                  else f"damaged data near byte {offset}: {exc}")
                return
            kind = {Header: "header", Schema: "schema", Channel: "channel", Message: "message",
                    Metadata: "metadata"}.get(type(record))
            if kind:
                yield kind, record


def _scanned_contents(path: Path) -> BagContents:
    header, schemas, topics, metadata = None, {}, {}, []
    by_id: dict[int, Topic] = {}
    count, start, end, problem = 0, 0, 0, ""
    for kind, record in _scan(path):
        if kind == "header":
            header = record
            _check_profile(path, header)
        elif kind == "schema":
            schemas[record.id] = record
        elif kind == "channel" and record.id not in by_id:
            by_id[record.id] = topics[record.topic] = _topic(record, schemas.get(record.schema_id))
        elif kind == "message":
            topic = by_id.get(record.channel_id)
            if topic is None:
                problem = f"message on unknown channel {record.channel_id}"
                break
            topic.count += 1
            start = record.log_time if count == 0 else min(start, record.log_time)
            end = max(end, record.log_time)
            count += 1
        elif kind == "metadata":
            metadata.append(record)
        elif kind == "problem":
            problem = record
    if header is None:
        raise BagError(f"{path}: no MCAP header ({problem or 'empty file'})")
    return BagContents(path, header.profile, header.library, False, topics, count, start, end,
                       problem or "file has no summary", metadata=metadata)


def open_bag(path: str | Path) -> BagContents:
    """Validate `path` and describe it; raises BagError with the reason when unusable."""
    path = Path(path)
    _check_file(path)
    try:
        contents = _complete_contents(path) or _scanned_contents(path)
    except BagError:
        raise
    except _READ_ERRORS as exc:
        raise BagError(f"{path}: unreadable MCAP ({exc})") from None
    for record in contents.metadata:
        if record.name == "rosbag2" and "serialized_metadata" in record.metadata:
            try:
                contents.rosbag2 = yaml.safe_load(record.metadata["serialized_metadata"]) or {}
            except yaml.YAMLError:
                contents.problem = contents.problem or "unparsable rosbag2 metadata record"
    for topic in contents.topics.values():
        if topic.schema is None or topic.schema.encoding != "ros2msg":
            encoding = topic.schema.encoding if topic.schema else "none"
            raise BagError(f"{path}: topic {topic.name} has schema encoding {encoding!r}, expected 'ros2msg'")
    return contents


def iter_messages(contents: BagContents, topics: Iterable[str] | None = None,
                  log_time_order: bool = True) -> Iterator[tuple[Topic, Message]]:
    """(topic, raw message) for the selected topics. Complete files: log-time order through the
    index; incomplete files: every complete record, sorted by log time when asked."""
    wanted = None if topics is None else set(topics)
    by_id = {t.channel_id: t for t in contents.topics.values()}
    if contents.complete:
        with contents.path.open("rb") as f:
            try:
                for _, channel, message in make_reader(f, validate_crcs=True).iter_messages(
                        topics=None if wanted is None else sorted(wanted), log_time_order=log_time_order):
                    yield by_id[channel.id], message
            except _READ_ERRORS as exc:
                raise BagError(f"{contents.path}: damaged chunk ({exc})") from None
        return
    pending = [(by_id[r.channel_id], r) for kind, r in _scan(contents.path)
               if kind == "message" and r.channel_id in by_id and (wanted is None or by_id[r.channel_id].name in wanted)]
    if log_time_order:
        pending.sort(key=lambda item: item[1].log_time)
    yield from pending


class Decoders:
    """CDR -> Python objects (SimpleNamespace) from the schema text stored in the file."""

    def __init__(self) -> None:
        from mcap_ros2.decoder import DecoderFactory

        self.factory = DecoderFactory()
        self.cache: dict[int, Any] = {}

    def decode(self, topic: Topic, data: bytes) -> Any:
        decoder = self.cache.get(topic.channel_id)
        if decoder is None:
            try:
                decoder = self.factory.decoder_for("cdr", topic.schema)
            except Exception as exc:  # the vendored parser raises its own error types
                raise BagError(f"topic {topic.name}: cannot parse the {topic.type_name} definition ({exc})") from None
            if decoder is None:
                raise BagError(f"topic {topic.name}: no decoder for type {topic.type_name}")
            self.cache[topic.channel_id] = decoder
        return decoder(data)
