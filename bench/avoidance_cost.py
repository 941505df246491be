#!/usr/bin/env python3
"""The avoidance barrier's cost in the core's position_control task (100 Hz, budget 200 µs in core.yaml).

In-process, the core's real GncCore in a hover (bench/gnc_workload.py), position_control called back to
back with fresh inputs, in rounds interleaving the configurations so that drift hits all alike:
  off        avoidance disabled (the core before issue 18)
  idle       enabled, nothing to avoid (no obstacles, no fence): the common case
  fence      missions/square.yaml's fence (4-edge inclusion polygon, ceiling, max distance)
  fence+4    the fence and 4 obstacles, 2 of them inside the detection range (APF, cap and stall detector work)
  fence+20   the fence and 20 obstacles (a cluttered scan)
Prints median and p99 µs per call, the ratio of medians to `off`, the share of the 2 ms tick the task
takes when it runs (budget 200 µs = 10 %) and its CPU share at 100 Hz, and the platform-stall probe's
worst oversleep (a stall there is the machine's, not c4d's).

Run under the graph lock: `flock /tmp/c4d_graph.lock python bench/avoidance_cost.py [--calls 20000]`.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "test" / "support"))
sys.path.insert(0, str(ROOT / "bench"))
from gnc_workload import flying_core, refresh  # noqa: E402
from stall_probe import StallProbe, worst_line  # noqa: E402

from c4d_common.barrier import FenceGeometry, Obstacle  # noqa: E402
from c4d_common.geodesy import GeoOrigin  # noqa: E402
from c4d_common.plan_files import load_plan  # noqa: E402

HOME = GeoOrigin(43.5629, 1.4815, 146.0)


def configurations(tick_s: float):
    fence = FenceGeometry.from_geofence(load_plan(ROOT / "missions" / "square.yaml").geofence, HOME)
    near = (Obstacle(1, 1.5, 0.0, 0.5), Obstacle(2, 0.0, -1.8, 0.4))
    far = (Obstacle(3, 6.0, 6.0, 1.0), Obstacle(4, -5.0, 3.0, 0.3, vx=1.0))
    many = near + far + tuple(Obstacle(10 + k, 8.0 + k, -6.0, 0.5) for k in range(16))
    setups = {"off": (False, (), None), "idle": (True, (), None), "fence": (True, (), fence),
              "fence+4": (True, near + far, fence), "fence+20": (True, many, fence)}
    cores = {}
    for name, (enabled, obstacles, geofence) in setups.items():
        core = flying_core(tick_s)
        if not enabled:
            core.barrier = None
        core.inputs.obstacles, core.inputs.fence = obstacles, geofence
        cores[name] = core
    return cores


def measure(cores, calls: int, rounds: int = 20) -> dict[str, list[float]]:
    samples: dict[str, list[float]] = {name: [] for name in cores}
    per_round = max(1, calls // rounds)
    now = time.monotonic()
    for _ in range(rounds):
        for name, core in cores.items():
            out = samples[name]
            for _ in range(per_round):
                now += 0.01
                refresh(core, now)
                core.inputs.obstacles_stamp = now
                core.state_update(0.002)
                core.guidance(0.02)
                t0 = time.perf_counter_ns()
                core.position_control(0.01)
                out.append((time.perf_counter_ns() - t0) / 1e3)
    return samples


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=20000, help="calls per configuration")
    args = parser.parse_args(argv)
    if args.calls < 100:
        parser.error("--calls must be >= 100")
    probe = StallProbe()
    try:
        cores = configurations(0.002)
        measure(cores, 2000, rounds=2)  # warm-up
        samples = measure(cores, args.calls)
    finally:
        stalls = probe.stop()
    base = statistics.median(samples["off"])
    print(f"position_control per call ({args.calls} calls each, interleaved in 20 rounds)")
    print(f"{'configuration':<12} {'median µs':>10} {'p99 µs':>9} {'ratio':>7} {'% of tick':>10} {'CPU @100 Hz':>12}")
    for name, values in samples.items():
        values.sort()
        median, p99 = statistics.median(values), values[int(0.99 * (len(values) - 1))]
        print(f"{name:<12} {median:>10.1f} {p99:>9.1f} {median / base:>6.2f}x {median / 20:>9.2f}% "
              f"{median * 0.01:>11.3f}%")
    print(worst_line(stalls))
    return 0


if __name__ == "__main__":
    sys.exit(main())
