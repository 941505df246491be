"""Rewrite an interrupted (or any) recording into a complete rosbag2 MCAP file.

Why: after a `kill -9`, a power loss or a full disk the recorder's file has every complete
chunk but no summary, statistics or `rosbag2` metadata record, so `ros2 bag info` and indexed
readers refuse it. Repair reads every complete record linearly (bag_reader) and writes them,
in file order, through the same BagWriter the recorder uses (schemas, channel QoS metadata,
type hashes and custom data preserved), which adds the summary and metadata. The source file is
never modified; `in_place` replaces it only after the new file is complete.
"""

from __future__ import annotations

import os
from pathlib import Path

from .bag_reader import BagContents, BagError, iter_messages, open_bag
from .bag_writer import BagSummary, BagWriter


def default_output(source: Path) -> Path:
    return source.with_name(source.stem + ".repaired.mcap")


def repair(source: str | Path, output: str | Path | None = None, in_place: bool = False) -> tuple[BagContents, BagSummary]:
    """Rewrite `source` with a summary; returns (what was read, what was written)."""
    source = Path(source)
    contents = open_bag(source)
    target = source.with_name(source.name + ".repair-tmp") if in_place else Path(output or default_output(source))
    if target.exists():
        raise BagError(f"{target}: already exists (choose another output)")
    custom = {str(k): str(v) for k, v in (contents.rosbag2.get("custom_data") or {}).items()}
    custom["c4d.repaired_from"] = source.name
    if contents.problem:
        custom["c4d.repair_reason"] = contents.problem
    try:
        writer = BagWriter(target, custom_data=custom)
    except OSError as exc:
        raise BagError(f"{target}: cannot create ({exc.strerror})") from None
    try:
        for topic in contents.topics.values():
            writer.add_topic(topic.name, topic.type_name, topic.schema.data.decode(), topic.offered_qos, topic.type_hash)
        for topic, message in iter_messages(contents, log_time_order=False):
            writer.write(topic.name, message.data, message.log_time, message.publish_time, message.sequence)
        written = writer.close()
    except OSError as exc:
        writer.abort()
        target.unlink(missing_ok=True)
        raise BagError(f"{target}: write failed ({exc.strerror})") from None
    except BaseException:
        writer.abort()
        target.unlink(missing_ok=True)
        raise
    if in_place:
        os.replace(target, source)
        written.path = source
    return contents, written
