#!/usr/bin/env python3
"""The simulated lidar's cost (issue 18): per scan in-process, and the flight loop with the lidar on vs off.

1. In-process: median / p99 time of one scan (c4d_sim.lidar: vectorised ray casting, noise, REP-117
   ranges) and of the sim's whole scan task (scan + LaserScan message + serialisation), for 360 and 720
   beams on seeded random worlds of 5, 20 and 50 obstacles (cylinders, yawed boxes, walls, one mover)
   around a moving sensor.
2. The flight loop: sim + perception + navigation + core as separate processes (as
   bench/loop_latency_cpu.py starts them, private domain), take-off to 3 m and a hover of --seconds,
   once without a world (lidar off) and once with a 50-obstacle world (lidar on: --beams at --rate Hz,
   perception clustering the scans), alternating --repeat times. Per variant: the core's overruns and
   worst tick load (gnc/executor_stats), the sim's own overruns and its IMU samples published late /
   dropped (sim/actuator_link), sensors/scan as received, CPU of sim and perception, and the
   platform-stall probe (test/support/stall_probe.py) over the same windows.

Run under the graph lock:
  . ./env.sh && flock /tmp/c4d_graph.lock python bench/lidar_raycast.py [--seconds 30] [--repeat 2]
      [--beams 360] [--rate 20]
"""

from __future__ import annotations

import argparse
import array
import math
import os
import random
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tools"))
sys.path.insert(0, str(ROOT / "bench"))
sys.path.insert(0, str(ROOT / "test" / "support"))
from loop_latency_cpu import NODES, measure_window, private_ros, take_off_and_hold  # noqa: E402
from stall_probe import StallProbe  # noqa: E402

from c4d_sim.lidar import Lidar, LidarConfig  # noqa: E402
from c4d_sim.world import Box, Cylinder, Mover, World  # noqa: E402

STALL_MS = 1.0


def random_world(n: int, seed: int) -> World:
    """n obstacles 4..28 m from home: 40 % pillars, 40 % yawed boxes, 15 % walls, one mover."""
    rnd = random.Random(seed)

    def spot() -> tuple[float, float]:
        r, a = rnd.uniform(4.0, 28.0), rnd.uniform(-math.pi, math.pi)
        return r * math.cos(a), r * math.sin(a)

    cylinders, boxes = [], []
    for i in range(n - 1):
        x, y = spot()
        kind = i % 20
        if kind < 8:
            cylinders.append(Cylinder(x, y, rnd.uniform(0.2, 1.5), 10.0))
        elif kind < 16:
            boxes.append(Box(x, y, rnd.uniform(0.5, 4.0), rnd.uniform(0.5, 4.0), rnd.uniform(-math.pi, math.pi), 10.0))
        else:
            boxes.append(Box(x, y, rnd.uniform(4.0, 15.0), 0.2, rnd.uniform(-math.pi, math.pi), 10.0))
    mover = Mover(((-10.0, -10.0), (10.0, -10.0)), 2.0, 0.5, 10.0, back_and_forth=True)
    return World(cylinders=tuple(cylinders), boxes=tuple(boxes), movers=(mover,), name=f"random{n}")


def world_yaml(world: World) -> dict:
    """The world as a world file (docs/flight_loop.md), for the sim process."""
    return {
        "name": world.name,
        "cylinders": [{"center": [c.x, c.y], "radius": c.radius, "height": c.height} for c in world.cylinders],
        "boxes": [{"center": [b.x, b.y], "size": [b.size_x, b.size_y], "yaw_deg": math.degrees(b.yaw), "height": b.height}
                  for b in world.boxes],
        "movers": [{"path": [list(p) for p in m.path], "speed": m.speed, "radius": m.radius, "height": m.height,
                    "mode": "back_and_forth" if m.back_and_forth else "loop"} for m in world.movers],
    }


def in_process(scans: int) -> list[tuple[int, int, float, float, float, float]]:
    """(beams, obstacles, scan p50, p99, task p50, p99) [µs] per case."""
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import LaserScan

    rows = []
    for beams in (360, 720):
        for n in (5, 20, 50):
            lidar = Lidar(LidarConfig(beams=beams), random_world(n, seed=n))
            scan_us, task_us = [], []
            for k in range(scans):
                t = 0.05 * k
                x, y, yaw = 2.0 * math.cos(0.3 * t), 2.0 * math.sin(0.3 * t), 0.5 * t
                t0 = time.perf_counter()
                ranges = lidar.scan(x, y, 3.0, yaw, t)
                t1 = time.perf_counter()
                m = LaserScan()  # what SimNode.scan adds: the message and its serialisation by rmw
                m.header.frame_id = "base_link"
                m.angle_min, m.angle_increment, m.range_min, m.range_max = -math.pi, 2 * math.pi / beams, 0.1, 30.0
                m.ranges = array.array("f", ranges.tobytes())
                serialize_message(m)
                t2 = time.perf_counter()
                scan_us.append((t1 - t0) * 1e6)
                task_us.append((t2 - t0) * 1e6)
            rows.append((beams, n, *np.percentile(scan_us, [50, 99]), *np.percentile(task_us, [50, 99])))
    return rows


def flight(node, executor, world_file: Path | None, beams: int, rate: float, seconds: float) -> dict:
    """One graph: take off, hover `seconds`, the figures of that window."""
    from diagnostic_msgs.msg import DiagnosticStatus
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import LaserScan

    from c4d_interfaces.msg import ExecutorStats, VehicleStatus
    from c4d_interfaces.srv import VehicleCommand

    procs = {}
    for pkg, name in NODES:
        args = [str(ROOT / "install" / pkg / "lib" / pkg / name), "--ros-args"]
        if name == "core":
            args += ["-p", "rt_priority:=50"]
        if name == "sim" and world_file is not None:
            args += ["-p", f"world:={world_file}", "-p", f"scan_beams:={beams}", "-p", f"scan_rate_hz:={rate:.1f}"]
        procs[name] = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    stats: list = []
    link: list = []
    scans: list[float] = []
    status: list = []
    recording = [False]
    best_effort = QoSProfile(depth=20, reliability=ReliabilityPolicy.BEST_EFFORT)
    reliable = QoSProfile(depth=20, reliability=ReliabilityPolicy.RELIABLE)
    subs = [node.create_subscription(ExecutorStats, "gnc/executor_stats", lambda m: recording[0] and stats.append(m), reliable),
            node.create_subscription(DiagnosticStatus, "sim/actuator_link", link.append, reliable),
            node.create_subscription(LaserScan, "sensors/scan", lambda m: recording[0] and scans.append(time.monotonic()),
                                     best_effort),
            node.create_subscription(VehicleStatus, "vehicle/status", status.append, QoSProfile(
                depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL))]
    client = node.create_client(VehicleCommand, "gnc/command")
    probe = StallProbe()
    try:
        take_off_and_hold(executor, client, status)
        link_start = len(link)
        while len(link) == link_start:  # a fresh sim report at the window's start
            executor.spin_once(timeout_sec=0.05)
        first = {kv.key: float(kv.value) for kv in link[-1].values}
        cpu, t0, wall = measure_window(executor, procs, seconds, recording)
        last = {kv.key: float(kv.value) for kv in link[-1].values}
        t_end = time.monotonic()
    finally:
        stalls = probe.stop()
        for p in procs.values():
            os.killpg(p.pid, signal.SIGINT)
        for p in procs.values():
            p.wait(timeout=15)
        for s in subs:
            node.destroy_subscription(s)
        node.destroy_client(client)
    inside = [ms for t, ms in stalls if t0 <= t <= t_end]
    return {"core_overruns": sum(m.overruns for m in stats), "core_ticks": sum(m.ticks for m in stats),
            "core_load_max": max((m.load_max_percent for m in stats), default=math.nan),
            "core_jitter_p99": statistics.median([m.release_jitter_p99_us for m in stats]) if stats else math.nan,
            "sim_overruns": last["overruns"] - first["overruns"], "imu_late": last["imu_late"] - first["imu_late"],
            "imu_dropped": last["imu_dropped"] - first["imu_dropped"],
            "imu_late_percent": 100 * (last["imu_late"] - first["imu_late"])
            / max(1.0, last["imu_samples"] - first["imu_samples"]),
            "scan_hz": len(scans) / wall,
            "cpu_sim": cpu["sim"], "cpu_perception": cpu["perception"], "cpu_total": sum(cpu.values()),
            "stall_median": statistics.median(inside) if inside else math.nan, "stall_worst": max(inside, default=math.nan),
            "stall_seconds": sum(1 for ms in inside if ms > STALL_MS)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0, help="hover window per run [s]")
    parser.add_argument("--repeat", type=int, default=1, help="off/on pairs; figures are medians (sums for counts)")
    parser.add_argument("--beams", type=int, default=360)
    parser.add_argument("--rate", type=float, default=20.0, help="scan rate of the lidar-on runs [Hz]")
    parser.add_argument("--scans", type=int, default=400, help="scans per in-process case")
    parser.add_argument("--no-graph", action="store_true", help="the in-process figures only")
    args = parser.parse_args()
    if args.repeat < 1 or args.seconds <= 0 or not 10.0 <= args.rate <= 20.0:
        parser.error("--repeat >= 1, --seconds > 0 and --rate in 10..20 Hz")
    print(f"1. one scan in-process ({args.scans} scans per case, sensor moving at 3 m), µs")
    print(f"{'beams':>6}{'obstacles':>10}{'scan p50':>10}{'scan p99':>10}{'task p50':>10}{'task p99':>10}")
    for beams, n, s50, s99, t50, t99 in in_process(args.scans):
        print(f"{beams:>6}{n:>10}{s50:>10.0f}{s99:>10.0f}{t50:>10.0f}{t99:>10.0f}")
    print("   (task = scan + LaserScan message + serialisation: what the sim's scan task adds to its tick)")
    if args.no_graph:
        return
    lease, node, executor = private_ros("lidar_bench")
    import rclpy

    runs: dict[str, list[dict]] = {"lidar off": [], "lidar on": []}
    with tempfile.TemporaryDirectory() as tmp:
        world_file = Path(tmp) / "bench_world.yaml"
        world_file.write_text(yaml.safe_dump(world_yaml(random_world(50, seed=50))))
        for _ in range(args.repeat):
            runs["lidar off"].append(flight(node, executor, None, args.beams, args.rate, args.seconds))
            runs["lidar on"].append(flight(node, executor, world_file, args.beams, args.rate, args.seconds))
    executor.shutdown()
    node.destroy_node()
    rclpy.shutdown()
    print(f"\n2. flight loop (sim + perception + navigation + core) hovering at 3 m, {args.seconds:.0f} s window, "
          f"{args.repeat} run(s) per variant, {os.cpu_count()} cores; lidar on: 50 obstacles, {args.beams} beams "
          f"at {args.rate:g} Hz")
    rows = [("core overruns (sum)", "core_overruns", "{:.0f}", sum), ("core ticks (sum)", "core_ticks", "{:.0f}", sum),
            ("core worst tick load [%]", "core_load_max", "{:.1f}", max),
            ("core release jitter p99 [µs]", "core_jitter_p99", "{:.0f}", statistics.median),
            ("sim overruns (sum)", "sim_overruns", "{:.0f}", sum), ("sim IMU late (sum)", "imu_late", "{:.0f}", sum),
            ("sim IMU dropped (sum)", "imu_dropped", "{:.0f}", sum),
            ("sim IMU late [% of samples]", "imu_late_percent", "{:.2f}", statistics.median),
            ("sensors/scan received [Hz]", "scan_hz", "{:.1f}", statistics.median),
            ("CPU sim [%]", "cpu_sim", "{:.1f}", statistics.median),
            ("CPU perception [%]", "cpu_perception", "{:.1f}", statistics.median),
            ("CPU 4 processes [% of a core]", "cpu_total", "{:.1f}", statistics.median),
            ("stall probe median [ms]", "stall_median", "{:.2f}", statistics.median),
            ("stall probe worst [ms]", "stall_worst", "{:.2f}", max),
            (f"stall probe seconds > {STALL_MS:g} ms", "stall_seconds", "{:.0f}", sum)]
    print(f"{'':<32}" + "".join(f"{label:>14}" for label in runs))
    for label, key, form, combine in rows:
        print(f"{label:<32}" + "".join(f"{form.format(combine([r[key] for r in rs])):>14}" for rs in runs.values()))


if __name__ == "__main__":
    main()
