"""The installed `core` executable as a real process over real DDS."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from ament_index_python.packages import get_package_prefix

CORE = Path(get_package_prefix("c4d_gnc")) / "lib" / "c4d_gnc" / "core"


@pytest.fixture(scope="module")
def ros(ros_node):
    return ros_node


def spin_until(executor, predicate, timeout, every=None):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if every:
            every()
        executor.spin_once(timeout_sec=0.005)
        if predicate():
            return True
    return False


def test_core_process_schedule_stats_arm_and_clean_stop(ros, module_processes):
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Imu

    from c4d_interfaces.msg import ActuatorCommand, ExecutorStats, ScheduleTable, VehicleState, VehicleStatus
    from c4d_interfaces.srv import VehicleCommand

    node, executor = ros
    assert CORE.is_file()
    proc = module_processes.spawn("core", [str(CORE)])
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    best = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
    got: dict[str, list] = {"schedule": [], "stats": [], "act": [], "status": []}
    node.create_subscription(ScheduleTable, "gnc/schedule", got["schedule"].append, latched)
    node.create_subscription(ExecutorStats, "gnc/executor_stats", got["stats"].append, 10)
    node.create_subscription(ActuatorCommand, "control/actuators", got["act"].append, best)
    node.create_subscription(VehicleStatus, "vehicle/status", got["status"].append, latched)
    assert spin_until(executor, lambda: got["schedule"] and len(got["stats"]) >= 2, 20), module_processes.log_of(proc)

    table = got["schedule"][0]
    entries = {e.name: e for e in table.entries}
    assert set(entries) == {"state_update", "guidance", "position_control", "attitude_control", "rate_control",
                            "mixer", "status"}
    assert entries["rate_control"].divider == 1 and entries["guidance"].divider == 10
    assert table.method == "gcdplus" and table.tick_period_us == 2000.0
    # core.yaml states the cascade's data dependencies (precedence edges): GCD+ does not place them itself, the
    # phases are repaired after it and the zero-interference certificate is not claimed (docs/gcdplus.md § SPC)
    assert not table.certificate_holds
    stats = got["stats"][-1]
    # a 1 s window is 500 tick slots, each executed or skipped after an overrun (a loaded machine
    # may stall the process; the window still ends on a tick deadline)
    assert stats.tick_rate_hz == 500.0 and len(stats.tasks) == 7
    assert 250 <= stats.ticks <= 500 <= stats.ticks + stats.skipped_ticks, stats
    assert {t.name: t.count for t in stats.tasks}["rate_control"] == stats.ticks
    assert got["status"] and not got["status"][-1].armed

    client = node.create_client(VehicleCommand, "gnc/command")
    assert client.wait_for_service(timeout_sec=10)

    def call(**fields):
        future = client.call_async(VehicleCommand.Request(**fields))
        assert spin_until(executor, future.done, 10)
        return future.result()

    refused = call(command=VehicleCommand.Request.CMD_ARM)
    assert refused.result == VehicleCommand.Response.RESULT_TEMPORARILY_REJECTED and "stale" in refused.message

    pub_imu = node.create_publisher(Imu, "perception/imu", best)
    pub_state = node.create_publisher(VehicleState, "navigation/state", best)

    def feed():
        now = node.get_clock().now().to_msg()
        imu = Imu()
        imu.header.stamp = now
        pub_imu.publish(imu)
        state = VehicleState()
        state.header.stamp = now
        state.orientation.w = 1.0
        state.valid = VehicleState.VALID_POSITION_XY | VehicleState.VALID_POSITION_Z | VehicleState.VALID_ATTITUDE
        pub_state.publish(state)

    spin_until(executor, lambda: False, 1.0, every=feed)
    accepted = call(command=VehicleCommand.Request.CMD_ARM)
    assert accepted.result == VehicleCommand.Response.RESULT_ACCEPTED, accepted.message
    got["act"].clear()
    assert spin_until(executor, lambda: any(m.armed for m in got["act"]), 5, every=feed)
    armed = [m for m in got["act"] if m.armed][-1]
    assert len(armed.outputs) == 4 and all(o == pytest.approx(0.05) for o in armed.outputs)  # idle on the ground
    assert spin_until(executor, lambda: got["status"] and got["status"][-1].armed, 5, every=feed)

    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=10) == 0
    spin_until(executor, lambda: False, 0.5)
    last = got["act"][-1]
    assert not last.armed and all(o == 0.0 for o in last.outputs)
    assert "stopped: motors commanded to zero" in module_processes.log_of(proc)


def test_bad_config_one_line_exit_2(tmp_path, ros_env):
    bad = tmp_path / "core.yaml"
    bad.write_text("executive:\n  tick_hz: 500\n  tasks:\n    - {name: mixer, group: magic, rate_hz: 500, budget_us: 10}\n")
    result = subprocess.run([str(CORE), "--ros-args", "-p", f"config:={bad}"], env=ros_env, capture_output=True,
                            text=True, timeout=60)
    assert result.returncode == 2
    errors = [line for line in result.stderr.splitlines() if line.strip()]
    assert errors == ["core: error: executive task 'mixer': unknown group 'magic' (groups: input, estimation, guidance, "
                      "control, actuators, telemetry, default)"]


def test_missing_airframe_field_exit_2(tmp_path, ros_env):
    import yaml

    from c4d_common.airframe import default_airframe_path

    doc = yaml.safe_load(default_airframe_path("quad_x").read_text())
    del doc["inertia_kg_m2"]
    frame = tmp_path / "frame.yaml"
    frame.write_text(yaml.safe_dump(doc))
    result = subprocess.run([str(CORE), "--ros-args", "-p", f"airframe:={frame}"], env=ros_env, capture_output=True,
                            text=True, timeout=60)
    assert result.returncode == 2 and "missing field 'inertia_kg_m2'" in result.stderr
    assert sys.executable  # the test ran in the project venv
