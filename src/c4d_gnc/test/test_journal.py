"""The input consumption journal (c4d_gnc.journal): records round-trip exactly, channels re-anchor when a
delta would not fit, each batch decodes alone, snapshots refuse foreign classes."""

from __future__ import annotations

import os
import pickle

import pytest

from c4d_gnc import journal as jr
from c4d_gnc.gnc import GncCore


def test_records_round_trip_with_deltas_and_re_anchoring():
    w = jr.JournalWriter()
    t0 = 1_795_000_000_123_456_789
    w.stamp(jr.N_IMU, t0)
    w.stamp(jr.N_IMU, t0 + 2_000_000)
    w.stamp(jr.N_IMU, t0 + 10_000_000_000)  # 10 s gap: beyond int32 ns, a BASE record re-anchors
    w.gnss(True, t0 - 50_000_000)
    w.external(jr.EXTERNAL_POSE, None)
    w.status(jr.STATUS_ARMED | jr.STATUS_STATION_KEEPING)
    w.setpoint(1, t0 + 1, t0 - 3)
    w.command(t0 + 2, 3, 4, True, 2.5)
    w.surroundings(t0 + 3, t0 - 7)
    w.blob(jr.C_FENCE, b"\x00\x01fence")
    w.tick(70_000, t0 + 4)  # a tick index beyond u16 from 0: re-anchored
    w.tick(70_001, t0 + 2_000_004)
    first = w.take()
    assert first is not None and w.take() is None
    w.stamp(jr.C_GYRO, t0)
    second = w.take()
    assert jr.parse_header(first) == (jr.JOURNAL, 0) and jr.parse_header(second) == (jr.JOURNAL, 1)
    assert list(jr.records(first)) == [
        (jr.N_IMU, t0), (jr.N_IMU, t0 + 2_000_000), (jr.N_IMU, t0 + 10_000_000_000), (jr.N_GNSS, True, t0 - 50_000_000),
        (jr.N_EXTERNAL, jr.EXTERNAL_POSE, None), (jr.N_STATUS, 3), (jr.C_SETPOINT, 1, t0 + 1, t0 - 3),
        (jr.C_COMMAND, t0 + 2, 3, 4, True, 2.5), (jr.C_SURROUNDINGS, t0 + 3, t0 - 7), (jr.C_FENCE, b"\x00\x01fence"),
        (jr.C_TICK, 70_000, t0 + 4), (jr.C_TICK, 70_001, t0 + 2_000_004)]
    assert list(jr.records(second)) == [(jr.C_GYRO, t0)]  # the second batch decodes without the first
    assert jr.stamp_s(t0) == 1_795_000_000 + 123_456_789 * 1e-9  # the node's float, bit for bit


def test_imu_records_cost_about_five_bytes():
    w = jr.JournalWriter()
    for i in range(500):
        w.stamp(jr.N_IMU, 1_795_000_000_000_000_000 + i * 2_000_000)
    assert len(w.take()) < 500 * 5 + 40


def test_bad_payloads_and_snapshots_are_refused():
    with pytest.raises(jr.JournalError, match="magic"):
        jr.parse_header(b"XXXX\x00\x00\x00\x00\x00")
    w = jr.JournalWriter()
    w.stamp(jr.N_IMU, 5)
    payload = w.take()
    with pytest.raises(jr.JournalError, match="truncated"):
        list(jr.records(payload[:-2]))
    evil = jr.HEADER.pack(jr.MAGIC, jr.SNAPSHOT, 0) + jr.AFTER.pack(0) + pickle.dumps(os.system)
    with pytest.raises(jr.JournalError, match="never holds"):
        jr.read_snapshot(evil)


def test_snapshot_round_trip_of_the_core():
    from c4d_gnc.core_config import load_core_config

    cfg = load_core_config()
    core = GncCore(cfg.airframe, cfg.schedule.tick_us / 1e6)
    w = jr.JournalWriter()
    w.stamp(jr.C_GYRO, 1)
    batch, snap = w.snapshot({"core": core, "cfg": cfg})
    assert jr.parse_header(batch)[0] == jr.JOURNAL
    after, state = jr.read_snapshot(snap)
    assert after == 0 and isinstance(state["core"], GncCore) and state["cfg"].schedule == cfg.schedule


def test_a_snapshot_in_parts_reads_back_whole_and_refuses_a_missing_part():
    """Nodes publish their arm snapshot as <= 16 KiB parts, one per flush: a 200 KB message in one burst
    overflowed the recorder's loopback socket and lost the best-effort samples sent at that instant."""
    w = jr.JournalWriter()
    w.tick(1, 1_000_000)
    state = {"big": list(range(20000)), "name": "nav"}
    out = w.snapshot_parts(state)
    assert jr.parse_header(out[0])[0] == jr.JOURNAL  # the pending batch first
    parts = [jr.read_part(p) for p in out[1:]]
    assert len(parts) > 3 and all(len(p) <= jr.HEADER.size + jr.PART.size + jr.SNAPSHOT_PART_BYTES for p in out[1:])
    after, _, count, _ = parts[0]
    assert after == jr.parse_header(out[0])[1] and count == len(parts)
    pieces = {index: piece for _, index, _, piece in reversed(parts)}  # any arrival order
    assert jr.read_snapshot_parts(pieces, count, after) == (after, state)
    del pieces[1]
    with pytest.raises(jr.JournalError, match="1 of"):
        jr.read_snapshot_parts(pieces, count, after)


def test_a_queued_snapshot_goes_out_one_payload_per_flush_after_each_batch():
    """What both nodes publish at each journal flush: the batch that is pending, then one queued snapshot payload."""
    w = jr.JournalWriter()
    w.tick(1, 1_000_000)
    w.queue_snapshot({"big": list(range(20000))})
    queued = len(w.outbox)
    assert queued > 3
    flushes = []
    for k in range(queued + 2):
        w.tick(k + 2, (k + 2) * 1_000_000)
        flushes.append(w.flush())
    assert all(len(f) == 2 for f in flushes[:queued]) and all(len(f) == 1 for f in flushes[queued:])
    assert all(jr.parse_header(f[0])[0] == jr.JOURNAL for f in flushes)  # each flush's own batch first
    assert jr.parse_header(flushes[0][1])[0] == jr.JOURNAL  # the batch pending when the snapshot was taken
    assert all(jr.parse_header(f[1])[0] == jr.SNAPSHOT_PART for f in flushes[1:queued]) and not w.outbox
