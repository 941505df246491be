#!/usr/bin/env python3
"""Re-simulation speed: navigation (EKF) + GNC core re-run over a recorded flight, as a multiple of real time.

For each of `--rounds` rounds, `resimulate()` (c4d_resim.run) over the flight's whole journal, both ways:
in one process (navigation's share of the wall time, the core's, their sum) and with navigation in a
second process streaming its states to the core (c4d_resim.pipeline: the wall time; navigation's busy
time overlaps the core's), against the flight time re-simulated (the core's snapshot to its last
journalled tick). Loading and indexing the MCAP are timed apart (not part of the re-simulation).
Prints medians side by side, the ratio to the 20x target, whether every round was bit-exact, and the
platform-stall probe's worst oversleep (a stall there is the machine's, not c4d's).

Run under the graph lock: `flock /tmp/c4d_graph.lock python bench/resim_speed.py FLIGHT.mcap [--rounds 5]`.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "test" / "support"))
from stall_probe import StallProbe, worst_line  # noqa: E402

from c4d_resim import flight as flight_module  # noqa: E402
from c4d_resim.run import resimulate  # noqa: E402

TARGET = 20.0
JOURNALS = {"/navigation/journal", "/gnc/journal"}


def size_cost(path: str) -> tuple[int, int, int]:
    """(bytes with the journals, bytes without, bytes of the journals' payloads): the flight rewritten twice by
    the recorder's writer (same chunk size and zstd), with and without the journal topics."""
    from c4d_data.bag_reader import iter_messages, open_bag
    from c4d_data.bag_writer import BagWriter

    contents = open_bag(path)
    sizes, payload = [], 0
    with tempfile.TemporaryDirectory() as tmp:
        for keep in (True, False):
            out = Path(tmp) / f"{keep}.mcap"
            w = BagWriter(out)
            for name, topic in contents.topics.items():
                if keep or name not in JOURNALS:
                    w.add_topic(name, topic.type_name, topic.schema.data.decode() if topic.schema else "",
                                topic.offered_qos, topic.type_hash)
            for topic, m in iter_messages(contents):
                if topic.name in JOURNALS:
                    payload += len(m.data) if keep else 0
                    if not keep:
                        continue
                w.write(topic.name, m.data, m.log_time, m.publish_time)
            w.close()
            sizes.append(out.stat().st_size)
    return sizes[0], sizes[1], payload


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("flight", help="flight MCAP recorded with journals")
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args(argv)
    if args.rounds < 1:
        parser.error("--rounds must be >= 1")
    loads: list[float] = []
    walls: dict[int, list[float]] = {1: [], 2: []}
    navs: dict[int, list[float]] = {1: [], 2: []}
    flight_s, exact = 0.0, True
    probe = StallProbe()
    try:
        for _ in range(args.rounds):
            t0 = time.perf_counter()
            flight_module.load(args.flight)
            loads.append(time.perf_counter() - t0)
            for processes in (1, 2):
                r = resimulate(args.flight, processes=processes)
                flight_s, exact = r.flight_s, exact and r.exact
                walls[processes].append(r.wall_s)
                navs[processes].append(r.nav_wall_s)
    finally:
        stalls = probe.stop()
    wall, nav, load = statistics.median(walls[1]), statistics.median(navs[1]), statistics.median(loads)
    wall2, nav2 = statistics.median(walls[2]), statistics.median(navs[2])
    print(f"re-simulation of {Path(args.flight).name}: {flight_s:.1f} s of flight, {args.rounds} rounds (medians), "
          f"{'bit-exact in every round' if exact else 'NOT bit-exact'}")
    print(f"{'what':<40} {'wall s':>8} {'x real time':>12} {'vs 20x':>8}")
    for name, s in (("navigation (1 process)", nav), ("core (1 process)", wall - nav),
                    ("navigation + core, 1 process", wall),
                    ("navigation busy (2nd process)", nav2), ("navigation + core, 2 processes", wall2)):
        print(f"{name:<40} {s:>8.3f} {flight_s / s:>12.1f} {flight_s / s / TARGET:>7.2f}x")
    print(f"{'load + index (apart)':<40} {load:>8.3f}")
    with_j, without, payload = size_cost(args.flight)
    print(f"journal size cost: {with_j / 2**20:.2f} MiB with, {without / 2**20:.2f} MiB without the journal topics "
          f"(rewritten alike): +{100 * (with_j - without) / without:.2f} % (journal payloads {payload / 1024:.0f} KiB "
          "before zstd)")
    print(worst_line(stalls))
    return 0


if __name__ == "__main__":
    sys.exit(main())
