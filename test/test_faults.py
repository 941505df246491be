"""Fault injection: each sim fault, set through its ROS parameter at run time, raises the right
perception health flag (real DDS between real processes); bad samples never pass perception."""

from __future__ import annotations

import math
import subprocess
import time

import pytest
from c4d_testing import installed_executable


@pytest.fixture(scope="module")
def ros(ros_node):
    return ros_node


def spin_until(executor, predicate, timeout):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        executor.spin_once(timeout_sec=0.02)
        if predicate():
            return True
    return False


FAULTS = [  # parameter, value, sensor, expected state
    ("fault.imu_dropout", True, "imu", "STALE"),
    ("fault.imu_freeze", True, "imu", "FROZEN"),
    ("fault.gps_loss", True, "gps", "STALE"),
    ("fault.baro_freeze", True, "baro", "FROZEN"),
    ("fault.baro_dropout", True, "baro", "STALE"),
    ("fault.mag_dropout", True, "mag", "STALE"),
    ("fault.range_dropout", True, "range_down", "STALE"),
]


def test_each_fault_raises_its_health_flag(ros, processes):
    from diagnostic_msgs.msg import DiagnosticArray
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import BatteryState, NavSatFix

    node, executor = ros
    sim = processes.spawn("sim", [installed_executable("c4d_sim", "sim")])
    processes.spawn("perception", [installed_executable("c4d_gnc", "perception")])
    health: dict[str, str] = {}

    def on_health(msg):
        for status in msg.status:
            health[status.hardware_id] = next(kv.value for kv in status.values if kv.key == "state")

    node.create_subscription(DiagnosticArray, "perception/health", on_health, 10)
    best = QoSProfile(depth=20, reliability=ReliabilityPolicy.BEST_EFFORT)
    battery, fixes = [], []
    node.create_subscription(BatteryState, "sensors/battery", battery.append, best)
    node.create_subscription(NavSatFix, "sensors/gps", fixes.append, best)
    client = node.create_client(SetParameters, "sim/set_parameters")
    assert client.wait_for_service(timeout_sec=30), processes.log_of(sim)

    def set_param(name, value):
        future = client.call_async(SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()]))
        assert spin_until(executor, future.done, 10)
        assert future.result().results[0].successful, future.result().results[0].reason

    all_ok = lambda: len(health) == 5 and all(v == "OK" for v in health.values())  # noqa: E731
    assert spin_until(executor, all_ok, 30), health
    for name, value, sensor, expected in FAULTS:
        set_param(name, value)
        assert spin_until(executor, lambda s=sensor, e=expected: health.get(s) == e, 10), (name, health)
        set_param(name, not value)
        assert spin_until(executor, all_ok, 15), (name, "did not recover", health)

    # battery drain: the state of charge falls 1000x faster than the avionics load alone explains
    spin_until(executor, lambda: len(battery) > 5, 5)
    before = battery[-1].percentage
    set_param("fault.battery_drain_factor", 1000.0)
    spin_until(executor, lambda: False, 2.0)
    assert before - battery[-1].percentage > 0.05
    # GNSS drift: the reported fix walks away at the injected rate
    fixes.clear()
    set_param("fault.gps_drift_m_s", [5.0, 0.0, 0.0])
    spin_until(executor, lambda: False, 2.0)
    dlon = fixes[-1].longitude - fixes[0].longitude
    east = math.radians(dlon) * 6378137.0 * math.cos(math.radians(fixes[0].latitude))
    assert east > 5.0
    # invalid parameter values are refused with a reason
    future = client.call_async(SetParameters.Request(parameters=[
        Parameter("fault.motor_health", value=[1.0, 2.0]).to_parameter_msg()]))
    assert spin_until(executor, future.done, 10) and not future.result().results[0].successful


def test_out_of_range_fault_start_value_exits_2_with_one_line_naming_it(ros_env):
    result = subprocess.run([installed_executable("c4d_sim", "sim"), "--ros-args", "-p", "fault.battery_drain_factor:=-1.0"],
                            capture_output=True, text=True, env=ros_env, timeout=60)
    assert result.returncode == 2, result.stderr
    assert result.stderr.splitlines() == ["sim: error: parameter 'fault.battery_drain_factor': -1.0 is outside [0, 1e+06]"]


def test_nan_and_out_of_range_samples_are_rejected_and_counted(ros, processes):
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Imu

    node, executor = ros
    processes.spawn("perception", [installed_executable("c4d_gnc", "perception")])
    best = QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT)
    out, reports = [], []
    pub = node.create_publisher(Imu, "sensors/imu", best)
    node.create_subscription(Imu, "perception/imu", out.append, best)
    node.create_subscription(DiagnosticArray, "perception/health", reports.append, 10)
    assert spin_until(executor, lambda: pub.get_subscription_count() > 0 and reports, 20)
    sent_bad = 0
    for k in range(300):
        m = Imu()
        m.linear_acceleration.z = 9.8
        if k % 3 == 0:
            m.angular_velocity.x = math.nan
            sent_bad += 1
        elif k % 3 == 1:
            m.linear_acceleration.x = 500.0  # 50 g: out of range
            sent_bad += 1
        pub.publish(m)
        executor.spin_once(timeout_sec=0.004)

    def counts():
        for status in reversed(reports[-1].status if reports else []):
            if status.hardware_id == "imu":
                kv = {v.key: v.value for v in status.values}
                return int(kv["accepted"]), int(kv["rejected"])
        return 0, 0

    assert spin_until(executor, lambda: sum(counts()) >= 290, 10), counts()
    accepted, rejected = counts()
    assert rejected >= 0.95 * sent_bad and accepted <= 300 - sent_bad
    spin_until(executor, lambda: False, 0.5)
    assert out and all(math.isfinite(m.angular_velocity.x) and abs(m.linear_acceleration.x) < 160 for m in out)
