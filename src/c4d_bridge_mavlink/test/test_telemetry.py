"""Telemetry scheduler: frame sizes, link budget, hand-computed queue model, GCD+ phases, drift-free
releases, SET_MESSAGE_INTERVAL semantics, and the real-time driver."""

from __future__ import annotations

import random

import pytest

from c4d_bridge_mavlink.signing import make_mavlink, mavlink
from c4d_bridge_mavlink.telemetry import LinkBudget, TelemetryDriver, TelemetryScheduler, frame_bytes
from c4d_bridge_mavlink.telemetry_case import case_message
from c4d_sched.gcdplus import gcd_plus
from c4d_sched.model import Task, TaskSet

HB = mavlink.MAVLINK_MSG_ID_HEARTBEAT  # 21-byte frame
ST = mavlink.MAVLINK_MSG_ID_SYSTEM_TIME  # 24-byte frame
ATT = mavlink.MAVLINK_MSG_ID_ATTITUDE  # 40-byte frame


def packer():
    mav = make_mavlink(1, 1)

    def pack(msg: mavlink.MAVLink_message) -> bytes:
        data = msg.pack(mav)
        mav.seq = (mav.seq + 1) % 256
        return data

    return pack


def encoder(msg_id: int):
    return lambda: case_message(msg_id)


def scheduler(link: LinkBudget, streams: dict[int, int], **kw) -> TelemetryScheduler:
    sched = TelemetryScheduler(link, packer(), **kw)
    for msg_id, interval in streams.items():
        sched.add_stream(msg_id, interval, encoder(msg_id))
    return sched


def test_frame_sizes_from_pymavlink() -> None:
    assert frame_bytes(HB) == 21 == len(case_message(HB).pack(make_mavlink(1, 1)))
    assert frame_bytes(HB, signed=True) == 34
    assert frame_bytes(mavlink.MAVLINK_MSG_ID_SYS_STATUS) == 10 + 43 + 2  # extensions included
    with pytest.raises(ValueError, match="unknown MAVLink message id"):
        frame_bytes(60000)


def test_link_budget() -> None:
    serial = LinkBudget.serial(57600)
    assert (serial.bit_rate, serial.bits_per_byte, serial.bytes_per_second) == (57600, 10, 5760)
    assert serial.quantum_ticks == 288  # 5 ms is the first whole number of bit times that is a multiple of 1 ms
    assert LinkBudget.serial(115200).quantum_ticks == 576
    udp = LinkBudget.udp(20_000)
    assert (udp.bit_rate, udp.bits_per_byte, udp.quantum_ticks) == (160_000, 8, 160)
    assert LinkBudget.serial(57601).quantum_ticks == 58  # no whole-tick ms grid: ~1 ms
    for bad in (lambda: LinkBudget.serial(0), lambda: LinkBudget.udp(-5), lambda: LinkBudget(100, 9)):
        with pytest.raises(ValueError):
            bad()


def test_queue_model_hand_computed() -> None:
    """10 000 bit/s UART: HEARTBEAT = 210 bit times, SYSTEM_TIME = 240, ATTITUDE = 400; period 1000.
    All released together (zero phases) at t = 0: HB starts at 0, ST at 210, ATT at 450.
    A 70-byte FIFO: at t = 0 it holds HB 21 + ST 24 = 45 bytes, ATT (40) does not fit: dropped."""
    link = LinkBudget(10_000, 10)
    sched = scheduler(link, {HB: 100_000, ST: 100_000, ATT: 100_000}, method="zero", queue_bytes=70)
    sched.start(5.0)
    frames = sched.advance(5.0 + 0.0449)  # up to tick 449
    assert [(f.msg_id, round((f.start - 5.0) * 10_000)) for f in frames] == [(HB, 0), (ST, 210)]
    assert sched.advance(5.0 + 0.1)[0].msg_id == HB  # next period at tick 1000
    stats = {r.msg_id: r for r in sched.stream_stats()}
    # tick 1000: same situation (HB on the wire, 21 bytes left + ST 24), ATT dropped again
    assert (stats[ATT].dropped, stats[ATT].sent, stats[HB].sent, stats[ST].sent) == (2, 0, 2, 1)
    assert stats[ST].max_delay_s == pytest.approx(0.021) and stats[ST].max_delay_ratio == pytest.approx(0.21)
    assert stats[HB].max_delay_s == 0
    link_stats = sched.link_stats()
    assert link_stats.queue_max_bytes == 45 and link_stats.queue_max_frames == 2 and link_stats.dropped == 2
    # big enough FIFO: ATT waits 450 bit times, 0.45 of its period
    roomy = scheduler(link, {HB: 100_000, ST: 100_000, ATT: 100_000}, method="zero", queue_bytes=1000)
    roomy.start(0.0)
    assert [round(f.start * 10_000) for f in roomy.advance(0.0999)] == [0, 210, 450]
    assert {r.msg_id: r.max_delay_ratio for r in roomy.stream_stats()}[ATT] == pytest.approx(0.45)


def test_gcdplus_phases_remove_the_queueing() -> None:
    """Ω = 1000: ATTITUDE (400) in section Ψ1, HEARTBEAT and SYSTEM_TIME (period 2000) in Ψ2 on
    alternate cycles, Σδ = 640 ≤ Ω: the certificate holds, no frame ever waits."""
    link = LinkBudget(10_000, 10)
    sched = scheduler(link, {HB: 200_000, ST: 200_000, ATT: 100_000}, queue_bytes=64)
    sched.start(0.0)
    expected = gcd_plus(TaskSet((Task("HEARTBEAT", 2000, 210), Task("SYSTEM_TIME", 2000, 240), Task("ATTITUDE", 1000, 400))))
    assert expected.detail.certificate
    assert tuple(sched.offsets().values()) == expected.offsets
    sched.advance(2.0)
    assert all(r.max_delay_s == 0 and r.dropped == 0 and r.sent >= 10 for r in sched.stream_stats())
    assert sched.link_stats().utilisation == pytest.approx(0.4 + 450 / 2000, abs=0.01)
    zero = scheduler(link, {HB: 200_000, ST: 200_000, ATT: 100_000}, queue_bytes=64, method="zero")
    zero.start(0.0)
    zero.advance(2.0)
    assert sum(r.dropped for r in zero.stream_stats()) > 0  # the same streams all released at once overflow


def test_releases_are_drift_free_whatever_the_call_times() -> None:
    link = LinkBudget.serial(57600)
    streams = {HB: 20_000, ST: 40_000, ATT: 100_000}
    once = scheduler(link, streams)
    once.start(100.0)
    reference = once.advance(102.0)
    jittery = scheduler(link, streams)
    jittery.start(100.0)
    rng = random.Random(1)
    now, got = 100.0, []
    while now < 102.0:
        now = min(102.0, now + rng.uniform(0.0, 0.013))
        got += jittery.advance(now)
    assert [(f.msg_id, f.release, f.start, f.data) for f in got] == [(f.msg_id, f.release, f.start, f.data) for f in reference]
    offsets = once.offsets()
    for msg_id, interval in streams.items():
        period = interval * 57600 // 1_000_000
        releases = [f.release for f in reference if f.msg_id == msg_id]
        assert releases == [100.0 + (offsets[msg_id] + k * period) / 57600 for k in range(len(releases))]
        assert len(releases) >= 2.0 * 1e6 / interval - 1


def test_set_message_interval_semantics() -> None:
    link = LinkBudget.serial(57600)
    sched = scheduler(link, {HB: 1_000_000, ST: 200_000})
    sched.start(0.0)
    assert len(sched.advance(0.999)) == 1 + 5
    assert sched.set_interval(HB, -1, 1.0) == -1  # disable
    frames = sched.advance(2.0)
    assert {f.msg_id for f in frames} == {ST}
    assert sched.set_interval(HB, 250_000, 2.0) == 250_000
    assert sched.set_interval(ST, 333_333, 2.0) == 335_000  # rounded to the 5 ms grid of 57600 bit/s
    expected = gcd_plus(TaskSet((Task("HEARTBEAT", 14400, 210), Task("SYSTEM_TIME", 19296, 240))))
    assert tuple(sched.offsets().values()) == expected.offsets  # phases re-assigned for the new periods
    frames = sched.advance(4.0)
    hb = [f.release for f in frames if f.msg_id == HB]
    assert hb[0] == 2.0 + sched.offsets()[HB] / 57600  # new epoch = the tick of the change
    assert len(hb) == 9 and all(b - a == pytest.approx(0.25) for a, b in zip(hb, hb[1:], strict=False))
    assert sched.set_interval(HB, 0, 4.0) == 1_000_000  # default restored
    assert sched.set_interval(HB, 1, 4.0) == 5000  # at least one quantum, and never shorter than a frame
    assert sched.interval_us(ST) == 335_000
    for bad in (float("nan"), float("inf"), -2, 10**12, "100"):
        with pytest.raises(ValueError):
            sched.set_interval(HB, bad, 4.0)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="no telemetry stream"):
        sched.set_interval(ATT, 100_000, 4.0)


def test_skipped_encodes_and_adding_streams() -> None:
    sched = TelemetryScheduler(LinkBudget.serial(57600), packer())
    sched.add_stream(HB, 100_000, lambda: None)
    with pytest.raises(ValueError, match="twice"):
        sched.add_stream(HB, 100_000, lambda: None)
    sched.add_stream(ST, -1, encoder(ST))  # off by default
    sched.start(0.0)
    assert sched.advance(0.999) == []
    (hb,) = [r for r in sched.stream_stats() if r.msg_id == HB]
    assert (hb.released, hb.skipped, hb.sent) == (10, 10, 0)
    sched.add_stream(ATT, 100_000, encoder(ATT))
    assert [f.msg_id for f in sched.advance(1.998)] == [ATT] * 10  # from a new epoch at 0.999 s


def test_huge_hyperperiods_stay_cheap() -> None:
    """Untrusted intervals with an enormous hyperperiod: GCD+ without the exact order selection."""
    sched = scheduler(LinkBudget.serial(57600), {HB: 20_000, ST: 59_995_000, ATT: 59_985_000})
    sched.start(0.0)
    assert "window too large" in sched.note
    assert len(sched.advance(1.0)) > 50


def test_real_time_driver_paces_frames() -> None:
    sched = scheduler(LinkBudget.serial(57600), {HB: 20_000, ST: 50_000})
    written: list[bytes] = []
    TelemetryDriver(sched, written.append).run_for(0.3)
    assert 15 + 6 <= len(written) <= 16 + 7
    assert all(r.dropped == 0 for r in sched.stream_stats())
