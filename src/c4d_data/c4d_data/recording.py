"""Flight-recording core, free of ROS: when to record, what goes in each file, and a writer
thread that never makes the receiving side wait.

Why: the data block must start a file when the vehicle arms and close it when it disarms (one
file per flight, D3.3 §2.2.9), lose nothing at full graph rates and never back-pressure the
GNC core. The receiving thread (the recorder node's drain loop) only appends to a bounded
deque; a writer thread does the MCAP work (zstd releases the GIL). When the queue is over its
message or byte bound the newest sample is dropped and counted: memory stays bounded and the
drop counter says so.

Flight boundaries use receive timestamps, not processing order: a file holds every sample
received from `pre_roll_s` before the arm edge to `post_roll_s` after the disarm edge (a
rolling pre-roll buffer covers samples taken before the arm message is seen). Latched topics
(all publishers transient-local: status, schedule, plan) are cached, so every file starts with
their last value (log time = file start) even if they were published once, long before.
"""

from __future__ import annotations

import collections
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from .bag_writer import BagSummary, BagWriter

IDLE, RECORDING, POST_ROLL = "idle", "recording", "post_roll"
SHUTDOWN_TIMEOUT_S = 7.0  # < the supervisor's default 10 s shutdown_timeout_s


@dataclass
class TopicInfo:
    name: str
    type_name: str
    definition: str
    offered_qos: list[dict[str, Any]]
    type_hash: str = ""
    latched: bool = False


@dataclass
class RecorderConfig:
    output_dir: Path
    prefix: str = "flight"
    pre_roll_s: float = 1.0
    post_roll_s: float = 1.0
    max_queue_messages: int = 200_000
    max_queue_bytes: int = 256 << 20
    chunk_size: int = 1 << 20
    max_chunk_age_s: float = 1.0
    compression: str = "zstd"
    fsync: bool = False


class Recorder:
    """Call on_message()/on_armed()/start()/stop()/poll() from one thread; files are written by
    an internal thread. `log(level, text)` receives notable events ('info' | 'warn' | 'error')."""

    def __init__(self, config: RecorderConfig, log: Callable[[str, str], None] | None = None,
                 clock_ns: Callable[[], int] = time.time_ns) -> None:
        self.config = config
        self.log = log or (lambda level, text: None)
        self.clock_ns = clock_ns
        self.topics: dict[str, TopicInfo] = {}
        self.state = IDLE
        self.armed: bool | None = None
        self.window_start = 0
        self.window_end = 0  # 0 = open-ended
        self.pre_roll: collections.deque = collections.deque()
        self.latched: dict[str, tuple] = {}
        self.latched_topics: set[str] = set()
        self.drops_at_start = 0
        self.queue: collections.deque = collections.deque()
        self.enqueued = self.dequeued = 0
        self.enqueued_bytes = self.dequeued_bytes = 0
        self.dropped = 0
        self.dropped_by_topic: collections.Counter = collections.Counter()
        self.files: list[BagSummary] = []
        self.current: Path | None = None
        self.written = 0
        self.last_error = ""
        self.running = True
        self.thread = threading.Thread(target=self._writer_loop, name="c4d-recorder-writer", daemon=True)
        self.thread.start()

    # ---------------------------------------------------------------- receiving side
    def add_topic(self, info: TopicInfo) -> None:
        self.topics[info.name] = info
        if info.latched:
            self.latched_topics.add(info.name)

    def on_message(self, topic: str, data: bytes, recv_ns: int, src_ns: int, seq: int) -> None:
        sample = (topic, data, recv_ns, src_ns, seq)
        if topic in self.latched_topics:
            self.latched[topic] = sample
        state = self.state
        if state == IDLE:
            pre = self.pre_roll
            pre.append(sample)
            horizon = recv_ns - int(self.config.pre_roll_s * 1e9)
            while pre and (pre[0][2] < horizon or len(pre) > self.config.max_queue_messages):
                pre.popleft()
            return
        if recv_ns < self.window_start or (self.window_end and recv_ns > self.window_end):
            return
        self._enqueue(sample)

    def _enqueue(self, sample: tuple) -> None:
        if (self.enqueued - self.dequeued >= self.config.max_queue_messages
                or self.enqueued_bytes - self.dequeued_bytes >= self.config.max_queue_bytes):
            self.dropped += 1
            self.dropped_by_topic[sample[0]] += 1
            return
        self.enqueued += 1
        self.enqueued_bytes += len(sample[1])
        self.queue.append(sample)

    def on_armed(self, armed: bool, stamp_ns: int) -> None:
        """Feed every vehicle status: the arm edge starts a file, the disarm edge ends it."""
        previous, self.armed = self.armed, armed
        if armed and not previous and self.state != RECORDING:
            self.start("armed", stamp_ns)
        elif not armed and previous and self.state == RECORDING:
            self.stop("disarmed", stamp_ns)

    def start(self, reason: str, at_ns: int | None = None) -> tuple[bool, str]:
        if self.state == RECORDING:
            return False, f"already recording {self.current}"
        if self.state == POST_ROLL:
            self._close_file()
        at_ns = at_ns if at_ns is not None else self.clock_ns()
        self.window_start = at_ns - int(self.config.pre_roll_s * 1e9)
        self.window_end = 0
        path = self._new_path(at_ns)
        self.current = path
        self.queue.append(("open", path, reason))
        self.state = RECORDING
        self.drops_at_start = self.dropped
        in_window = [s for s in self.pre_roll if s[2] >= self.window_start]
        shown = {s[0] for s in in_window}
        for topic, sample in self.latched.items():
            if topic not in shown:
                self._enqueue((topic, sample[1], self.window_start, sample[3], sample[4]))
        for sample in in_window:
            self._enqueue(sample)
        self.pre_roll.clear()
        self.log("info", f"recording started ({reason}): {path}")
        return True, str(path)

    def stop(self, reason: str, at_ns: int | None = None) -> tuple[bool, str]:
        if self.state != RECORDING:
            return False, "not recording"
        at_ns = at_ns if at_ns is not None else self.clock_ns()
        self.window_end = at_ns + int(self.config.post_roll_s * 1e9)
        self.state = POST_ROLL
        self.stop_reason = reason
        return True, f"stopping {self.current} ({reason}), post-roll {self.config.post_roll_s:.1f} s"

    def poll(self) -> None:
        """Call periodically: ends the post-roll once the clock passes the window end."""
        if self.state == POST_ROLL and self.clock_ns() > self.window_end:
            self._close_file()

    def _close_file(self) -> None:
        self.queue.append(("close", self.current, self.dropped - self.drops_at_start))
        self.log("info", f"recording stopped ({getattr(self, 'stop_reason', 'stop')}): {self.current}")
        self.state = IDLE
        self.current = None

    def _new_path(self, at_ns: int) -> Path:
        stamp = datetime.fromtimestamp(at_ns * 1e-9, UTC).strftime("%Y%m%dT%H%M%SZ")
        path = self.config.output_dir / f"{self.config.prefix}_{stamp}.mcap"
        k = 2
        while path.exists() or any(f.path == path for f in self.files) or path == self.current:
            path = self.config.output_dir / f"{self.config.prefix}_{stamp}_{k}.mcap"
            k += 1
        return path

    def status(self) -> dict[str, Any]:
        return {"state": self.state, "file": str(self.current or ""), "files": len(self.files),
                "written": self.written, "dropped": self.dropped, "queued": self.enqueued - self.dequeued,
                "topics": len(self.topics), "error": self.last_error}

    def shutdown(self, timeout: float = SHUTDOWN_TIMEOUT_S) -> bool:
        """Close the open file (keeping what was received) and stop the writer thread; False (and an
        error logged) if the writer did not finish within `timeout` — shorter than the supervisor's
        10 s SIGINT-to-SIGKILL grace, so the process still ends by itself (the file then lacks its
        summary; `repair` rebuilds it)."""
        if self.state != IDLE:
            self.stop_reason = "shutdown"
            self._close_file()
        self.queue.append(("exit",))
        self.thread.join(timeout)
        if self.thread.is_alive():
            self.last_error = f"writer still busy {timeout:g} s after the stop ({self.enqueued - self.dequeued} queued)"
            self.log("error", self.last_error)
            return False
        return True

    # ---------------------------------------------------------------- writer thread
    def _writer_loop(self) -> None:
        bag: BagWriter | None = None
        failed = False
        while True:
            try:
                item = self.queue.popleft()
            except IndexError:
                if bag is not None and not failed:
                    try:
                        bag.flush_if_older(self.config.max_chunk_age_s)
                    except OSError as exc:
                        failed = self._write_failed(bag, exc)
                time.sleep(0.004)
                continue
            if len(item) == 5:
                self.dequeued += 1
                self.dequeued_bytes += len(item[1])
                if bag is None or failed:
                    continue
                try:
                    if item[0] not in bag.topics:
                        info = self.topics[item[0]]
                        bag.add_topic(info.name, info.type_name, info.definition, info.offered_qos, info.type_hash)
                    bag.write(item[0], item[1], item[2], item[3], item[4])
                    self.written += 1
                except OSError as exc:
                    failed = self._write_failed(bag, exc)
                continue
            kind = item[0]
            if kind == "open":
                failed = False
                try:
                    item[1].parent.mkdir(parents=True, exist_ok=True)
                    bag = BagWriter(item[1], chunk_size=self.config.chunk_size, compression=self.config.compression,
                                    fsync=self.config.fsync, custom_data={"c4d.start_reason": item[2]})
                except OSError as exc:
                    bag, failed = None, True
                    self.last_error = f"cannot create {item[1]}: {exc.strerror}"
                    self.log("error", self.last_error)
            elif kind == "close":
                if bag is not None and not failed:
                    bag.custom_data["c4d.dropped_messages"] = str(item[2])
                    try:
                        self.files.append(bag.close())
                        self.log("info", f"closed {bag.path}: {bag.message_count} messages")
                    except OSError as exc:
                        self._write_failed(bag, exc)
                bag, failed = None, False
            elif kind == "exit":
                return

    def _write_failed(self, bag: BagWriter, exc: OSError) -> bool:
        summary = bag.abort()
        self.files.append(summary)
        self.last_error = (f"write to {bag.path} failed ({exc.strerror or exc}); kept {summary.bytes} bytes "
                           f"({summary.message_count} messages buffered), readable up to the last complete chunk; "
                           f"run `repair` on it")
        self.log("error", self.last_error)
        return True
