"""The flight recorder's start-time settings, validated and typed, free of ROS.

Why apart from the node: which topics are recorded (include / exclude regular expressions on
fully qualified names) and whether a configuration is usable (compression, writable output
directory) are decisions a test can check without DDS; the node only reads its parameters and
hands them here. Ranges of the numeric parameters are enforced by their ROS descriptors.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .recording import RecorderConfig

COMPRESSIONS = ("zstd", "lz4", "none")


@dataclass(frozen=True)
class RecorderSettings:
    """What the recorder node does besides the recording core (`recording`): topic selection,
    arm/disarm source, DDS history depth, discovery and drain periods, CPU niceness."""

    recording: RecorderConfig
    include: tuple[re.Pattern[str], ...]
    exclude: tuple[re.Pattern[str], ...]
    auto_arm: bool
    status_topic: str
    queue_depth: int
    discovery_period_s: float
    drain_period_s: float
    niceness: int

    @classmethod
    def from_parameters(cls, p: Mapping[str, Any]) -> RecorderSettings:
        """Settings from the declared parameter values; ValueError (one line) when unusable."""
        try:
            include = tuple(re.compile(x) for x in p["include"] if x)
            exclude = tuple(re.compile(x) for x in p["exclude"] if x)
        except re.error as exc:
            raise ValueError(str(exc)) from None
        if p["compression"] not in COMPRESSIONS:
            raise ValueError(f"compression must be zstd, lz4 or none, not {p['compression']!r}")
        recording = RecorderConfig(Path(p["output_dir"]).expanduser(), p["prefix"], p["pre_roll_s"], p["post_roll_s"],
                                   p["max_queue_messages"], p["max_queue_bytes"], p["chunk_size"], p["max_chunk_age_s"],
                                   p["compression"], p["fsync"])
        return cls(recording, include, exclude, p["auto_arm"], p["status_topic"], p["queue_depth"],
                   p["discovery_period_s"], p["drain_period_s"], p["niceness"])

    def make_output_dir(self) -> Path:
        """Create the output directory; OSError / ValueError when it cannot be written."""
        output_dir = self.recording.output_dir
        output_dir.mkdir(parents=True, exist_ok=True)
        if not os.access(output_dir, os.W_OK):
            raise ValueError(f"output_dir {output_dir} is not writable")
        return output_dir

    def wants(self, topic: str) -> bool:
        """Is `topic` (fully qualified) recorded: it matches an include pattern (all when none) and no exclude."""
        return (not self.include or any(r.search(topic) for r in self.include)) and not any(
            r.search(topic) for r in self.exclude)
