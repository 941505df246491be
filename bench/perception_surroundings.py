"""Perception's surroundings cost: per scan in-process, and the perception process's CPU at 20 Hz scans.

1. In-process (ROS-free + glue): median / p99 time per scan of detections + tracking, and of building
   the Surroundings and MarkerArray messages, for 360 and 720 beams on a world of 4 posts, a mover
   and a wall (ray cast by test/support/scan_cast.py).
2. The perception process alone in a private domain, fed by this script: raw sensors/imu at 500 Hz
   and navigation/state at 500 Hz throughout (its real load), sensors/scan at 20 Hz in the second
   window only. Prints the process's CPU (utime + stime from /proc) per window side by side, with
   the platform-stall probe's worst oversleep.

Run under the graph lock: `flock /tmp/c4d_graph.lock python bench/perception_surroundings.py`.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "test" / "support"))
from scan_cast import cast
from stall_probe import StallProbe

from c4d_gnc.surroundings import ClusterConfig, Tracker, detections

POSTS = [(6.0, 2.0, 0.5), (-3.0, 5.0, 0.3), (4.0, -7.0, 1.0), (-9.0, -2.0, 0.6)]
WALL = ((-15.0, 12.0), (15.0, 12.0))
WINDOW_S = 20.0


def world(t: float) -> list[tuple[float, float, float]]:
    return [*POSTS, (-6.0 + 1.5 * (t % 8.0), -4.0, 0.5)]


def scan_of(beams: int, t: float) -> tuple[np.ndarray, float, float]:
    import scan_cast
    scan_cast.BEAMS, scan_cast.INC = beams, 2.0 * math.pi / beams
    return cast(0.3 * t, 0.1 * t, 0.2 * t, world(t), [WALL], noise=0.02, seed=int(t * 20)), scan_cast.ANGLE_MIN, scan_cast.INC


def in_process(beams: int, scans: int = 400) -> tuple[list[float], list[float], int]:
    from c4d_gnc.perception_surroundings import markers
    from c4d_interfaces.msg import Obstacle, Surroundings

    tracker, cfg = Tracker(), ClusterConfig()
    pipeline, messages = [], []
    inputs = [(k / 20.0, *scan_of(beams, k / 20.0)) for k in range(scans)]
    count = 0
    for t, ranges, amin, inc in inputs:
        ranges = ranges.tolist()  # what rclpy hands over (array.array in fact, converted the same way)
        t0 = time.perf_counter()
        tracks = tracker.update(t, detections(np.asarray(ranges, dtype=np.float64), amin, inc, 0.2, 30.0,
                                              0.3 * t, 0.1 * t, 0.2 * t, cfg))
        t1 = time.perf_counter()
        msg = Surroundings()
        for tr in tracks:
            o = Obstacle(id=tr.id, radius=float(tr.radius), confidence=float(tr.confidence))
            o.position.x, o.position.y = float(tr.x), float(tr.y)
            o.velocity.x, o.velocity.y = float(tr.vx), float(tr.vy)
            msg.obstacles.append(o)
        markers(msg)
        t2 = time.perf_counter()
        pipeline.append((t1 - t0) * 1e3)
        messages.append((t2 - t1) * 1e3)
        count = len(tracks)
    return pipeline, messages, count


def cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def process_cpu() -> tuple[float, float]:
    """Perception's CPU [% of one core] without and with 20 Hz scans (500 Hz IMU + state throughout)."""
    import rclpy
    from sensor_msgs.msg import Imu, LaserScan

    from c4d_common import quat
    from c4d_interfaces.msg import VehicleState
    from c4d_ros.manifest import IMU, NAV_STATE, SCAN
    from c4d_ros.stamps import s_to_stamp

    domain = 185  # this helper's range; the bench runs under the graph lock
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    proc = subprocess.Popen([sys.executable, "-m", "c4d_gnc.perception_node"], env=env, start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    rclpy.init(domain_id=domain)
    node = rclpy.create_node("bench_feeder")
    pub_imu = node.create_publisher(Imu, IMU.name, IMU.qos)
    pub_state = node.create_publisher(VehicleState, NAV_STATE.name, NAV_STATE.qos)
    pub_scan = node.create_publisher(LaserScan, SCAN.name, SCAN.qos)
    imu = Imu()
    imu.linear_acceleration.z = 9.81
    state = VehicleState(valid=VehicleState.VALID_POSITION_XY | VehicleState.VALID_HEADING)
    state.orientation.w = 1.0
    scans = []
    for k in range(160):
        ranges, amin, inc = scan_of(720, k / 20.0)
        s = LaserScan(angle_min=amin, angle_max=amin + inc * 719, angle_increment=inc, range_min=0.2, range_max=30.0)
        s.ranges = ranges.tolist()
        scans.append((k / 20.0, s))
    time.sleep(3.0)  # discovery
    results = []
    try:
        for with_scans in (False, True):
            start, c0, k = time.monotonic(), cpu_s(proc.pid), 0
            while (now := time.monotonic()) - start < WINDOW_S:
                stamp = s_to_stamp(now)
                imu.header.stamp = state.header.stamp = stamp
                pub_imu.publish(imu)
                t_scan, scan = scans[(k // 25) % len(scans)]
                state.position.x, state.position.y = 0.3 * t_scan, 0.1 * t_scan
                w, qx, qy, qz = quat.from_euler(0.0, 0.0, 0.2 * t_scan)
                state.orientation.w, state.orientation.z = w, qz
                pub_state.publish(state)
                if with_scans and k % 25 == 0:
                    scan.header.stamp = stamp
                    pub_scan.publish(scan)
                k += 1
                time.sleep(max(0.0, start + k * 0.002 - time.monotonic()))
            results.append(100.0 * (cpu_s(proc.pid) - c0) / (time.monotonic() - start))
    finally:
        proc.terminate()
        proc.wait(timeout=10)
        node.destroy_node()
        rclpy.shutdown()
    return results[0], results[1]


def main() -> int:
    print("per scan, in-process (400 scans at 20 Hz, 4 posts + 1 mover + a 30 m wall, moving vehicle):")
    print(f"{'beams':>6} {'pipeline med':>13} {'p99':>7} {'msgs+markers med':>17} {'p99':>7} {'tracks':>7}")
    for beams in (360, 720):
        pipe, msgs, n = in_process(beams)
        print(f"{beams:>6} {np.median(pipe):>10.2f} ms {np.percentile(pipe, 99):>5.2f} ms "
              f"{np.median(msgs):>14.2f} ms {np.percentile(msgs, 99):>5.2f} ms {n:>7}")
    probe = StallProbe()
    without, with_scans = process_cpu()
    stalls = probe.stop()
    worst = max((s for _, s in stalls), default=float("nan"))
    print(f"\nperception process, {WINDOW_S:.0f} s windows, 500 Hz IMU + 500 Hz navigation/state fed throughout:")
    print(f"  CPU without scans {without:5.1f} %   with 720-beam scans at 20 Hz {with_scans:5.1f} %   "
          f"(+{with_scans - without:.1f} % of a core, ratio {with_scans / without:.2f})")
    print(f"  platform-stall probe: worst oversleep {worst:.1f} ms over {len(stalls)} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
