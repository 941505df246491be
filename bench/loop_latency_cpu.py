#!/usr/bin/env python3
"""Flight loop over DDS: end-to-end latency and CPU per process, EventsExecutor vs default.

Starts sim, perception, navigation and core as separate processes (this machine, loopback
DDS, private domain), takes off to 3 m and, while hovering, measures for --seconds:
- latency from an IMU sample's time to the actuator command computed from it
  (ActuatorCommand.header.stamp − input_stamp, the sample time the core used), p50 / p99 / max,
  also in 500 Hz ticks (goal p99 ≤ 2 ticks);
- CPU of each process (utime + stime from /proc over the window) and the total
  (goal ≤ 100 % of one core).
Run twice, side by side: the event-driven nodes with rclpy's EventsExecutor, then with the
default SingleThreadedExecutor (parameter events_executor). The core never uses an rclpy
executor for its loop (it drains with take calls), so it is the same in both runs.

Usage: . ./env.sh && python bench/loop_latency_cpu.py [--seconds 20]
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tools"))
import ros_domain

ROOT = Path(__file__).resolve().parent.parent
NODES = [("c4d_sim", "sim"), ("c4d_gnc", "perception"), ("c4d_gnc", "navigation"), ("c4d_gnc", "core")]
CLOCK_TICKS = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS


def run(events: bool, seconds: float, node, executor) -> dict:
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    from c4d_interfaces.msg import ActuatorCommand, VehicleStatus
    from c4d_interfaces.srv import VehicleCommand

    procs = {}
    for pkg, name in NODES:
        args = [str(ROOT / "install" / pkg / "lib" / pkg / name), "--ros-args", "-p",
                f"events_executor:={'true' if events else 'false'}"]
        if name == "core":
            args = args[:1] + ["--ros-args", "-p", "rt_priority:=50"]
        procs[name] = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    latencies: list[float] = []
    status: list = []
    recording = [False]

    def on_actuators(m):
        if recording[0] and m.armed:
            latencies.append((m.header.stamp.sec - m.input_stamp.sec) + (m.header.stamp.nanosec - m.input_stamp.nanosec) * 1e-9)

    sub = node.create_subscription(ActuatorCommand, "control/actuators", on_actuators,
                                   QoSProfile(depth=50, reliability=ReliabilityPolicy.BEST_EFFORT))
    sub2 = node.create_subscription(VehicleStatus, "vehicle/status", status.append, QoSProfile(
        depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    client = node.create_client(VehicleCommand, "gnc/command")
    try:
        client.wait_for_service(timeout_sec=30)
        deadline = time.monotonic() + 40
        while time.monotonic() < deadline:  # retry until the estimator is ready to arm
            future = client.call_async(VehicleCommand.Request(command=VehicleCommand.Request.CMD_TAKEOFF, altitude=3.0))
            while not future.done():
                executor.spin_once(timeout_sec=0.05)
            if future.result().result == 0:
                break
            end = time.monotonic() + 1.0
            while time.monotonic() < end:
                executor.spin_once(timeout_sec=0.05)
        while not (status and status[-1].nav_state == VehicleStatus.NAV_HOLD):
            executor.spin_once(timeout_sec=0.05)
        cpu0 = {n: cpu_seconds(p.pid) for n, p in procs.items()}
        t0 = time.monotonic()
        recording[0] = True
        while time.monotonic() - t0 < seconds:
            executor.spin_once(timeout_sec=0.05)
        recording[0] = False
        wall = time.monotonic() - t0
        cpu = {n: 100 * (cpu_seconds(p.pid) - cpu0[n]) / wall for n, p in procs.items()}
    finally:
        for p in procs.values():
            os.killpg(p.pid, signal.SIGINT)
        for p in procs.values():
            p.wait(timeout=15)
        node.destroy_subscription(sub)
        node.destroy_subscription(sub2)
        node.destroy_client(client)
    lat = np.array(latencies) * 1e6
    return {"cpu": cpu, "p50": np.percentile(lat, 50), "p99": np.percentile(lat, 99), "max": lat.max(), "n": len(lat)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    args = parser.parse_args()
    lease = ros_domain.acquire()
    os.environ["ROS_DOMAIN_ID"] = str(lease.domain_id)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    rclpy.init()
    node = rclpy.create_node("loop_bench")
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    results = {label: run(events, args.seconds, node, executor)
               for label, events in (("EventsExecutor", True), ("SingleThreaded", False))}
    tick_us = 2000.0
    print(f"4-process flight loop hovering at 3 m, {args.seconds:.0f} s window per variant, {os.cpu_count()} cores")
    print(f"{'':<26}" + "".join(f"{label:>18}" for label in results))
    for name in ("sim", "perception", "navigation", "core"):
        print(f"{'CPU ' + name + ' (%)':<26}" + "".join(f"{r['cpu'][name]:>18.1f}" for r in results.values()))
    print(f"{'CPU total (% of one core)':<26}" + "".join(f"{sum(r['cpu'].values()):>18.1f}" for r in results.values()))
    for key in ("p50", "p99", "max"):
        print(f"{'IMU→actuator ' + key + ' (µs)':<26}" + "".join(
            f"{r[key]:>10.0f} ({r[key] / tick_us:.2f} t)" for r in results.values()))
    print(f"{'commands measured':<26}" + "".join(f"{r['n']:>18}" for r in results.values()))
    executor.shutdown()
    node.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main()
