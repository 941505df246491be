#!/usr/bin/env python3
"""Flight loop over DDS: end-to-end latency and CPU per process, EventsExecutor vs default.

Starts sim, perception, navigation and core as separate processes (this machine, loopback
DDS, private domain), takes off to 3 m and, while hovering, measures for --seconds:
- latency from an IMU sample's time to the actuator command computed from it
  (ActuatorCommand.header.stamp − input_stamp, the sample time the core used), p50 / p99 / max,
  also in 500 Hz ticks (goal p99 ≤ 2 ticks);
- the delivered rate of sensors/imu and navigation/state as this process receives them (distinct
  sample stamps in the window vs 500 Hz nominal), and the age of each IMU sample on arrival
  (receive time − stamp: never negative when the simulated hardware stamps honestly);
- CPU of each process (utime + stime from /proc over the window) and the total
  (goal ≤ 100 % of one core).
Run side by side: the event-driven nodes with rclpy's EventsExecutor, then with the
default SingleThreadedExecutor (parameter events_executor; --executors picks one). The core never
uses an rclpy executor for its loop (it drains with take calls), so it is the same in both runs.
--repeat N runs each variant N times and prints the median of each figure. --hog starts a busy
loop pinned to the last CPU (taskset) for the whole run: the simulated IMU must still be
delivered at ≥ 99.5 % of its rate.

Usage: . ./env.sh && python bench/loop_latency_cpu.py [--seconds 20] [--repeat 2] [--hog]
       [--executors events|default|both]
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
CORE_PARAMS: list[str] = []  # --core-param


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS


def private_ros(name: str):
    """(domain lease, node, executor) on a private ROS_DOMAIN_ID (tools/ros_domain), loopback discovery;
    the graph's processes started afterwards inherit the domain. Keep the lease while the graph runs."""
    lease = ros_domain.acquire()
    os.environ["ROS_DOMAIN_ID"] = str(lease.domain_id)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    rclpy.init()
    node = rclpy.create_node(name)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    return lease, node, executor


def measure_window(executor, procs: dict, seconds: float, recording: list[bool]) -> tuple[dict[str, float], float, float]:
    """Spin for `seconds` with recording[0] set (the callbacks record only then); returns (CPU % of one core
    per process over the window, window start on time.monotonic(), window length [s])."""
    cpu0 = {n: cpu_seconds(p.pid) for n, p in procs.items()}
    t0 = time.monotonic()
    recording[0] = True
    while time.monotonic() - t0 < seconds:
        executor.spin_once(timeout_sec=0.05)
    recording[0] = False
    wall = time.monotonic() - t0
    return {n: 100 * (cpu_seconds(p.pid) - cpu0[n]) / wall for n, p in procs.items()}, t0, wall


def take_off_and_hold(executor, client, status: list) -> None:
    """Take off to 3 m through gnc/command (retried until the estimator is ready to arm) and spin until
    vehicle/status (appended to `status` by the caller's subscription) reports HOLD."""
    from c4d_interfaces.msg import VehicleStatus
    from c4d_interfaces.srv import VehicleCommand

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


def run(events: bool, seconds: float, node, executor) -> dict:
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Imu

    from c4d_interfaces.msg import ActuatorCommand, VehicleState, VehicleStatus
    from c4d_interfaces.srv import VehicleCommand
    from c4d_ros.cdr import header_stamp

    procs = {}
    for pkg, name in NODES:
        args = [str(ROOT / "install" / pkg / "lib" / pkg / name), "--ros-args", "-p",
                f"events_executor:={'true' if events else 'false'}"]
        if name == "core":
            args = args[:1] + ["--ros-args", "-p", "rt_priority:=50"] + [a for p in CORE_PARAMS for a in ("-p", p)]
        procs[name] = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    latencies: list[float] = []
    status: list = []
    recording = [False]
    imu_stamps: set[int] = set()
    state_stamps: set[int] = set()
    imu_ages: list[float] = []

    def on_imu(raw: bytes) -> None:  # raw: this process must not be the bottleneck it measures
        if recording[0]:
            sec, nanosec = header_stamp(raw)
            imu_stamps.add(sec * 1_000_000_000 + nanosec)
            imu_ages.append(time.time() - (sec + nanosec * 1e-9))

    def on_state(raw: bytes) -> None:
        if recording[0]:
            sec, nanosec = header_stamp(raw)
            state_stamps.add(sec * 1_000_000_000 + nanosec)

    def on_actuators(m):
        if recording[0] and m.armed:
            latencies.append((m.header.stamp.sec - m.input_stamp.sec) + (m.header.stamp.nanosec - m.input_stamp.nanosec) * 1e-9)

    sub = node.create_subscription(ActuatorCommand, "control/actuators", on_actuators,
                                   QoSProfile(depth=50, reliability=ReliabilityPolicy.BEST_EFFORT))
    sub2 = node.create_subscription(VehicleStatus, "vehicle/status", status.append, QoSProfile(
        depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    sub3 = node.create_subscription(Imu, "sensors/imu", on_imu, QoSProfile(
        depth=50, reliability=ReliabilityPolicy.BEST_EFFORT), raw=True)
    sub4 = node.create_subscription(VehicleState, "navigation/state", on_state, QoSProfile(
        depth=50, reliability=ReliabilityPolicy.BEST_EFFORT), raw=True)
    client = node.create_client(VehicleCommand, "gnc/command")
    try:
        take_off_and_hold(executor, client, status)
        cpu, _, wall = measure_window(executor, procs, seconds, recording)
    finally:
        for p in procs.values():
            os.killpg(p.pid, signal.SIGINT)
        for p in procs.values():
            p.wait(timeout=15)
        node.destroy_subscription(sub)
        node.destroy_subscription(sub2)
        node.destroy_subscription(sub3)
        node.destroy_subscription(sub4)
        node.destroy_client(client)
    lat = np.array(latencies) * 1e6
    ages = np.array(imu_ages) * 1e6
    return {"cpu": cpu, "p50": np.percentile(lat, 50), "p99": np.percentile(lat, 99), "max": lat.max(), "n": len(lat),
            "imu_hz": len(imu_stamps) / wall, "state_hz": len(state_stamps) / wall,
            "age_min": ages.min(), "age_p50": np.percentile(ages, 50), "age_p99": np.percentile(ages, 99)}


def median_run(runs: list[dict]) -> dict:
    """Each figure's median over the runs (CPU per process too)."""
    out = {key: float(np.median([r[key] for r in runs])) for key in runs[0] if key != "cpu"}
    out["cpu"] = {name: float(np.median([r["cpu"][name] for r in runs])) for name in runs[0]["cpu"]}
    return out


def start_hog() -> subprocess.Popen:
    """A busy loop pinned to the last CPU (the competing load of a companion board's user code)."""
    cpu = str(os.cpu_count() - 1)
    return subprocess.Popen(["taskset", "-c", cpu, sys.executable, "-c", "while True: pass"], start_new_session=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--repeat", type=int, default=1, help="runs per variant; figures are medians")
    parser.add_argument("--executors", choices=("events", "default", "both"), default="both")
    parser.add_argument("--hog", action="store_true", help="a busy loop pinned to the last CPU during the runs")
    parser.add_argument("--core-param", action="append", default=[], metavar="NAME:=VALUE",
                        help="a core parameter for the runs (repeatable), e.g. tick_phase:=0.75")
    args = parser.parse_args()
    if args.repeat < 1 or args.seconds <= 0:
        parser.error("--repeat must be >= 1 and --seconds > 0")
    if any(":=" not in p for p in args.core_param):
        parser.error("--core-param takes NAME:=VALUE")
    CORE_PARAMS.extend(args.core_param)
    lease, node, executor = private_ros("loop_bench")
    import rclpy

    variants = [(label, events) for label, events in (("EventsExecutor", True), ("SingleThreaded", False))
                if args.executors == "both" or (args.executors == "events") == events]
    hog = start_hog() if args.hog else None
    try:
        results = {label: median_run([run(events, args.seconds, node, executor) for _ in range(args.repeat)])
                   for label, events in variants}
    finally:
        if hog is not None:
            os.killpg(hog.pid, signal.SIGKILL)
            hog.wait()
    tick_us = 2000.0
    print(f"4-process flight loop hovering at 3 m, {args.seconds:.0f} s window per variant, {os.cpu_count()} cores"
          + (f", medians of {args.repeat} runs" if args.repeat > 1 else "")
          + (f", busy-loop hog on CPU {os.cpu_count() - 1}" if args.hog else ""))
    print(f"{'':<26}" + "".join(f"{label:>18}" for label in results))
    for name in ("sim", "perception", "navigation", "core"):
        print(f"{'CPU ' + name + ' (%)':<26}" + "".join(f"{r['cpu'][name]:>18.1f}" for r in results.values()))
    print(f"{'CPU total (% of one core)':<26}" + "".join(f"{sum(r['cpu'].values()):>18.1f}" for r in results.values()))
    for key in ("p50", "p99", "max"):
        print(f"{'IMU→actuator ' + key + ' (µs)':<26}" + "".join(
            f"{r[key]:>10.0f} ({r[key] / tick_us:.2f} t)" for r in results.values()))
    print(f"{'commands measured':<26}" + "".join(f"{r['n']:>18.0f}" for r in results.values()))
    for key, label in (("imu_hz", "sensors/imu (Hz)"), ("state_hz", "navigation/state (Hz)")):
        print(f"{label:<26}" + "".join(f"{r[key]:>10.1f} ({r[key] / 5:5.1f} %)" for r in results.values()))
    for key in ("age_min", "age_p50", "age_p99"):
        print(f"{'IMU age ' + key[4:] + ' (µs)':<26}" + "".join(f"{r[key]:>18.0f}" for r in results.values()))
    executor.shutdown()
    node.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main()
