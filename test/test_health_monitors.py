"""Health node on the ground with the real graph: monitors raise their events from real
faults injected in the sim, and a dead node is detected within 1 s (no flight, so no
failsafe action: the policy's events only act in the air)."""

from __future__ import annotations

import functools
import os
import signal
import time

from c4d_testing import installed_executable, spin_for

NODES = [("c4d_sim", "sim", []), ("c4d_gnc", "perception", []), ("c4d_gnc", "navigation", []),
         ("c4d_gnc", "core", []), ("c4d_mission", "mission", []), ("c4d_health", "health", [])]


def test_monitors_and_dead_node_detection(module_processes, ros_node):
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    procs = {name: module_processes.spawn(name, [installed_executable(pkg, name), *args]) for pkg, name, args in NODES}
    node, executor = ros_node
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    summary, diagnostics = [], []
    node.create_subscription(DiagnosticStatus, "health/summary",
                             lambda m: summary.append({kv.key: kv.value for kv in m.values}), latched)
    node.create_subscription(DiagnosticArray, "diagnostics", diagnostics.append, 10)
    params = node.create_client(SetParameters, "sim/set_parameters")

    spin = functools.partial(spin_for, executor)

    def active():
        return summary[-1]["active"].split(",") if summary and summary[-1]["active"] else []

    assert spin(40, lambda: summary and not summary[-1]["dead_nodes"] and "gps_loss" not in active()
                and "estimator_invalid" not in active()), summary[-1:] or "no summary"
    assert params.wait_for_service(timeout_sec=20)
    future = params.call_async(SetParameters.Request(parameters=[Parameter("fault.gps_loss", value=True).to_parameter_msg()]))
    assert spin(10, future.done) and future.result().results[0].successful
    assert spin(10, lambda: "gps_loss" in active()), summary[-1]
    assert summary[-1]["failsafe"] in ("NONE", "WARN")  # on the ground: reported, no action
    assert spin(3, lambda: diagnostics and any(s.name == "health/gps_loss" and s.level == DiagnosticStatus.ERROR
                                               for s in diagnostics[-1].status))
    os.killpg(procs["mission"].pid, signal.SIGKILL)
    t0 = time.monotonic()
    assert spin(5, lambda: "mission" in summary[-1]["dead_nodes"])
    detected = time.monotonic() - t0
    print(f"\ndead node detected after {detected:.2f} s")
    assert detected <= 1.0
