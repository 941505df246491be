"""Live EKF and failsafe parameters on the real nodes (navigation and health started alone, no sim;
docs/parameters.md): rclpy SetParameters of a NaN / out-of-range / cross-rule-breaking value is
refused with the reason; a valid one is applied — navigation before its next IMU sample (the log
names that sample's time), health at its next tick (the log names the tick) — and persisted in the
vehicle's store (one file per node), from which a restarted node restores it. A few seconds."""

from __future__ import annotations

import os
from pathlib import Path

import yaml
from c4d_testing import call_service, installed_executable, spin_for
from lifecycle_msgs.msg import State
from lifecycle_msgs.srv import GetState
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu

from c4d_ros import manifest

VEHICLE = "live-p2"


def _store(node: str) -> Path:
    base = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(base) / "c4d" / "vehicles" / VEHICLE / f"{node}.yaml"


def _active(spin, node, name: str, seconds: float = 30.0) -> bool:
    client = node.create_client(GetState, f"/{name}/get_state")
    return spin(seconds, lambda: client.service_is_ready() and call_service(
        spin, client, GetState.Request()).current_state.id == State.PRIMARY_STATE_ACTIVE)


def _set(spin, client, name: str, value) -> tuple[bool, str]:
    request = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
    result = call_service(spin, client, request).results[0]
    return bool(result.successful), str(result.reason)


def test_navigation_and_health_parameters_refused_applied_persisted(processes, ros_node):
    node, executor = ros_node

    def spin(seconds, until=None):
        return spin_for(executor, seconds, until)
    for name in ("navigation", "health"):
        _store(name).unlink(missing_ok=True)
    nav = processes.spawn("navigation", [installed_executable("c4d_gnc", "navigation"), "--ros-args", "-p",
                                         f"vehicle:={VEHICLE}"])
    health = processes.spawn("health", [installed_executable("c4d_health", "health"), "--ros-args", "-p",
                                        f"vehicle:={VEHICLE}"])
    assert _active(spin, node, "navigation"), processes.log_of(nav)
    assert _active(spin, node, "health"), processes.log_of(health)

    navp = node.create_client(SetParameters, "/navigation/set_parameters")
    ok, reason = _set(spin, navp, "ekf.gps_gate", float("nan"))  # rclpy's descriptor range check answers first
    assert not ok and "ekf.gps_gate" in reason and "nan" in reason, reason
    ok, reason = _set(spin, navp, "ekf.gps_gate", 0.5)
    assert not ok and "ekf.gps_gate" in reason and "Min: 1.0" in reason, reason
    ok, reason = _set(spin, navp, "ekf.gps_gate", 3)  # an integer for a double parameter
    assert not ok and "expected 'Type.DOUBLE'" in reason, reason
    assert not _set(spin, navp, "mag_declination_deg", 3.0)[0]  # read-only: a restart
    assert _set(spin, navp, "ekf.gps_gate", 3.0) == (True, "")
    imu = node.create_publisher(Imu, manifest.P_IMU.name, manifest.P_IMU.qos)
    sample = Imu()
    sample.header.stamp.sec, sample.header.stamp.nanosec = 100, 2_000_000
    sample.linear_acceleration.z = 9.80665
    for _ in range(5):
        imu.publish(sample)
        if spin(0.5, lambda: "parameters applied at IMU sample" in processes.log_of(nav)):
            break
    assert "parameters applied at IMU sample t=100.002000 s: ekf.gps_gate=3" in processes.log_of(nav), \
        processes.log_of(nav)[-1500:]

    hp = node.create_client(SetParameters, "/health/set_parameters")
    assert _set(spin, hp, "battery_critical_threshold", 0.35) == (
        False, "battery_critical_threshold (0.35) must be below battery_low_threshold (0.3)")
    ok, reason = _set(spin, hp, "core_stall_repeat_count", 2.5)
    assert not ok and "not an integer" in reason, reason
    assert _set(spin, hp, "battery_low_threshold", 0.4) == (True, "")
    assert spin(2.0, lambda: "parameters applied at health tick" in processes.log_of(health)), processes.log_of(health)
    assert "battery_low_threshold=0.4" in processes.log_of(health)
    assert spin(3.0, lambda: _store("navigation").exists() and _store("health").exists())
    assert yaml.safe_load(_store("navigation").read_text()) == {"ekf.gps_gate": 3.0}
    assert yaml.safe_load(_store("health").read_text()) == {"battery_low_threshold": 0.4}
    codes = processes.stop()
    assert all(code == 0 for code in codes.values()), codes

    again = processes.spawn("navigation2", [installed_executable("c4d_gnc", "navigation"), "--ros-args", "-p",
                                            f"vehicle:={VEHICLE}"])
    assert spin(20.0, lambda: "restored 1 parameter(s)" in processes.log_of(again)), processes.log_of(again)
    assert "ekf.gps_gate=3" in processes.log_of(again)
    processes.stop()
    for name in ("navigation", "health"):
        _store(name).unlink(missing_ok=True)
