"""Whole graph in real time over DDS: sim → perception → navigation → core → sim, four processes.

Take-off to 5 m, hover 30 s, land: the estimator is compared with the simulator's ground
truth (both in the simulator's home frame), the hold with its target, and the core's own
profiler is checked for overruns.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from c4d_testing import installed_executable, spin_for

from c4d_common.geodesy import GeoOrigin

SIM_HOME = GeoOrigin(43.5629, 1.4815, 146.0)  # start of config/sim.yaml
NODES = [("c4d_sim", "sim", []), ("c4d_gnc", "perception", []), ("c4d_gnc", "navigation", []),
         ("c4d_gnc", "core", ["--ros-args", "-p", "rt_priority:=50"])]


@pytest.fixture(scope="module")
def graph(module_processes, ros_node):
    procs = {name: module_processes.spawn(name, [installed_executable(pkg, name), *args]) for pkg, name, args in NODES}
    return (*ros_node, procs, module_processes)


def test_takeoff_hover_land(graph):
    from nav_msgs.msg import Odometry
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    from c4d_common import quat
    from c4d_interfaces.msg import ExecutorStats, VehicleState, VehicleStatus
    from c4d_interfaces.srv import VehicleCommand

    node, executor, procs, group = graph
    best = QoSProfile(depth=50, reliability=ReliabilityPolicy.BEST_EFFORT)
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    rec = {"truth": [], "state": [], "status": [], "stats": []}
    phase = {"name": "ground"}

    def on_truth(m):
        p, q = m.pose.pose.position, m.pose.pose.orientation
        rec["truth"].append((m.header.stamp.sec + m.header.stamp.nanosec * 1e-9, (p.x, p.y, p.z), (q.w, q.x, q.y, q.z),
                             phase["name"]))

    def on_state(m):
        p, q, o = m.position, m.orientation, m.origin
        rec["state"].append((m.header.stamp.sec + m.header.stamp.nanosec * 1e-9, (p.x, p.y, p.z), (q.w, q.x, q.y, q.z),
                             (o.latitude, o.longitude, o.altitude), m.valid, phase["name"]))

    node.create_subscription(Odometry, "sim/ground_truth", on_truth, best)
    node.create_subscription(VehicleState, "navigation/state", on_state, best)
    node.create_subscription(VehicleStatus, "vehicle/status", rec["status"].append, latched)
    node.create_subscription(ExecutorStats, "gnc/executor_stats", rec["stats"].append, 10)
    client = node.create_client(VehicleCommand, "gnc/command")

    spin = functools.partial(spin_for, executor, watch=(group, procs))

    def call(**fields):
        future = client.call_async(VehicleCommand.Request(**fields))
        assert spin(10, future.done)
        return future.result()

    assert client.wait_for_service(timeout_sec=30)
    valid = VehicleState.VALID_POSITION_XY | VehicleState.VALID_ATTITUDE | VehicleState.VALID_ORIGIN
    assert spin(30, lambda: rec["state"] and rec["state"][-1][4] & valid == valid), "estimator never became valid"
    spin(1.0)
    hold_xy = np.mean([s[1][:2] for s in rec["state"][-200:]], axis=0)
    for _ in range(10):  # "temporarily rejected" (inputs not fresh yet) is worth a retry, like the mission does
        reply = call(command=VehicleCommand.Request.CMD_TAKEOFF, altitude=5.0)
        if reply.result != VehicleCommand.Response.RESULT_TEMPORARILY_REJECTED:
            break
        spin(1.0)
    assert reply.result == VehicleCommand.Response.RESULT_ACCEPTED, reply.message
    assert spin(25, lambda: rec["status"] and rec["status"][-1].nav_state == VehicleStatus.NAV_HOLD
                and rec["status"][-1].landed_state == VehicleStatus.LANDED_IN_AIR), "take-off did not complete"
    phase["name"] = "settle"
    spin(3.0)
    phase["name"] = "hover"
    spin(30.0)
    phase["name"] = "land"
    reply = call(command=VehicleCommand.Request.CMD_LAND)
    assert reply.result == VehicleCommand.Response.RESULT_ACCEPTED, reply.message
    assert spin(30, lambda: rec["status"] and not rec["status"][-1].armed), "no landing detection / disarm"
    assert rec["status"][-1].landed_state == VehicleStatus.LANDED_ON_GROUND
    assert rec["truth"][-1][1][2] < 0.05

    # --- estimator vs ground truth during the hover, in the simulator's home frame
    truth_t = np.array([t[0] for t in rec["truth"]])
    home = GeoOrigin(*next(s[3] for s in rec["state"] if s[4] & VehicleState.VALID_ORIGIN))
    horizontal, attitude = [], []
    for t, p, q, _, _, name in rec["state"]:
        if name != "hover":
            continue
        k = int(np.clip(np.searchsorted(truth_t, t), 1, len(truth_t) - 1))
        k = k if abs(truth_t[k] - t) < abs(truth_t[k - 1] - t) else k - 1
        if abs(truth_t[k] - t) > 0.006:
            continue
        est = SIM_HOME.to_enu(*home.to_geodetic(*p))
        tp, tq = rec["truth"][k][1], rec["truth"][k][2]
        horizontal.append(math.hypot(est[0] - tp[0], est[1] - tp[1]))
        attitude.append(math.degrees(quat.angle_between(q, tq)))
    assert len(horizontal) > 1000
    horizontal_rms = math.sqrt(np.mean(np.square(horizontal)))
    attitude_rms = math.sqrt(np.mean(np.square(attitude)))
    target = np.array(SIM_HOME.to_enu(*home.to_geodetic(hold_xy[0], hold_xy[1], 5.0)))
    hover = np.array([t[1] for t in rec["truth"] if t[3] == "hover"])
    hold_errors = np.linalg.norm(hover - target, axis=1)
    stats = rec["stats"][-1]
    hold_h = math.sqrt(np.mean(np.sum((hover[:, :2] - target[:2]) ** 2, axis=1)))
    hold_v = math.sqrt(np.mean((hover[:, 2] - target[2]) ** 2))
    print(f"\nestimator horizontal RMS {horizontal_rms:.3f} m, attitude RMS {attitude_rms:.2f}°, hold error RMS "
          f"{math.sqrt(np.mean(hold_errors ** 2)):.3f} m (horizontal {hold_h:.3f}, vertical {hold_v:.3f}, max "
          f"{hold_errors.max():.3f} m), core overruns "
          f"{stats.overruns_total} of {stats.ticks_total} ticks, jitter p99 {stats.release_jitter_p99_us:.0f} µs")
    assert horizontal_rms <= 0.3
    assert attitude_rms <= 2.0
    assert math.sqrt(np.mean(hold_errors ** 2)) <= 0.5
    # Platform stalls of this shared VM (bench/executive_jitter.py probes them: a bare spin loop
    # is frozen for up to milliseconds several times per 10 s, even under SCHED_FIFO) cost rare
    # overruns in bursts; the core's own work never needs more than half a tick (load max above).
    assert stats.overruns_total <= stats.ticks_total // 200
