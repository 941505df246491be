"""Thesis telemetry case on a 57600-baud link: GCD+ vs zero vs Paparazzi phases, side by side.

What: the 16 Table 3.3 messages mapped to MAVLink (c4d_bridge_mavlink.telemetry_case) run through
the bridge's telemetry scheduler and its link-FIFO model for two hyperperiods (4 s, exact, in
simulated time), with a bounded send queue (default 256 bytes). Printed per message: frame size,
period, phase, drops and max delay / period for each method; then link utilisation, bytes/s,
queue high-water mark. With --real S it also runs GCD+ for S seconds for real over a pty (the
scheduler paces the bytes) and prints what the far end received.
Run: . ./env.sh && python bench/telemetry_link.py [--queue BYTES] [--real SECONDS]
"""

from __future__ import annotations

import argparse
import os
import select
import sys
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src" / "c4d_bridge_mavlink"))

from c4d_bridge_mavlink.signing import make_mavlink  # source tree on sys.path above
from c4d_bridge_mavlink.telemetry import TelemetryDriver
from c4d_bridge_mavlink.telemetry_case import CASE, CASE_QUEUE_BYTES, case_scheduler, simulate
from c4d_bridge_mavlink.transport import open_endpoint

METHODS = ("gcdplus", "zero", "paparazzi")


def compare(queue_bytes: int) -> None:
    runs = {method: simulate(method, 4.0, queue_bytes) for method in METHODS}
    reports = {method: {r.msg_id: r for r in run.stream_stats()} for method, run in runs.items()}
    head = f"{'Paparazzi':22} {'MAVLink':21} {'B':>3} {'T ms':>5}"
    for method in METHODS:
        head += f" | {method + ' O ms':>14} {'drop':>4} {'η/T':>6}"
    print(f"57600 baud, 10 bits/byte, send queue {queue_bytes} B, 4 s simulated (2 hyperperiods)\n")
    print(head)
    print("-" * len(head))
    for message in CASE:
        line = f"{message.paparazzi:22} {message.mavlink:21} {message.mavlink_frame:3} {message.period_s * 1000:5.0f}"
        for method in METHODS:
            r = reports[method][message.msg_id]
            line += f" | {r.offset_us / 1000:14.2f} {r.dropped:4} {r.max_delay_ratio:6.3f}"
        print(line)
    print("-" * len(head))
    for method, run in runs.items():
        stats, rs = run.link_stats(), reports[method].values()
        print(
            f"{method:10} dropped {stats.dropped:3}  max η/T {max(r.max_delay_ratio for r in rs):6.3f}  "
            f"streams with η/T ≥ 0.1: {sum(r.max_delay_ratio >= 0.1 for r in rs):2}  utilisation {stats.utilisation:.3f}  "
            f"{stats.bytes_per_second:6.0f} B/s  queue max {stats.queue_max_bytes:3} B / {stats.queue_max_frames:2} frames"
            + (f"  [{stats.note}]" if stats.note else "")
        )


def real_run(seconds: float) -> None:
    master, slave = os.openpty()
    endpoint = open_endpoint(f"serial:{os.ttyname(slave)}:57600")
    receiver = make_mavlink(255, 190)
    counts: Counter = Counter()
    total = 0
    first = last = None

    def read_for(duration: float) -> None:
        nonlocal total, first, last
        end = time.monotonic() + duration
        while True:
            if select.select([master], [], [], max(0.0, end - time.monotonic()))[0]:
                data = os.read(master, 4096)
                last = time.monotonic()
                first = first or last
                total += len(data)
                counts.update(m.get_msgId() for m in receiver.parse_buffer(data) or [])
            if time.monotonic() >= end:
                return

    try:
        sched = case_scheduler("gcdplus", endpoint.pack)
        TelemetryDriver(sched, endpoint.write, sleep=read_for).run_for(seconds)
        read_for(0.1)
    finally:
        endpoint.close()
        os.close(master)
        os.close(slave)
    sent = sum(r.sent for r in sched.stream_stats())
    stats = sched.link_stats()
    print(
        f"\nreal pty, GCD+, {seconds:.1f} s: sent {sent} frames, received {sum(counts.values())} "
        f"(parse errors {receiver.total_receive_errors}), {total / (last - first):.0f} B/s received, "
        f"model utilisation {stats.utilisation:.3f}, max η/T {max(r.max_delay_ratio for r in sched.stream_stats()):.3f}, "
        f"dropped {stats.dropped}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--queue", type=int, default=CASE_QUEUE_BYTES, help="send queue size in bytes")
    parser.add_argument("--real", type=float, default=0.0, help="also run GCD+ for real over a pty for this many seconds")
    args = parser.parse_args()
    if args.queue <= 0 or args.real < 0:
        parser.error("--queue must be > 0 and --real >= 0")
    compare(args.queue)
    if args.real:
        real_run(args.real)


if __name__ == "__main__":
    main()
