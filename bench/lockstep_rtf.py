#!/usr/bin/env python3
"""Lockstep real-time factor: simulated seconds per wall second of the flight chain, quiet and under a CPU hog.

Starts sim and core with `lockstep:=true`, perception and navigation with `use_sim_time:=true`
(private domain, loopback DDS), takes off to 3 m and, while hovering, measures for --seconds of
wall time: the real-time factor (simulated time from /clock over wall time; > 1 = faster than
real time) and the CPU of each process. Run twice side by side: quiet, then with one busy loop
per CPU. In lockstep a slower machine only lowers the factor; the flight stays the same
(test/test_lockstep.py checks that bit for bit).

Usage: . ./env.sh && flock /tmp/c4d_graph.lock python bench/lockstep_rtf.py [--seconds 15]
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tools"))
import ros_domain

ROOT = Path(__file__).resolve().parent.parent
NODES = [("c4d_sim", "sim", ["lockstep:=true"]), ("c4d_gnc", "perception", ["use_sim_time:=true"]),
         ("c4d_gnc", "navigation", ["use_sim_time:=true"]), ("c4d_gnc", "core", ["lockstep:=true"])]
CLOCK_TICKS = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS


def run(hogs: int, seconds: float, node, executor) -> dict:
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock

    from c4d_interfaces.srv import VehicleCommand

    procs = {}
    for pkg, name, params in NODES:
        args = [str(ROOT / "install" / pkg / "lib" / pkg / name), "--ros-args"] + [a for p in params for a in ("-p", p)]
        procs[name] = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    hog_procs = [subprocess.Popen([sys.executable, "-c", "while True: pass"], start_new_session=True) for _ in range(hogs)]
    sim_time = [0.0]
    sub = node.create_subscription(Clock, "clock", lambda m: sim_time.__setitem__(0, m.clock.sec + m.clock.nanosec * 1e-9),
                                   QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
    client = node.create_client(VehicleCommand, "gnc/command")

    def spin(s: float) -> None:
        end = time.monotonic() + s
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=0.05)

    try:
        client.wait_for_service(timeout_sec=30)
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:  # retry until the estimator is ready (simulated time runs meanwhile)
            future = client.call_async(VehicleCommand.Request(command=VehicleCommand.Request.CMD_TAKEOFF, altitude=3.0))
            while not future.done():
                executor.spin_once(timeout_sec=0.05)
            if future.result().result == 0:
                break
            spin(0.5)
        takeoff_t = sim_time[0]
        while sim_time[0] < takeoff_t + 5.0:  # climb, settle
            executor.spin_once(timeout_sec=0.05)
        cpu0 = {n: cpu_seconds(p.pid) for n, p in procs.items()}
        t0, s0 = time.monotonic(), sim_time[0]
        spin(seconds)
        wall, simulated = time.monotonic() - t0, sim_time[0] - s0
        cpu = {n: 100 * (cpu_seconds(p.pid) - cpu0[n]) / wall for n, p in procs.items()}
    finally:
        for p in hog_procs:
            os.killpg(p.pid, signal.SIGKILL)
        for p in procs.values():
            os.killpg(p.pid, signal.SIGINT)
        for p in procs.values():
            p.wait(timeout=15)
        node.destroy_subscription(sub)
        node.destroy_client(client)
    return {"rtf": simulated / wall, "cpu": cpu, "simulated": simulated, "wall": wall}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=15.0)
    args = parser.parse_args()
    lease = ros_domain.acquire()
    os.environ["ROS_DOMAIN_ID"] = str(lease.domain_id)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    rclpy.init()
    node = rclpy.create_node("lockstep_bench")
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    cpus = os.cpu_count() or 1
    results = {label: run(hogs, args.seconds, node, executor) for label, hogs in (("quiet", 0), (f"{cpus} hogs", cpus))}
    print(f"lockstep flight chain hovering at 3 m, {args.seconds:.0f} s wall window per variant, {cpus} cores")
    print(f"{'':<30}" + "".join(f"{label:>14}" for label in results))
    print(f"{'real-time factor (sim s/wall s)':<30}" + "".join(f"{r['rtf']:>14.2f}" for r in results.values()))
    print(f"{'simulated seconds':<30}" + "".join(f"{r['simulated']:>14.1f}" for r in results.values()))
    for name in ("sim", "perception", "navigation", "core"):
        print(f"{'CPU ' + name + ' (%)':<30}" + "".join(f"{r['cpu'][name]:>14.1f}" for r in results.values()))
    print(f"{'CPU total (% of one core)':<30}" + "".join(f"{sum(r['cpu'].values()):>14.1f}" for r in results.values()))
    executor.shutdown()
    node.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main()
