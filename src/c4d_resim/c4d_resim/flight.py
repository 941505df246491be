"""A recorded flight as re-simulation needs it: the nodes' journals and snapshots, and every input sample
indexed by its stamp (the key the journals use).

Why an index by stamp: the journal says "navigation consumed the baro sample stamped t", not where it
sits in the file; the recorder's log time is its own receive time, not the node's.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from c4d_data.bag_reader import BagError, iter_messages, open_bag
from c4d_gnc import journal as jr

NAV_JOURNAL, CORE_JOURNAL = "/navigation/journal", "/gnc/journal"
IMU, STATE, ACTUATORS, STATUS = "/perception/imu", "/navigation/state", "/control/actuators", "/vehicle/status"
SENSORS = {"gps": "/perception/gps", "external_gnss": "/navigation/external/gnss", "baro": "/perception/baro",
           "mag": "/perception/mag", "range": "/perception/range_down", "surroundings": "/perception/surroundings"}
SETPOINTS = {1: "/guidance/setpoint", 2: "/guidance/pilot", 3: "/guidance/offboard"}  # SetpointSource values
REQUIRED = (NAV_JOURNAL, CORE_JOURNAL, IMU, STATE, ACTUATORS)
STAMPED = (IMU, STATE, *SENSORS.values(), *SETPOINTS.values())


class FlightError(ValueError):
    """The file cannot be re-simulated; str() is one line."""


@dataclass
class Journal:
    """One node's journal: its first snapshot (state, the last batch before it) and the batches after it."""

    snapshot: Any = None
    after_seq: int = -1
    batches: list[tuple[int, bytes]] = field(default_factory=list)  # (seq, payload) after the snapshot, in seq order
    lost: int = 0  # batches missing between the snapshot and the end (seq gaps)


@dataclass
class Flight:
    path: Path
    by_stamp: dict[str, dict[int, bytes]]  # topic -> stamp ns -> raw CDR
    logged: dict[str, list[tuple[int, bytes]]]  # recorded navigation/state, control/actuators, vehicle/status
    nav: Journal
    core: Journal
    others: list[tuple[str, int, int, bytes]]  # (topic, log, publish, raw) of everything else, to copy
    topics: dict[str, Any]


def _journal(name: str, payloads: list[bytes]) -> Journal:
    j = Journal()
    batches: dict[int, bytes] = {}
    parts: dict[int, tuple[int, dict[int, bytes]]] = {}  # after_seq -> (count, index -> slice)
    for payload in payloads:
        try:
            kind, seq = jr.parse_header(payload)
            if kind == jr.SNAPSHOT and j.snapshot is None:
                j.after_seq, j.snapshot = jr.read_snapshot(payload)
            elif kind == jr.SNAPSHOT_PART:
                after, index, count, piece = jr.read_part(payload)
                parts.setdefault(after, (count, {}))[1][index] = piece
            elif kind == jr.JOURNAL:
                batches[seq] = payload
        except jr.JournalError as exc:
            raise FlightError(f"{name}: {exc}") from None
    if j.snapshot is None and parts:  # the first snapshot published in parts
        after = min(parts)
        try:
            j.after_seq, j.snapshot = jr.read_snapshot_parts(parts[after][1], parts[after][0], after)
        except jr.JournalError as exc:
            raise FlightError(f"{name}: {exc}") from None
    if j.snapshot is None:
        raise FlightError(f"{name} holds no snapshot: the file does not cover an arm (recorded before the journal "
                          "existed, or cut before take-off)")
    seqs = sorted(s for s in batches if s > j.after_seq)
    j.batches = [(s, batches[s]) for s in seqs]
    j.lost = (seqs[-1] - j.after_seq - len(seqs)) if seqs else 0
    return j


def load(path: str | Path) -> Flight:
    """Read and index a flight; FlightError / BagError (one line) for a file resim cannot use."""
    contents = open_bag(path)
    if not contents.complete:
        raise BagError(f"{path}: truncated or interrupted recording ({contents.problem}); run `repair {path}` first")
    missing = [t for t in REQUIRED if t not in contents.topics]
    if missing:
        raise FlightError(f"{path}: not a c4d flight recording with journals: missing topic(s) {', '.join(missing)}")
    by_stamp: dict[str, dict[int, bytes]] = {t: {} for t in STAMPED}
    logged: dict[str, list[tuple[int, bytes]]] = {STATE: [], ACTUATORS: [], STATUS: []}
    journals: dict[str, list[bytes]] = {NAV_JOURNAL: [], CORE_JOURNAL: []}
    others = []
    for topic, m in iter_messages(contents):
        name, data = topic.name, bytes(m.data)
        if name in journals:
            journals[name].append(_uint8_array(data))
            continue
        if name in by_stamp and len(data) >= 12:
            by_stamp[name][jr.cdr_stamp_ns(data)] = data
        if name in logged:
            logged[name].append((m.log_time, data))
        if name not in (STATE, ACTUATORS):
            others.append((name, m.log_time, m.publish_time, data))
    return Flight(contents.path, by_stamp, logged, _journal(NAV_JOURNAL, journals[NAV_JOURNAL]),
                  _journal(CORE_JOURNAL, journals[CORE_JOURNAL]), others, contents.topics)


def _uint8_array(data: bytes) -> bytes:
    """The data field of a serialized std_msgs/UInt8MultiArray (layout: dim sequence, data_offset, data)."""
    import struct

    try:
        (ndim,) = struct.unpack_from("<I", data, 4)
        i = 8
        for _ in range(ndim):  # MultiArrayDimension: string label, uint32 size, uint32 stride
            (n,) = struct.unpack_from("<I", data, i)
            i = (i + 4 + n + 3) & ~3
            i += 8
        i += 4  # data_offset
        (n,) = struct.unpack_from("<I", data, i)
        return data[i + 4:i + 4 + n]
    except struct.error:
        raise FlightError("journal message is not a std_msgs/UInt8MultiArray") from None
