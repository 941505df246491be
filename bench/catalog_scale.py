#!/usr/bin/env python3
"""Fleet catalog at scale (issue 21 item 5): index 1000 synthetic flights and report files/s,
MB/s and peak memory, for 1 worker and for all CPUs side by side, then the re-index (nothing
new) and the peak memory of one short vs one long flight (memory must not grow with the file).

Flights: `--unique` distinct survey flights written with the project's MCAP writer
(c4d_data.catalog_synthetic, 500 Hz estimate/actuators/IMU, durations spread over
`--min-s`..`--max-s`, ~0.23 MB/s like a SITL recording), hard-linked under 4 vehicle folders up to
`--count` files (generating 1000 distinct files would take longer than indexing them; every link
is still opened, decompressed and decoded). Each round indexes into a fresh database with the
installed `catalog` command; peak memory is the largest process of the run (ru_maxrss of the
catalog process and its pool workers, from wait4). Medians over `--rounds`, with the
platform-stall probe's worst oversleep (a stall there is the machine's, not the catalog's).

Run under the graph lock: `flock /tmp/c4d_graph.lock python bench/catalog_scale.py [--count 1000]`.
"""

from __future__ import annotations

import argparse
import os
import random
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "test" / "support"))
from stall_probe import StallProbe, worst_line  # noqa: E402

from c4d_data.catalog_synthetic import FlightSpec, write_flight  # noqa: E402


def catalog_exe() -> str:
    exe = ROOT / "install" / "c4d_data" / "lib" / "c4d_data" / "catalog"
    if not exe.is_file():
        sys.exit("catalog_scale: error: catalog not installed (colcon build --packages-select c4d_data)")
    return str(exe)


def run_measured(args: list[str]) -> tuple[float, float, str]:
    """(wall s, peak RSS MiB of the largest process, stdout) of one catalog run: a fresh intermediate
    process runs it and reports RUSAGE_CHILDREN (the catalog process and its waited pool workers)."""
    code = ("import resource, subprocess, sys, time; t = time.monotonic(); "
            "p = subprocess.run(sys.argv[1:], capture_output=True, text=True); "
            "print(time.monotonic() - t, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024, p.returncode); "
            "sys.stdout.write(p.stdout); sys.stderr.write(p.stderr[-2000:])")
    done = subprocess.run([sys.executable, "-c", code, catalog_exe(), *args], capture_output=True, text=True)
    head, _, out = done.stdout.partition("\n")
    wall, rss, rc = head.split()
    if rc != "0":
        sys.exit(f"catalog_scale: error: catalog failed: {done.stderr.strip().splitlines()[-1:]}")
    return float(wall), float(rss), out


def make_fleet(root: Path, count: int, unique: int, min_s: float, max_s: float) -> tuple[int, float]:
    """Write `unique` flights and link them up to `count` files; returns (files, total MB)."""
    rng = random.Random(21)
    sources = []
    for k in range(unique):
        path = root / "unique" / f"u{k:03d}.mcap"
        path.parent.mkdir(parents=True, exist_ok=True)
        if not path.exists():
            write_flight(path, FlightSpec(vehicle=f"synth-{k % 4 + 1}", seed=k, duration_s=rng.uniform(min_s, max_s),
                                          state_hz=500.0, bulk=True, wear=k / unique,
                                          start_ns=1_790_000_000 * 10**9 + k * 3_600 * 10**9))
        sources.append(path)
    fleet = root / "fleet"
    total = 0.0
    for k in range(count):
        target = fleet / f"vehicle{k % 4 + 1}" / f"flight_{k:05d}.mcap"
        target.parent.mkdir(parents=True, exist_ok=True)
        if not target.exists():
            os.link(sources[k % unique], target)
        total += target.stat().st_size / 2**20
    return count, total


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--count", type=int, default=1000)
    parser.add_argument("--unique", type=int, default=41, help="distinct flights (coprime with the 4 vehicles)")
    parser.add_argument("--min-s", type=float, default=5.0)
    parser.add_argument("--max-s", type=float, default=20.0)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--dir", help="keep the flights here (default: a temporary folder, removed)")
    args = parser.parse_args()
    if args.count < 1 or not 1 <= args.unique <= args.count or args.rounds < 1 or not 0 < args.min_s <= args.max_s:
        parser.error("count >= unique >= 1, rounds >= 1, 0 < min-s <= max-s")
    work = Path(args.dir) if args.dir else Path(tempfile.mkdtemp(prefix="c4d-catalog-scale-"))
    probe = StallProbe()
    try:
        started = time.monotonic()
        files, mb = make_fleet(work, args.count, args.unique, args.min_s, args.max_s)
        print(f"fleet: {files} files ({args.unique} distinct, {args.min_s:.0f}-{args.max_s:.0f} s at 500 Hz), "
              f"{mb:.0f} MB, written in {time.monotonic() - started:.0f} s")
        cpus = os.cpu_count() or 1
        results: dict[int, list[tuple[float, float]]] = {}
        reindex: list[float] = []
        # 1 worker indexes one vehicle's folder only (a quarter of the files, every distinct flight among them)
        subset = work / "fleet" / "vehicle1"
        sizes = {1: (len(list(subset.glob("*.mcap"))), sum(p.stat().st_size for p in subset.glob("*.mcap")) / 2**20),
                 cpus: (files, mb)}
        for r in range(args.rounds):
            for jobs in sorted({1, cpus}):
                db = work / f"round{r}_j{jobs}.sqlite"
                db.unlink(missing_ok=True)
                folder = subset if jobs == 1 and cpus > 1 else work / "fleet"
                wall, rss, out = run_measured([str(folder), "--db", str(db), "-j", str(jobs)])
                assert f"{sizes[jobs][0]} flights indexed" in out, out
                results.setdefault(jobs, []).append((wall, rss))
                if jobs == cpus:
                    wall2, _, out2 = run_measured([str(work / "fleet"), "--db", str(db), "-j", str(jobs)])
                    assert f"0 flights indexed, {files} unchanged" in out2, out2
                    reindex.append(wall2)
            print(f"round {r + 1}: " + ", ".join(f"{j} worker(s) {sizes[j][0]} files {results[j][-1][0]:.1f} s"
                                                 for j in sorted(results)),
                  flush=True)
        print(f"\n{'workers':>8} {'files':>6} {'files/s':>9} {'MB/s':>7} {'wall [s]':>9} {'peak RSS [MiB]':>15}   "
              f"(medians of {args.rounds})")
        base = None
        for jobs in sorted(results):
            n, size = sizes[jobs]
            wall = statistics.median(w for w, _ in results[jobs])
            rss = statistics.median(m for _, m in results[jobs])
            base = base or n / wall
            print(f"{jobs:>8} {n:>6} {n / wall:>9.2f} {size / wall:>7.1f} {wall:>9.1f} {rss:>15.1f}   "
                  f"x{n / wall / base:.2f} vs 1 worker")
        print(f"re-index, nothing new: {statistics.median(reindex):.2f} s for {files} files "
              f"({files / statistics.median(reindex):.0f} files/s)")
        sweep = []  # memory vs flight length, one worker
        for seconds in (10.0, 300.0):
            single = work / f"single_{seconds:.0f}"
            single.mkdir(exist_ok=True)
            path = single / "flight.mcap"
            if not path.exists():
                write_flight(path, FlightSpec(seed=7, duration_s=seconds, state_hz=500.0, bulk=True))
            (single / "catalog.sqlite").unlink(missing_ok=True)
            wall, rss, _ = run_measured([str(single), "-j", "1"])
            sweep.append(f"{seconds:.0f} s flight ({path.stat().st_size / 2**20:.1f} MB): peak RSS {rss:.1f} MiB, "
                         f"{wall:.1f} s")
        print("memory vs flight length (1 worker): " + "; ".join(sweep))
    finally:
        stalls = probe.stop()
        if not args.dir:
            shutil.rmtree(work, ignore_errors=True)
    print(worst_line(stalls))
    return 0


if __name__ == "__main__":
    sys.exit(main())
