"""The thesis telemetry case (Table 3.3 → MAVLink) on a 57600-baud link: GCD+ phases vs zero phases,
in simulated time (exact, checked against c4d_sched's FIFO evaluator) and for real over a pty."""

from __future__ import annotations

import os
import select
import time
from collections import defaultdict

import pytest

from c4d_bridge_mavlink.signing import make_mavlink
from c4d_bridge_mavlink.telemetry import TelemetryDriver
from c4d_bridge_mavlink.telemetry_case import CASE, CASE_QUEUE_BYTES, case_scheduler, simulate
from c4d_bridge_mavlink.transport import open_endpoint
from c4d_sched.fifo import evaluate
from c4d_sched.model import Task, TaskSet


def test_frames_are_of_similar_size() -> None:
    assert len({m.msg_id for m in CASE}) == len(CASE) == 16
    assert all(abs(m.mavlink_frame - m.paparazzi_frame) <= 4 for m in CASE)


def test_gcdplus_no_overflow_and_delays_below_ten_percent() -> None:
    sched = simulate("gcdplus")
    reports = sched.stream_stats()
    assert all(r.dropped == 0 and r.sent == r.released > 0 for r in reports)
    assert max(r.max_delay_ratio for r in reports) < 0.10
    link = sched.link_stats()
    assert link.queue_max_bytes < CASE_QUEUE_BYTES and 0.7 < link.utilisation < 0.8
    # the link model is the exact FIFO of c4d_sched (all frames have their largest size here)
    streams = {s.msg_id: s for s in sched._streams}
    taskset = TaskSet(tuple(Task(r.name, streams[r.msg_id].period, streams[r.msg_id].wcet) for r in reports))
    exact = evaluate(taskset, [sched.offsets()[r.msg_id] for r in reports])
    assert [streams[r.msg_id].stats.delay_max for r in reports] == [t.max_delay for t in exact.tasks]


def test_zero_phases_overflow_and_delays_measured() -> None:
    zero, gcd = simulate("zero"), simulate("gcdplus")
    dropped = {r.name: r.dropped for r in zero.stream_stats() if r.dropped}
    worst = max(zero.stream_stats(), key=lambda r: r.max_delay_ratio)
    print(f"\nzero phases: dropped {dropped}, worst delay {worst.name} {worst.max_delay_ratio:.3f} of its period, "
          f"queue max {zero.link_stats().queue_max_bytes} B; GCD+: queue max {gcd.link_stats().queue_max_bytes} B")
    assert sum(dropped.values()) > 0
    assert zero.link_stats().queue_max_bytes > gcd.link_stats().queue_max_bytes


def test_real_pty_run_delivers_every_frame_on_time() -> None:
    """2 s of the case written for real to a 57600-baud serial endpoint on a pty; the far end parses
    every frame and time-stamps it. The pty does not throttle: the scheduler's link model does."""
    master, slave = os.openpty()
    endpoint = open_endpoint(f"serial:{os.ttyname(slave)}:57600")
    receiver = make_mavlink(255, 190)
    arrivals: dict[int, list[float]] = defaultdict(list)
    received_bytes = 0

    def read_for(seconds: float) -> None:
        nonlocal received_bytes
        end = time.monotonic() + seconds
        while True:
            ready, _, _ = select.select([master], [], [], max(0.0, end - time.monotonic()))
            if ready:
                data = os.read(master, 4096)
                now = time.monotonic()
                received_bytes += len(data)
                for msg in receiver.parse_buffer(data) or []:
                    arrivals[msg.get_msgId()].append(now)
            if time.monotonic() >= end:
                return

    try:
        sched = case_scheduler("gcdplus", endpoint.pack)
        TelemetryDriver(sched, endpoint.write, sleep=read_for).run_for(2.0)
        read_for(0.1)
        start = sched._t0
    finally:
        endpoint.close()
        os.close(master)
        os.close(slave)
    assert receiver.total_receive_errors == 0
    reports = {r.msg_id: r for r in sched.stream_stats()}
    late = []
    for message in CASE:
        report, times = reports[message.msg_id], arrivals[message.msg_id]
        assert report.dropped == 0 and len(times) == report.sent == report.released > 0, message.mavlink
        period = message.period_s
        offset = sched.offsets()[message.msg_id] / 57600
        late += [t - (start + offset + k * period) for k, t in enumerate(times)]
        if len(times) >= 3:  # drift-free: mean spacing is the period
            assert (times[-1] - times[0]) / (len(times) - 1) == pytest.approx(period, rel=0.02, abs=0.002), message.mavlink
    late.sort()
    assert late[0] >= 0 and late[len(late) // 2] < 0.010  # never early, median lateness small
    assert received_bytes / 2.0 <= 5760 * 1.02  # paced at 57600/10 bytes per second
    assert sum(r.sent for r in reports.values()) == sum(len(t) for t in arrivals.values()) > 350
