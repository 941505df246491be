#!/usr/bin/env python3
"""The sim's tick cost without / with the external-pose emulator at 100 Hz (issue 19).

The real SimNode (bundled sim config, no world, 1 kHz physics, every sensor task) runs its own
CyclicExecutive in real time in this process on a private domain, for --seconds per variant:
  off      external_pose.enabled false (the task runs and returns at once: the default)
  ros      enabled, output ros: nav_msgs/Odometry on navigation/external/odometry (a matched subscriber)
  mavlink  enabled, output mavlink: VISION_POSITION_ESTIMATE datagrams to a bound local UDP socket
  both     both outputs
Variants alternate --repeat times. Per variant: the tick's busy time (all tasks of a tick; p50 / p99 /
max), the mean busy time per tick, the external_pose task alone per call (p50 / p99: it runs every
10th tick), the sim's overruns and skipped ticks, the process CPU, and the platform-stall probe
(test/support/stall_probe.py) worst oversleep over each window: an overrun with a multi-ms probe
stall is the machine's, not the sim's.

Run under the graph lock:
  . ./env.sh && flock /tmp/c4d_graph.lock python bench/sim_external_pose.py [--seconds 20] [--repeat 2]
"""

from __future__ import annotations

import argparse
import os
import socket
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "bench"))
sys.path.insert(0, str(ROOT / "test" / "support"))
from loop_latency_cpu import private_ros  # noqa: E402
from stall_probe import StallProbe  # noqa: E402

VARIANTS = ("off", "ros", "mavlink", "both")


def run_variant(node, variant: str, seconds: float, port: int, probe_windows: list) -> dict[str, float]:
    import rclpy
    from rclpy.parameter import Parameter

    from c4d_sched.executive import grid_start_ns
    from c4d_sim.sim_config import default_sim_config, load_sim_config
    from c4d_sim.sim_node import SimNode

    overrides = [Parameter("external_pose.enabled", value=variant != "off"),
                 Parameter("external_pose.output", value="ros" if variant == "off" else variant),
                 Parameter("external_pose.mavlink_url", value=f"udpout:127.0.0.1:{port}")]
    sim_node = rclpy.create_node("sim", context=node.context, parameter_overrides=overrides)
    sim = SimNode(sim_node, load_sim_config(default_sim_config()))
    executive = sim.executive
    busy, task = [], []
    profiler = executive.profiler
    tick_done, task_ran = profiler.tick_done, profiler.task_ran

    def on_tick(jitter_ns: int, busy_ns: int, overrun: bool, skipped: int) -> None:
        busy.append(busy_ns)
        tick_done(jitter_ns, busy_ns, overrun, skipped)

    def on_task(name: str, start_ns: int, end_ns: int) -> None:
        if name == "external_pose":
            task.append(end_ns - start_ns)
        task_ran(name, start_ns, end_ns)

    profiler.tick_done, profiler.task_ran = on_tick, on_task  # instrumentation of this run only
    time.sleep(1.0)  # discovery with the subscriber before the window
    executive.start(t0_ns=grid_start_ns(time.monotonic_ns(), executive.tick_ns, 2_000_000))
    cpu0, t0 = time.process_time(), time.monotonic()
    try:
        executive.run(max_ticks=int(seconds * 1000))
    finally:
        executive.release_gc()
    cpu, wall = time.process_time() - cpu0, time.monotonic() - t0
    probe_windows.append((variant, t0, t0 + wall))
    b, x = np.array(busy[1000:]) / 1e3, np.array(task[100:] or [0]) / 1e3  # the first second warms up
    row = {"ticks": float(len(busy)), "busy_p50": float(np.percentile(b, 50)), "busy_p99": float(np.percentile(b, 99)),
           "busy_max": float(b.max()), "busy_mean": float(b.mean()), "task_p50": float(np.percentile(x, 50)),
           "task_p99": float(np.percentile(x, 99)), "overruns": float(profiler.overruns_total),
           "skipped": float(profiler.skipped_total), "cpu": 100.0 * cpu / wall,
           "released": float(sim.external.released), "udp_sent": float(sim.vision.sent if sim.vision else 0)}
    if sim.vision:
        sim.vision.close()
    sim_node.destroy_node()
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    from nav_msgs.msg import Odometry

    from c4d_ros.manifest import EXTERNAL_ODOMETRY

    lease, node, executor = private_ros("bench_sim_external_pose")
    node.create_subscription(Odometry, EXTERNAL_ODOMETRY.name, lambda m: None, EXTERNAL_ODOMETRY.qos)  # matched, not spun
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.setblocking(False)
    probe = StallProbe()
    rows: dict[str, list[dict[str, float]]] = {v: [] for v in VARIANTS}
    windows: list = []
    try:
        for _ in range(args.repeat):
            for variant in VARIANTS:
                rows[variant].append(run_variant(node, variant, args.seconds, rx.getsockname()[1], windows))
                while True:  # drain the datagrams
                    try:
                        rx.recv(2048)
                    except BlockingIOError:
                        break
    finally:
        stalls = probe.stop()
        rx.close()
        node.destroy_node()
        lease.release()
    worst = {v: max([ms for t, ms in stalls if any(a <= t <= b for name, a, b in windows if name == v)] or [0.0])
             for v in VARIANTS}

    def med(variant: str, key: str) -> float:
        return statistics.median(r[key] for r in rows[variant])

    print(f"sim tick cost, {args.seconds:g} s per variant x {args.repeat} (medians of runs), pid {os.getpid()}")
    print(f"{'':34}" + "".join(f"{v:>12}" for v in VARIANTS))
    for key, label in (("busy_mean", "tick busy mean (µs)"), ("busy_p50", "tick busy p50 (µs)"),
                       ("busy_p99", "tick busy p99 (µs)"), ("busy_max", "tick busy max (µs)"),
                       ("task_p50", "external_pose task p50 (µs)"), ("task_p99", "external_pose task p99 (µs)"),
                       ("cpu", "sim CPU (% of one core)"), ("overruns", "overruns"), ("skipped", "skipped ticks"),
                       ("released", "samples published"), ("udp_sent", "MAVLink datagrams")):
        print(f"{label:34}" + "".join(f"{med(v, key):>12.1f}" for v in VARIANTS))
    print(f"{'ratio busy mean vs off':34}" + "".join(f"{med(v, 'busy_mean') / med('off', 'busy_mean'):>12.2f}"
                                                     for v in VARIANTS))
    print(f"{'stall probe worst (ms)':34}" + "".join(f"{worst[v]:>12.2f}" for v in VARIANTS))


if __name__ == "__main__":
    main()
