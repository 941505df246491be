"""Telemetry scheduler of one link: periodic MAVLink streams phased by GCD+ on the link's budget.

What: each stream (one MAVLink message id) is released every `interval` at an absolute instant
epoch + O + k·T (drift-free: computed from k, never now + T). At a release the scheduler calls
the stream's `encode() -> MAVLink message | None` (None: nothing to send this time, counted as
skipped), packs the message with the link's `pack(msg) -> bytes` (seq and signing of the
endpoint) and puts the frame in a bounded send queue that drains at the link rate — a model of
the UART / link FIFO: a frame starts when every earlier byte is on the wire, its bytes leave the
queue one byte time after another, and a frame that does not fit in the free space is dropped
(counted). `advance(now)` returns the frames whose transmission starts by `now`, in order, with
their model start times; the caller writes them (a pty or a UDP socket does not throttle, so the
model is the throttle). `next_event()` says when to call again.

Why GCD+: messages released together queue behind each other; phases (offsets) chosen by
c4d_sched GCD+ (thesis ch. 3) spread them so that no queue builds up. Time is counted in bit times
of the link (the unit of c4d_sched tasks on a link): period T = interval in bit times, wcet C =
largest frame of the message on the wire (MAVLink 2: header 10 + full payload + CRC 2 + 13 if
signed) × bits per byte (10 on a UART: start + 8 data + stop; 8 on UDP). The same integer ticks
drive the queue model, so its delays equal c4d_sched.fifo's exact evaluation when frames have
their full length (`fifo.evaluate` is the oracle of the tests).

Link budget: `LinkBudget.serial(baud)` (bit rate = baud, 10 bits per byte, i.e. baud/10 bytes/s)
or `LinkBudget.udp(bytes_per_second)` (8 bits per byte).

Intervals (SET_MESSAGE_INTERVAL semantics, `set_interval`): -1 disables the stream, 0 restores its
default, a positive value is the interval in µs, rounded to the link's quantum (the smallest
multiple of 1 ms that is a whole number of bit times, ≤ 10 ms, e.g. 5 ms at 57600 bit/s; else
1 ms rounded to bit times), at least one frame time, at most MAX_INTERVAL_US. The effective value
is returned (MESSAGE_INTERVAL replies). Rounding bounds GCD+'s work for any input a GCS may send.
Any change re-assigns every phase and restarts all streams from a new epoch (the next tick).

Typical use (the node):
    sched = TelemetryScheduler(LinkBudget.serial(57600), pack=endpoint.pack, queue_bytes=512)
    sched.add_stream(mavlink.MAVLINK_MSG_ID_ATTITUDE, 100_000, encode_attitude)
    sched.start(time.monotonic())
    ... every few ms:  for frame in sched.advance(time.monotonic()): endpoint.write(frame.data)
    ... on MAV_CMD_SET_MESSAGE_INTERVAL: sched.set_interval(msg_id, param2, time.monotonic())
    ... statistics:   sched.link_stats(now), sched.stream_stats()
`TelemetryDriver` is a small real-time loop doing the same against a write callback.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from c4d_sched.arith import lcm_all
from c4d_sched.gcdplus import run_order
from c4d_sched.methods import assign
from c4d_sched.model import Task, TaskSet

from .signing import mavlink

MAX_INTERVAL_US = 60_000_000
MAX_EVALUATED_JOBS = 200_000  # above: GCD+ without the exact-evaluation order selection
FALLBACK_ORDER = "increasing_period_decreasing_wcet"  # the order of the thesis case study

Encoder = Callable[[], "mavlink.MAVLink_message | None"]
Packer = Callable[["mavlink.MAVLink_message"], bytes]


def frame_bytes(msg_id: int, signed: bool = False) -> int:
    """Largest MAVLink 2 frame of a message id on the wire (payload incl. extensions, untruncated)."""
    cls = mavlink.mavlink_map.get(msg_id)
    if cls is None:
        raise ValueError(f"unknown MAVLink message id {msg_id}")
    return mavlink.HEADER_LEN_V2 + cls.unpacker.size + 2 + (mavlink.MAVLINK_SIGNATURE_BLOCK_LEN if signed else 0)


@dataclass(frozen=True)
class LinkBudget:
    """Capacity of one link: `bit_rate` bit times per second, `bits_per_byte` on the wire."""

    bit_rate: int
    bits_per_byte: int

    def __post_init__(self) -> None:
        if isinstance(self.bit_rate, bool) or not isinstance(self.bit_rate, int) or self.bit_rate <= 0:
            raise ValueError(f"link bit rate must be a positive integer, got {self.bit_rate!r}")
        if self.bits_per_byte not in (8, 10, 11, 12):
            raise ValueError(f"bits per byte must be 8, 10, 11 or 12, got {self.bits_per_byte!r}")

    @classmethod
    def serial(cls, baud: int) -> LinkBudget:
        return cls(baud, 10)

    @classmethod
    def udp(cls, bytes_per_second: int) -> LinkBudget:
        if isinstance(bytes_per_second, bool) or not isinstance(bytes_per_second, int) or bytes_per_second <= 0:
            raise ValueError(f"UDP link rate must be a positive integer of bytes/s, got {bytes_per_second!r}")
        return cls(bytes_per_second * 8, 8)

    @property
    def bytes_per_second(self) -> float:
        return self.bit_rate / self.bits_per_byte

    @property
    def quantum_ticks(self) -> int:
        """Interval grid in bit times (see module docstring)."""
        whole_us = 1_000_000 // math.gcd(self.bit_rate, 1_000_000)  # smallest whole-tick duration, µs
        quantum_us = math.lcm(1000, whole_us)
        if quantum_us <= 10_000:
            return quantum_us * self.bit_rate // 1_000_000
        return max(1, round(self.bit_rate / 1000))


@dataclass(frozen=True)
class Transmission:
    """A frame to write now: its stream, bytes, and model release / start instants (clock s)."""

    msg_id: int
    data: bytes
    release: float
    start: float


@dataclass
class StreamStats:
    """Counters of one stream; delays in bit times, `max_delay_ratio` = max delay / period."""

    released: int = 0
    sent: int = 0
    dropped: int = 0  # queue overflow
    skipped: int = 0  # encode() returned None
    delay_sum: int = 0
    delay_max: int = 0
    max_delay_ratio: float = 0.0


@dataclass(frozen=True)
class StreamReport:
    msg_id: int
    name: str
    interval_us: int  # -1 when disabled
    offset_us: float
    released: int
    sent: int
    dropped: int
    skipped: int
    mean_delay_s: float
    max_delay_s: float
    max_delay_ratio: float


@dataclass(frozen=True)
class LinkStats:
    elapsed_s: float
    bytes_sent: int
    bytes_per_second: float
    utilisation: float  # busy time / elapsed time
    queue_bytes: int  # now
    queue_max_bytes: int
    queue_max_frames: int  # frames in the FIFO, the one on the wire included
    dropped: int
    method: str
    note: str


class _Stream:
    def __init__(self, msg_id: int, name: str, default_us: int, encode: Encoder, wcet: int) -> None:
        self.msg_id, self.name, self.default_us, self.encode, self.wcet = msg_id, name, default_us, encode, wcet
        self.requested_us = default_us
        self.period = 0  # bit times; 0 when disabled
        self.offset = 0
        self.next_release = 0
        self.stats = StreamStats()


class TelemetryScheduler:
    """Streams of one link, their GCD+ phases, and the link's send-queue model (see module doc)."""

    def __init__(
        self, link: LinkBudget, pack: Packer, *, signed: bool = False, queue_bytes: int = 512, method: str = "gcdplus"
    ) -> None:
        if isinstance(queue_bytes, bool) or not isinstance(queue_bytes, int) or queue_bytes <= 0:
            raise ValueError(f"queue size must be a positive number of bytes, got {queue_bytes!r}")
        self.link, self.pack, self.signed, self.queue_bytes, self.method = link, pack, signed, queue_bytes, method
        self.note = ""
        self._streams: list[_Stream] = []
        self._by_id: dict[int, _Stream] = {}
        self._t0: float | None = None
        self._queue: deque[tuple[_Stream, bytes, int]] = deque()
        self._queued_bytes = 0
        self._link_free = 0
        self._now = 0
        self._bytes_sent = 0
        self._busy = 0
        self._queue_max_bytes = 0
        self._queue_max_frames = 0

    # -- configuration ------------------------------------------------------------------------
    def add_stream(self, msg_id: int, interval_us: int, encode: Encoder, name: str | None = None) -> None:
        """Declare a stream (interval -1: off until enabled). Re-phases if already started."""
        if msg_id in self._by_id:
            raise ValueError(f"stream {msg_id} is defined twice")
        wcet = frame_bytes(msg_id, self.signed) * self.link.bits_per_byte
        label = name or mavlink.mavlink_map[msg_id].msgname
        self._check_interval(interval_us, label, allow_zero=False)
        stream = _Stream(msg_id, label, int(interval_us), encode, wcet)
        self._streams.append(stream)
        self._by_id[msg_id] = stream
        if self._t0 is not None:
            self._rephase(self._now)

    def set_interval(self, msg_id: int, interval_us: float, now: float) -> int:
        """SET_MESSAGE_INTERVAL: -1 off, 0 default, > 0 µs. Returns the effective interval (µs, -1 off);
        ValueError (one line) for an unknown stream or a bad value."""
        stream = self._by_id.get(msg_id)
        if stream is None:
            raise ValueError(f"no telemetry stream for message id {msg_id}")
        self._check_interval(interval_us, stream.name, allow_zero=True)
        stream.requested_us = stream.default_us if interval_us == 0 else int(interval_us)
        if self._t0 is not None:
            self._rephase(self._tick(now))
        return self.interval_us(msg_id)

    def interval_us(self, msg_id: int) -> int:
        """Effective interval of a stream in µs (-1 when disabled)."""
        stream = self._by_id[msg_id]
        period = self._period_of(stream)
        return -1 if period == 0 else round(period * 1_000_000 / self.link.bit_rate)

    @staticmethod
    def _check_interval(value: float, name: str, allow_zero: bool) -> None:
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            raise ValueError(f"stream {name}: interval must be a number of µs, got {value!r}")
        if value == -1 or (value == 0 and allow_zero) or 0 < value <= MAX_INTERVAL_US:
            return
        raise ValueError(f"stream {name}: interval {value} µs is not -1 (off), 0 (default) or in 1..{MAX_INTERVAL_US}")

    def _period_of(self, stream: _Stream) -> int:
        if stream.requested_us <= 0:
            return 0
        quantum = self.link.quantum_ticks
        ticks = stream.requested_us * self.link.bit_rate / 1_000_000
        quanta = max(round(ticks / quantum), math.ceil(stream.wcet / quantum), 1)
        return quanta * quantum

    # -- phases -------------------------------------------------------------------------------
    def start(self, now: float) -> None:
        """Start the streams: tick 0 = `now` on the caller's clock (seconds)."""
        self._t0 = now
        self._rephase(0)

    def _rephase(self, epoch: int) -> None:
        for stream in self._streams:
            stream.period = self._period_of(stream)
        active = [s for s in self._streams if s.period]
        self.note = ""
        if active:
            offsets = self._assign([s.period for s in active], [s.wcet for s in active], [s.name for s in active])
            for stream, offset in zip(active, offsets, strict=True):
                stream.offset = offset
                stream.next_release = epoch + offset

    def _assign(self, periods: list[int], wcets: list[int], names: list[str]) -> Sequence[int]:
        taskset = TaskSet(tuple(Task(n, p, c) for n, p, c in zip(names, periods, wcets, strict=True)), unit="bit")
        if self.method == "gcdplus":
            horizon = 2 * lcm_all(periods) + max(periods)
            if sum(horizon // p for p in periods) > MAX_EVALUATED_JOBS:
                self.note = f"order {FALLBACK_ORDER} (window too large for the exact order selection)"
                return run_order(taskset, FALLBACK_ORDER).offsets
        assignment = assign(taskset, self.method)
        self.note = assignment.note
        return assignment.offsets

    # -- running ------------------------------------------------------------------------------
    def _tick(self, now: float) -> int:
        assert self._t0 is not None, "start() first"
        return max(self._now, math.floor((now - self._t0) * self.link.bit_rate + 1e-6))

    def _time(self, tick: int) -> float:
        assert self._t0 is not None
        return self._t0 + tick / self.link.bit_rate

    def _occupancy(self, tick: int) -> int:
        """Bytes in the link FIFO at `tick`: queued frames + the unsent rest of the current one."""
        in_flight = max(0, self._link_free - tick)
        return self._queued_bytes + -(-in_flight // self.link.bits_per_byte)

    def _next_stream(self) -> _Stream | None:
        best = None
        for stream in self._streams:
            if stream.period and (best is None or stream.next_release < best.next_release):
                best = stream
        return best

    def advance(self, now: float) -> list[Transmission]:
        """Release every job due by `now` and return the frames whose transmission starts by `now`."""
        limit = self._tick(now)
        out: list[Transmission] = []
        while True:
            stream = self._next_stream()
            head_start = max(self._queue[0][2], self._link_free) if self._queue else None
            if head_start is not None and head_start <= limit and (stream is None or head_start <= stream.next_release):
                out.append(self._transmit(head_start))
            elif stream is not None and stream.next_release <= limit:
                self._release(stream)
            else:
                break
        self._now = limit
        return out

    def _release(self, stream: _Stream) -> None:
        tick = stream.next_release
        stream.next_release += stream.period
        stream.stats.released += 1
        msg = stream.encode()
        if msg is None:
            stream.stats.skipped += 1
            return
        data = self.pack(msg)
        if self._occupancy(tick) + len(data) > self.queue_bytes:
            stream.stats.dropped += 1
            return
        self._queue.append((stream, data, tick))
        self._queued_bytes += len(data)
        self._queue_max_bytes = max(self._queue_max_bytes, self._occupancy(tick))
        self._queue_max_frames = max(self._queue_max_frames, len(self._queue) + (self._link_free > tick))

    def _transmit(self, start: int) -> Transmission:
        stream, data, release = self._queue.popleft()
        self._queued_bytes -= len(data)
        duration = len(data) * self.link.bits_per_byte
        self._link_free = start + duration
        self._busy += duration
        self._bytes_sent += len(data)
        delay = start - release
        stats = stream.stats
        stats.sent += 1
        stats.delay_sum += delay
        stats.delay_max = max(stats.delay_max, delay)
        stats.max_delay_ratio = max(stats.max_delay_ratio, delay / stream.period if stream.period else 0.0)
        return Transmission(stream.msg_id, data, self._time(release), self._time(start))

    def next_event(self) -> float | None:
        """Clock time of the next release or transmission start (None if nothing is scheduled)."""
        candidates = []
        if self._queue:
            candidates.append(max(self._queue[0][2], self._link_free))
        stream = self._next_stream()
        if stream is not None:
            candidates.append(stream.next_release)
        return self._time(min(candidates)) if candidates else None

    # -- statistics ---------------------------------------------------------------------------
    def offsets(self) -> dict[int, int]:
        """Current phase of each enabled stream in bit times."""
        return {s.msg_id: s.offset for s in self._streams if s.period}

    def stream_stats(self) -> list[StreamReport]:
        rate = self.link.bit_rate
        reports = []
        for s in self._streams:
            st = s.stats
            reports.append(
                StreamReport(
                    s.msg_id, s.name, self.interval_us(s.msg_id), s.offset * 1e6 / rate, st.released, st.sent, st.dropped,
                    st.skipped, st.delay_sum / st.sent / rate if st.sent else 0.0, st.delay_max / rate, st.max_delay_ratio,
                )
            )
        return reports

    def link_stats(self, now: float | None = None) -> LinkStats:
        tick = self._now if now is None else self._tick(now)
        elapsed = tick / self.link.bit_rate
        busy = self._busy - max(0, self._link_free - tick)  # bit times actually on the wire by now
        return LinkStats(
            elapsed, self._bytes_sent, self._bytes_sent / elapsed if elapsed else 0.0, busy / tick if tick else 0.0,
            self._occupancy(tick), self._queue_max_bytes, self._queue_max_frames,
            sum(s.stats.dropped for s in self._streams), self.method, self.note,
        )


class TelemetryDriver:
    """Real-time loop: runs a scheduler against the clock and writes each frame when it starts."""

    def __init__(
        self, scheduler: TelemetryScheduler, write: Callable[[bytes], object],
        clock: Callable[[], float] = time.monotonic, sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        self.scheduler, self.write, self.clock, self.sleep = scheduler, write, clock, sleep

    def run_for(self, duration_s: float, max_sleep_s: float = 0.05) -> None:
        start = self.clock()
        self.scheduler.start(start)
        end = start + duration_s
        while True:
            now = self.clock()
            for frame in self.scheduler.advance(min(now, end)):
                self.write(frame.data)
            if now >= end:
                return
            wake = self.scheduler.next_event()
            self.sleep(max(0.0, min(max_sleep_s, end - now, (wake - now) if wake is not None else max_sleep_s)))
