"""Lockstep is deterministic: the same flight on a quiet and on a saturated machine is the same bit for bit.

sim (lockstep) → perception → navigation → core (lockstep) over DDS, four processes, flown twice:
once on a quiet machine, once with a busy loop on every CPU. Each run: the sim starts held at
t = 0; once the graph is discovered the test lets it run to t = 3 s (held again), commands a
take-off to 3 m — so the command lands at the same simulated tick in both runs — and lets it run
to t = 8 s. The ground truth (sim/ground_truth, 100 Hz simulated) of both runs must be identical,
float for float, and no step may be missed: every actuator command the sim received is 2 ms
(one step) after the previous one, no IMU sample was late or dropped, the core neither overran
nor skipped a tick. Prints the real-time factor (simulated seconds per wall second) of each run.

Fails when lockstep leaks wall time into the flight: a tick that ran before its step's inputs
arrived, a command applied at a different tick, a sim that stepped without the core's answer —
each shows up as diverging trajectories, most of all under the CPU hog.
"""

from __future__ import annotations

import functools
import os
import sys
import time

import pytest
from c4d_testing import installed_executable, spin_for

HOLD_S, END_S = 3.0, 8.0
LOCKSTEP_NODES = [
    ("c4d_sim", "sim", ["-p", "lockstep:=true", "-p", "lockstep_pause_at_s:=0.0"]),
    ("c4d_gnc", "perception", ["-p", "use_sim_time:=true"]),
    ("c4d_gnc", "navigation", ["-p", "use_sim_time:=true"]),
    ("c4d_gnc", "core", ["-p", "lockstep:=true"]),
]
HOG = [sys.executable, "-c", "while True: pass"]


def stamp_ns(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def fly(node, executor, group, hogs: int) -> dict:
    """One lockstep flight; returns the truth samples by stamp, the sim's and core's figures, the RTF."""
    from diagnostic_msgs.msg import DiagnosticStatus
    from nav_msgs.msg import Odometry
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import SetParameters
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    from c4d_interfaces.msg import ExecutorStats
    from c4d_interfaces.srv import VehicleCommand

    procs = {name: group.spawn(name, [installed_executable(pkg, name), "--ros-args", *args])
             for pkg, name, args in LOCKSTEP_NODES}
    for i in range(hogs):
        procs[f"hog{i}"] = group.spawn(f"hog{i}", HOG)
    truth: dict[int, tuple] = {}
    arrival: dict[int, float] = {}  # wall time each truth sample arrived (real-time factor)
    link: list = []
    stats: list = []

    def on_truth(m):
        p, q, v, w = m.pose.pose.position, m.pose.pose.orientation, m.twist.twist.linear, m.twist.twist.angular
        arrival[stamp_ns(m.header.stamp)] = time.monotonic()
        truth[stamp_ns(m.header.stamp)] = (p.x, p.y, p.z, q.w, q.x, q.y, q.z, v.x, v.y, v.z, w.x, w.y, w.z)

    subs = [node.create_subscription(Odometry, "sim/ground_truth", on_truth,
                                     QoSProfile(depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT)),
            node.create_subscription(DiagnosticStatus, "sim/actuator_link", link.append, 10),
            node.create_subscription(ExecutorStats, "gnc/executor_stats", stats.append, 10)]
    command = node.create_client(VehicleCommand, "gnc/command")
    set_params = node.create_client(SetParameters, "sim/set_parameters")
    spin = functools.partial(spin_for, executor, watch=(group, procs))

    def held_at(t_s: float) -> bool:  # the sim's diagnostics: step t_s answered, holding
        values = {kv.key: kv.value for kv in link[-1].values} if link else {}
        return values.get("lockstep_holding") == "1" and float(values["lockstep_t"]) >= t_s - 1e-9

    def run_to(t_s: float, timeout_s: float) -> float:
        value = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=t_s)
        future = set_params.call_async(SetParameters.Request(parameters=[Parameter(name="lockstep_pause_at_s",
                                                                                   value=value)]))
        assert spin(10, future.done) and future.result().results[0].successful
        start = time.monotonic()
        assert spin(timeout_s, lambda: held_at(t_s)), f"lockstep never reached t = {t_s} s"
        return time.monotonic() - start

    try:
        assert command.wait_for_service(timeout_sec=30) and set_params.wait_for_service(timeout_sec=30)
        # held at t = 0: the core answered step 0; discovery of the whole chain settles before time moves
        assert spin(30, lambda: held_at(0.0)), "the core never answered the sim's first step"
        assert spin(30, lambda: {"perception", "navigation"} <= {n for n, _ in node.get_node_names_and_namespaces()})
        spin(2.0)
        run_to(HOLD_S, 60)
        future = command.call_async(VehicleCommand.Request(command=VehicleCommand.Request.CMD_TAKEOFF, altitude=3.0))
        assert spin(10, future.done)
        assert future.result().result == VehicleCommand.Response.RESULT_ACCEPTED, future.result().message
        run_to(END_S, 90)
        spin(1.5)  # the sim's diagnostics of the held state (the core's stats follow simulated time: none while held)
    finally:
        for name in [n for n in procs if n.startswith("hog")]:
            os.killpg(procs[name].pid, 9)
        for sub in subs:
            node.destroy_subscription(sub)
        node.destroy_client(command)
        node.destroy_client(set_params)
    values = {kv.key: float(kv.value) for kv in link[-1].values}
    return {"truth": truth, "link": values, "stats": stats[-1], "rtf": real_time_factor(arrival, 0.5, HOLD_S),
            "rtf_flight": real_time_factor(arrival, HOLD_S + 0.5, END_S)}


def real_time_factor(arrival: dict[int, float], t0_s: float, t1_s: float) -> float:
    """Simulated seconds per wall second between the truth samples nearest t0_s and t1_s (running, not held)."""
    stamps = sorted(t for t in arrival if t0_s * 1e9 <= t <= t1_s * 1e9)
    return (stamps[-1] - stamps[0]) / 1e9 / (arrival[stamps[-1]] - arrival[stamps[0]])


@pytest.fixture(scope="module")
def flights(ros_node, ros_env, tmp_path_factory):
    from c4d_testing import ProcessGroup

    node, executor = ros_node
    out = {}
    for label, hogs in (("quiet", 0), ("hog", os.cpu_count() or 2)):
        group = ProcessGroup(tmp_path_factory.mktemp(label), ros_env)
        try:
            out[label] = fly(node, executor, group, hogs)
        finally:
            group.stop()
    return out


def test_lockstep_flight_is_identical_under_cpu_load(flights):
    quiet, hog = flights["quiet"], flights["hog"]
    for label, run in flights.items():
        link, stats = run["link"], run["stats"]
        print(f"\n{label}: real-time factor {run['rtf_flight']:.2f} in flight ({run['rtf']:.2f} on the ground), "
              f"{len(run['truth'])} truth samples, max command gap {link['max_gap_ms']:.1f} ms, IMU late "
              f"{link['imu_late']:.0f} dropped {link['imu_dropped']:.0f}, core overruns {stats.overruns_total} "
              f"skipped {stats.skipped_ticks_total} of {stats.ticks_total} ticks")
        assert abs(link["max_gap_ms"] - 2.0) < 0.01, f"{label}: a step went unanswered (gap {link['max_gap_ms']} ms)"
        assert link["imu_late"] == 0 and link["imu_dropped"] == 0, label
        assert stats.overruns_total == 0 and stats.skipped_ticks_total == 0, label
    common = sorted(set(quiet["truth"]) & set(hog["truth"]))
    expected = int(END_S * 100)
    assert len(common) >= 0.95 * expected, f"only {len(common)} of {expected} truth samples seen in both runs"
    end = quiet["truth"][common[-1]]
    assert end[2] > 2.0, f"the vehicle did not take off (z = {end[2]:.2f} m)"
    differing = [t for t in common if quiet["truth"][t] != hog["truth"][t]]
    assert not differing, (f"{len(differing)} of {len(common)} truth samples differ, first at t = {differing[0] / 1e9:.3f} s: "
                           f"{quiet['truth'][differing[0]]} vs {hog['truth'][differing[0]]}")
