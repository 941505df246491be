#!/usr/bin/env python3
"""Flight recorder throughput and CPU on synthetic load (issue 8 goal: >= 20 000 small msgs/s
sustained without drops on this machine).

For each load (payload size, aggregate rate, topics) it starts the `recorder` (manual start)
and `python -m c4d_data.synthetic` as separate processes on loopback DDS in a private domain,
records the whole burst, and prints: messages sent and recorded (DDS sequence numbers prove
which ones are missing), writer-queue drops, recorded msgs/s and payload MB/s, recorder CPU
(utime + stime of its process over the burst, % of one core) and the file size. Loads:
- small: 16-byte payloads at 20 000 msgs/s over 4 topics;
- 10 kB: 10 000-byte random (incompressible) payloads at 2 000 msgs/s (20 MB/s);
- graph: ~ the full SITL graph (2 600 msgs/s of 250-byte messages over 25 topics).
Then the MCAP writer alone (BagWriter, in process, no DDS) for the same two sizes.

Usage: . ./env.sh && python bench/recorder_throughput.py [--seconds 10]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tools"))
import ros_domain

CLOCK_TICKS = os.sysconf("SC_CLK_TCK")
LOADS = [("small", 16, 20000, 4), ("10 kB", 10000, 2000, 2), ("graph", 250, 2600, 25)]


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS


def trigger(node, name: str) -> None:
    import rclpy
    from std_srvs.srv import Trigger

    client = node.create_client(Trigger, name)
    if not client.wait_for_service(timeout_sec=20):
        raise SystemExit(f"bench: error: {name} not available")
    future = client.call_async(Trigger.Request())
    rclpy.spin_until_future_complete(node, future, timeout_sec=10)
    node.destroy_client(client)


def run_load(node, env, out: Path, label: str, size: int, rate: int, topics: int, seconds: float) -> None:
    from ament_index_python.packages import get_package_prefix

    from c4d_data.bag_reader import iter_messages, open_bag

    exe = Path(get_package_prefix("c4d_data")) / "lib" / "c4d_data" / "recorder"
    folder = out / label.replace(" ", "")
    recorder = subprocess.Popen([str(exe), "--ros-args", "-p", f"output_dir:={folder}", "-p", "auto_arm:=false"],
                                env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    load = subprocess.Popen([sys.executable, "-m", "c4d_data.synthetic", "--rate", str(rate), "--size", str(size),
                             "--topics", str(topics), "--duration", str(seconds), "--delay", "4",
                             *(["--random"] if size >= 1000 else [])], env=env, stdout=subprocess.PIPE, text=True)
    try:
        time.sleep(1.5)
        trigger(node, "recorder/start")
        cpu0, t0 = cpu_seconds(recorder.pid), time.monotonic()
        sent_line = load.communicate(timeout=seconds + 60)[0].strip()
        time.sleep(1.0)
        cpu1, t1 = cpu_seconds(recorder.pid), time.monotonic()
        trigger(node, "recorder/stop")
        time.sleep(1.5)
    finally:
        recorder.send_signal(2)
        recorder.wait(timeout=30)
        if load.poll() is None:
            load.kill()
    sent = {k: int(v) for k, v in (item.split("=") for item in sent_line.split()[5:])}
    bag = open_bag(next(folder.glob("*.mcap")))
    recorded = {t: bag.topics[t].count if t in bag.topics else 0 for t in sent}
    missing = 0
    for name in sent:
        seqs = [m.sequence for _, m in iter_messages(bag, [name], log_time_order=False)]
        missing += sent[name] - len(set(seqs))
    times = sorted(m.log_time for _, m in iter_messages(bag, list(sent), log_time_order=False))
    span = (times[-1] - times[0]) * 1e-9 if len(times) > 1 else float("nan")
    total = sum(recorded.values())
    drops = (bag.rosbag2.get("custom_data") or {}).get("c4d.dropped_messages", "?")
    print(f"{label:>6}: sent {sum(sent.values()):>7}  recorded {total:>7}  missing {missing:>5}  queue drops {drops:>3}  "
          f"{total / span:>8.0f} msgs/s  {total * size / span / 1e6:>6.2f} MB/s payload  recorder CPU "
          f"{100 * (cpu1 - cpu0) / (t1 - t0):>5.1f} %  file {bag.path.stat().st_size / 2**20:.1f} MiB")


def writer_only(out: Path) -> None:
    from rclpy.serialization import serialize_message
    from std_msgs.msg import UInt8MultiArray

    from c4d_data.bag_writer import BagWriter
    from c4d_data.msgdef import full_text

    for label, size, n in (("small", 16, 200_000), ("10 kB", 10000, 20_000)):
        writer = BagWriter(out / f"writer_{size}.mcap")
        writer.add_topic("/load", "std_msgs/msg/UInt8MultiArray", full_text("std_msgs/msg/UInt8MultiArray"), [])
        data = [serialize_message(UInt8MultiArray(data=os.urandom(size))) for _ in range(64)]
        start = time.perf_counter()
        for k in range(n):
            writer.write("/load", data[k % 64], k * 1000, k * 1000, k)
        writer.close()
        elapsed = time.perf_counter() - start
        print(f"writer only, {label:>6}: {n / elapsed:>9.0f} msgs/s  {n * size / elapsed / 1e6:>7.1f} MB/s payload")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0)
    args = parser.parse_args()
    import rclpy

    lease = ros_domain.acquire()
    env = {**os.environ, "ROS_DOMAIN_ID": str(lease.domain_id), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    os.environ.update(env)
    rclpy.init(domain_id=lease.domain_id)
    node = rclpy.create_node("recorder_bench")
    try:
        with tempfile.TemporaryDirectory(prefix="c4d-recorder-bench-") as tmp:
            print(f"recorder over DDS, {args.seconds:.0f} s per load, {os.cpu_count()} cores")
            for label, size, rate, topics in LOADS:
                run_load(node, env, Path(tmp), label, size, rate, topics, args.seconds)
            writer_only(Path(tmp))
    finally:
        node.destroy_node()
        rclpy.shutdown()
        lease.release()
    return 0


if __name__ == "__main__":
    sys.exit(main())
