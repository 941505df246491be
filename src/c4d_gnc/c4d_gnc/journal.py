"""Input consumption journal of the navigation and core nodes, for deterministic re-simulation (`resim`).

ROS-free. Why: a recorded flight holds every input sample, but not which sample a node used when —
navigation's callbacks interleave IMU, GNSS, baro, ... in DDS arrival order, the core's tick reads
the newest gyro and state drained at its input phase, at a clock time no topic carries, and the
commands it serves are service calls no recorder sees. The journal is that missing part, written by
the nodes as they consume: one record per consumed input (identified by its sample stamp, not its
content: the content is in the recording), the core's tick index and clock per tick, commands with
their fields, fences with their bytes, live retunes; plus one snapshot of the node's ROS-free state
(pickled) when the vehicle arms — the start point of a re-simulation (the file begins 1 s before arm;
what happened since boot is not in it).

Wire format (the payload of a std_msgs/UInt8MultiArray on `navigation/journal` / `gnc/journal`):
  header  MAGIC (4 bytes) | kind (u8: JOURNAL or SNAPSHOT) | seq (u32: batch number, gaps = a lost batch)
  JOURNAL  records: kind (u8) + kind-specific little-endian fields (RECORDS); stamps are integer
           nanoseconds coded as int32 deltas against a per-channel base (BASE records re-anchor a
           channel whose delta would not fit): ~5 bytes per IMU sample, ~14 per core tick, before zstd.
  SNAPSHOT after_seq (u32: the last batch consumed before it) + pickle of the node's state.
  SNAPSHOT_PART  after_seq (u32), index (u16), count (u16) + a <= 16 KiB slice of that pickle. The nodes publish a
           snapshot as parts, one per journal flush (10 Hz): sent whole, navigation's 200 KB burst overflowed the
           recorder's loopback UDP socket and best-effort samples published at that instant were lost.
Snapshots are read back with a restricted unpickler (only c4d, numpy and plain container classes).
"""

from __future__ import annotations

import io
import pickle
import struct
import types
from collections import deque
from collections.abc import Iterator
from typing import Any

MAGIC = b"C4DJ"
JOURNAL, SNAPSHOT, SNAPSHOT_PART = 0, 1, 2
HEADER = struct.Struct("<4sBI")
AFTER = struct.Struct("<I")
PART = struct.Struct("<IHH")  # after_seq, index, count
SNAPSHOT_PART_BYTES = 16 * 1024

# channels of the delta-coded stamps
CH_IMU, CH_GNSS, CH_BARO, CH_MAG, CH_RANGE, CH_EXT, CH_NOW, CH_GYRO, CH_STATE, CH_SURROUND = range(10)
CH_SETPOINT = 10  # + source (c4d_common.vehicle.SetpointSource, < 6)
CHANNELS = 16

# record kinds: (name, struct of the fields after the kind byte)
BASE = 0  # channel u8, absolute int64
N_IMU, N_GNSS, N_BARO, N_MAG, N_RANGE, N_EXTERNAL, N_STATUS, N_RETUNE = 1, 2, 3, 4, 5, 6, 7, 8
C_TICK, C_GYRO, C_STATE, C_SETPOINT, C_COMMAND, C_SURROUNDINGS, C_FENCE, C_RETUNE = 16, 17, 18, 19, 20, 21, 22, 23
EXTERNAL_ODOMETRY, EXTERNAL_POSE = 0, 1
STATUS_ARMED, STATUS_STATION_KEEPING = 1, 2
RECORDS: dict[int, struct.Struct] = {
    BASE: struct.Struct("<Bq"),
    N_IMU: struct.Struct("<i"), N_GNSS: struct.Struct("<Bi"), N_BARO: struct.Struct("<i"), N_MAG: struct.Struct("<i"),
    N_RANGE: struct.Struct("<i"), N_EXTERNAL: struct.Struct("<BBi"),  # kind, valid stamp (0: unreadable), stamp
    N_STATUS: struct.Struct("<B"),
    N_RETUNE: struct.Struct("<I"),  # length of the pickled {ekf.<field>: value} that follows (before its IMU record)
    C_TICK: struct.Struct("<Hi"),  # k - previous k, now
    C_GYRO: struct.Struct("<i"), C_STATE: struct.Struct("<i"),
    C_SETPOINT: struct.Struct("<Bii"),  # source, now, setpoint stamp
    C_COMMAND: struct.Struct("<iBBBd"),  # now, command, mode, force, altitude
    C_SURROUNDINGS: struct.Struct("<ii"),  # now, scan stamp
    C_FENCE: struct.Struct("<I"),  # length of the serialized Geofence that follows
    C_RETUNE: struct.Struct("<I"),  # length of the pickled {name: value} that follows
}
STAMP_CHANNEL = {N_IMU: CH_IMU, N_BARO: CH_BARO, N_MAG: CH_MAG, N_RANGE: CH_RANGE, C_GYRO: CH_GYRO,
                 C_STATE: CH_STATE}
INT32 = 1 << 31


class JournalError(ValueError):
    """A journal message that cannot be read (wrong magic, truncated record, unknown kind)."""


def stamp_ns(sec: int, nanosec: int) -> int:
    return sec * 1_000_000_000 + nanosec


def stamp_s(ns: int) -> float:
    """The float a node computes from the stamp (sec + nanosec * 1e-9): bit-identical."""
    sec, nanosec = divmod(ns, 1_000_000_000)
    return sec + nanosec * 1e-9


class JournalWriter:
    """Appends records to the current batch; `take()` returns the batch's payload (None when empty).

    Cheap enough for the 500 Hz paths (~1 µs a record): a struct pack into a bytearray."""

    def __init__(self) -> None:
        self.buf = bytearray()
        self.base = [0] * CHANNELS
        self.seq = 0
        self.k = 0
        self.outbox: deque[bytes] = deque()  # a queued snapshot's payloads, published one per flush

    def queue_snapshot(self, state: Any) -> None:
        """Queue `snapshot_parts(state)`; `flush()` hands them out one at a time (a whole snapshot in one burst
        overflowed the recorder's loopback socket)."""
        self.outbox.extend(self.snapshot_parts(state))

    def flush(self) -> list[bytes]:
        """What a node publishes at each journal flush, in order: the pending batch, then one queued payload."""
        out = [p for p in (self.take(),) if p is not None]
        if self.outbox:
            out.append(self.outbox.popleft())
        return out

    def _delta(self, channel: int, ns: int) -> int:
        d = ns - self.base[channel]
        if not -INT32 <= d < INT32:
            self.buf += bytes((BASE,)) + RECORDS[BASE].pack(channel, ns)
            d = 0
        self.base[channel] = ns
        return d

    def stamp(self, kind: int, ns: int) -> None:
        """A record whose only field is a stamp (N_IMU, N_BARO, N_MAG, N_RANGE, C_GYRO, C_STATE)."""
        d = self._delta(STAMP_CHANNEL[kind], ns)
        self.buf.append(kind)
        self.buf += RECORDS[kind].pack(d)

    def gnss(self, external: bool, ns: int) -> None:
        d = self._delta(CH_GNSS, ns)
        self.buf.append(N_GNSS)
        self.buf += RECORDS[N_GNSS].pack(int(external), d)

    def external(self, which: int, ns: int | None) -> None:
        d = 0 if ns is None else self._delta(CH_EXT, ns)
        self.buf.append(N_EXTERNAL)
        self.buf += RECORDS[N_EXTERNAL].pack(which, ns is not None, d)

    def status(self, flags: int) -> None:
        self.buf.append(N_STATUS)
        self.buf += RECORDS[N_STATUS].pack(flags)

    def tick(self, k: int, now_ns: int) -> None:
        dk = k - self.k
        if not 0 <= dk < 1 << 16:
            self.buf += bytes((BASE,)) + RECORDS[BASE].pack(CHANNELS, k)  # channel CHANNELS: the tick index
            dk = 0
        self.k = k
        d = self._delta(CH_NOW, now_ns)
        self.buf.append(C_TICK)
        self.buf += RECORDS[C_TICK].pack(dk, d)

    def setpoint(self, source: int, now_ns: int, ns: int) -> None:
        dn, ds = self._delta(CH_NOW, now_ns), self._delta(CH_SETPOINT + source, ns)
        self.buf.append(C_SETPOINT)
        self.buf += RECORDS[C_SETPOINT].pack(source, dn, ds)

    def command(self, now_ns: int, command: int, mode: int, force: bool, altitude: float) -> None:
        dn = self._delta(CH_NOW, now_ns)
        self.buf.append(C_COMMAND)
        self.buf += RECORDS[C_COMMAND].pack(dn, command, mode, force, altitude)

    def surroundings(self, now_ns: int, ns: int) -> None:
        dn, ds = self._delta(CH_NOW, now_ns), self._delta(CH_SURROUND, ns)
        self.buf.append(C_SURROUNDINGS)
        self.buf += RECORDS[C_SURROUNDINGS].pack(dn, ds)

    def blob(self, kind: int, data: bytes) -> None:
        """C_FENCE (serialized Geofence), C_RETUNE / N_RETUNE (pickled changes)."""
        self.buf.append(kind)
        self.buf += RECORDS[kind].pack(len(data))
        self.buf += data

    def take(self) -> bytes | None:
        if not self.buf:
            return None
        payload = HEADER.pack(MAGIC, JOURNAL, self.seq) + self.buf
        self.seq += 1
        self.buf = bytearray()
        self.base, self.k = [0] * CHANNELS, 0  # each batch decodes alone (a re-simulation starts mid-stream)
        return bytes(payload)

    def snapshot(self, state: Any) -> list[bytes]:
        """The pending batch (if any) then a SNAPSHOT of `state` taken after it: publish both, in order."""
        out = [p for p in (self.take(),) if p is not None]
        out.append(HEADER.pack(MAGIC, SNAPSHOT, self.seq) + AFTER.pack(self.seq - 1 & 0xFFFFFFFF)
                   + _dumps(state))
        return out

    def snapshot_parts(self, state: Any) -> list[bytes]:
        """As `snapshot`, the state cut into SNAPSHOT_PART payloads of <= SNAPSHOT_PART_BYTES (the nodes publish
        one per flush; `read_snapshot_parts` joins them)."""
        out = [p for p in (self.take(),) if p is not None]
        after, data, size = self.seq - 1 & 0xFFFFFFFF, _dumps(state), SNAPSHOT_PART_BYTES
        count = max(1, -(-len(data) // size))
        head = HEADER.pack(MAGIC, SNAPSHOT_PART, self.seq)
        out += [head + PART.pack(after, i, count) + data[i * size:(i + 1) * size] for i in range(count)]
        return out


def parse_header(payload: bytes) -> tuple[int, int]:
    """(kind, seq) of a journal message; JournalError when it is not one."""
    if len(payload) < HEADER.size:
        raise JournalError(f"journal message of {len(payload)} bytes is shorter than its header")
    magic, kind, seq = HEADER.unpack_from(payload)
    if magic != MAGIC or kind not in (JOURNAL, SNAPSHOT, SNAPSHOT_PART):
        raise JournalError("not a c4d journal message (magic or kind)")
    return kind, seq


def records(payload: bytes) -> Iterator[tuple]:
    """The records of a JOURNAL payload as (kind, *absolute fields): stamps in integer ns (each batch
    decodes alone: its channels start at 0), C_TICK with the tick index, C_FENCE / C_RETUNE with their bytes."""
    base = [0] * (CHANNELS + 1)  # the last: the tick index
    i, end = HEADER.size, len(payload)
    try:
        while i < end:
            kind = payload[i]
            i += 1
            rec = RECORDS.get(kind)
            if rec is None:
                raise JournalError(f"unknown journal record kind {kind}")
            fields = rec.unpack_from(payload, i)
            i += rec.size
            if kind == BASE:
                base[fields[0]] = fields[1]
                continue
            if kind in STAMP_CHANNEL:
                ch = STAMP_CHANNEL[kind]
                base[ch] += fields[0]
                yield kind, base[ch]
            elif kind == N_GNSS:
                base[CH_GNSS] += fields[1]
                yield kind, bool(fields[0]), base[CH_GNSS]
            elif kind == N_EXTERNAL:
                if fields[1]:
                    base[CH_EXT] += fields[2]
                yield kind, fields[0], base[CH_EXT] if fields[1] else None
            elif kind == N_STATUS:
                yield kind, fields[0]
            elif kind == C_TICK:
                base[CHANNELS] += fields[0]
                base[CH_NOW] += fields[1]
                yield kind, base[CHANNELS], base[CH_NOW]
            elif kind == C_SETPOINT:
                base[CH_NOW] += fields[1]
                base[CH_SETPOINT + fields[0]] += fields[2]
                yield kind, fields[0], base[CH_NOW], base[CH_SETPOINT + fields[0]]
            elif kind == C_COMMAND:
                base[CH_NOW] += fields[0]
                yield kind, base[CH_NOW], fields[1], fields[2], bool(fields[3]), fields[4]
            elif kind == C_SURROUNDINGS:
                base[CH_NOW] += fields[0]
                base[CH_SURROUND] += fields[1]
                yield kind, base[CH_NOW], base[CH_SURROUND]
            else:  # C_FENCE, C_RETUNE, N_RETUNE
                n = fields[0]
                if i + n > end:
                    raise JournalError("truncated journal record")
                yield kind, bytes(payload[i:i + n])
                i += n
    except struct.error:
        raise JournalError("truncated journal record") from None


SAFE_MODULES = ("c4d_gnc.", "c4d_common.", "c4d_sched.", "numpy", "collections", "builtins", "enum", "datetime",
                "pathlib")
SAFE_FUNCTIONS = {("numpy.core.multiarray", "_reconstruct"), ("numpy._core.multiarray", "_reconstruct"),
                  ("numpy.core.multiarray", "scalar"), ("numpy._core.multiarray", "scalar"),
                  ("numpy._core.numeric", "_frombuffer"), ("numpy.core.numeric", "_frombuffer")}


def _bound(owner: Any, name: str) -> Any:
    """A bound method of a c4d object (how a snapshot stores e.g. the EKF's on_correction callback)."""
    if not type(owner).__module__.startswith(("c4d_gnc.", "c4d_common.", "c4d_sched.")):
        raise JournalError(f"snapshot binds a method of {type(owner).__name__}, which is not a c4d class")
    return getattr(owner, name)


class _SnapshotPickler(pickle.Pickler):
    """Stores bound methods as (_bound, owner, name): the reader then needs no builtins.getattr."""

    def reducer_override(self, obj: Any) -> Any:
        if isinstance(obj, types.MethodType):
            return _bound, (obj.__self__, obj.__func__.__name__)
        return NotImplemented


def _dumps(state: Any) -> bytes:
    out = io.BytesIO()
    _SnapshotPickler(out, protocol=pickle.HIGHEST_PROTOCOL).dump(state)
    return out.getvalue()


class _SafeUnpickler(pickle.Unpickler):
    """Resolves only classes of c4d, numpy and plain containers, numpy's array rebuilders and _bound: a crafted
    file cannot name a function (os.system, eval, ...) to call."""

    def find_class(self, module: str, name: str) -> Any:
        if module == __name__ and name == "_bound":
            return _bound
        if (module, name) in SAFE_FUNCTIONS:
            return super().find_class(module, name)
        if any(module == m.rstrip(".") or module.startswith(m) for m in SAFE_MODULES):
            found = super().find_class(module, name)
            if isinstance(found, type):
                return found
        raise JournalError(f"snapshot refers to {module}.{name}, which a c4d snapshot never holds")


def read_snapshot(payload: bytes) -> tuple[int, Any]:
    """(after_seq, state) of a SNAPSHOT payload; JournalError when unreadable."""
    kind, _ = parse_header(payload)
    if kind != SNAPSHOT or len(payload) < HEADER.size + AFTER.size:
        raise JournalError("not a journal snapshot")
    (after,) = AFTER.unpack_from(payload, HEADER.size)
    return after, _loads(payload[HEADER.size + AFTER.size:])


def read_part(payload: bytes) -> tuple[int, int, int, bytes]:
    """(after_seq, index, count, slice) of a SNAPSHOT_PART payload; JournalError when it is not one."""
    kind, _ = parse_header(payload)
    if kind != SNAPSHOT_PART or len(payload) < HEADER.size + PART.size:
        raise JournalError("not a journal snapshot part")
    after, index, count = PART.unpack_from(payload, HEADER.size)
    if count == 0 or index >= count:
        raise JournalError(f"snapshot part {index} of {count}")
    return after, index, count, payload[HEADER.size + PART.size:]


def read_snapshot_parts(parts: dict[int, bytes], count: int, after: int) -> tuple[int, Any]:
    """(after_seq, state) from the slices of one snapshot by index; JournalError when one is missing."""
    missing = [i for i in range(count) if i not in parts]
    if missing:
        raise JournalError(f"snapshot incomplete: {len(missing)} of {count} parts missing")
    return after, _loads(b"".join(parts[i] for i in range(count)))


def _loads(data: bytes) -> Any:
    try:
        return _SafeUnpickler(io.BytesIO(data)).load()
    except JournalError:
        raise
    except Exception as exc:  # whatever a damaged pickle raises: one line
        raise JournalError(f"unreadable snapshot: {type(exc).__name__}: {exc}") from None


_CDR_STAMP = struct.Struct("<iI")  # header.stamp right after the 4-byte CDR encapsulation (little endian)


def cdr_stamp_ns(raw: bytes) -> int:
    """The header stamp [ns] of a serialized stamped message (its first field)."""
    sec, nanosec = _CDR_STAMP.unpack_from(raw, 4)
    return sec * 1_000_000_000 + nanosec


def safe_loads(data: bytes) -> Any:
    """Unpickle with the restricted unpickler (C_RETUNE records); JournalError when unreadable."""
    try:
        return _SafeUnpickler(io.BytesIO(data)).load()
    except JournalError:
        raise
    except Exception as exc:
        raise JournalError(f"unreadable journal record: {type(exc).__name__}: {exc}") from None
