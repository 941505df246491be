"""Managed nodes (c4d_ros.lifecycle) through the standard lifecycle services, and `c4d up`'s lifecycle
manager (c4d_bringup.lifecycle_manager, system modes). docs/lifecycle.md.

- payload and core started alone with autostart false: every transition through /<node>/change_state
  with /<node>/get_state checks (configure, activate, deactivate, activate); an invalid transition is
  answered false, not a crash; the core refuses deactivate and shutdown while armed, with its reason logged;
- `c4d up` of a system whose core cannot configure (its config file does not exist): exit 1, the core's
  reason printed, nothing left running;
- `c4d up` under the bundled system modes: payload configured but inactive while vehicle/status says
  disarmed, active once it says armed (the test publishes the status, as the core would);
- health watches lifecycle states: navigation deactivated through its service is `node_inactive` in
  health/summary within 1 s, and clears within 1 s of its re-activation.
No sim, no flight: each part is a few seconds.
"""

from __future__ import annotations

import time
from functools import partial

import pytest
import yaml
from c4d_testing import call_service, installed_executable, spin_for
from diagnostic_msgs.msg import DiagnosticStatus
from lifecycle_msgs.msg import State, Transition
from lifecycle_msgs.srv import ChangeState, GetState

from c4d_interfaces.msg import VehicleStatus
from c4d_interfaces.srv import VehicleCommand
from c4d_ros import manifest

ACTIVE, INACTIVE, UNCONFIGURED = State.PRIMARY_STATE_ACTIVE, State.PRIMARY_STATE_INACTIVE, State.PRIMARY_STATE_UNCONFIGURED


class Lifecycle:
    """Client of one node's change_state / get_state."""

    def __init__(self, node, executor, name: str) -> None:
        self.name, self.spin = name, partial(spin_for, executor)
        self.change = node.create_client(ChangeState, f"/{name}/change_state")
        self.get = node.create_client(GetState, f"/{name}/get_state")

    def state(self) -> int:
        return call_service(self.spin, self.get, GetState.Request()).current_state.id

    def set(self, transition: int) -> bool:
        request = ChangeState.Request()
        request.transition.id = transition
        return bool(call_service(self.spin, self.change, request).success)


def wait_state(lc: Lifecycle, state: int, seconds: float) -> bool:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if lc.state() == state:
            return True
        lc.spin(0.3)
    return False


def test_transitions_through_the_services_and_the_armed_core_refuses(processes, ros_node):
    node, executor = ros_node
    nodes = {name: processes.spawn(name, [installed_executable(pkg, name), "--ros-args", "-p", "autostart:=false"])
             for pkg, name in (("c4d_mission", "payload"), ("c4d_gnc", "core"))}
    payload, core = Lifecycle(node, executor, "payload"), Lifecycle(node, executor, "core")
    for lc in (payload, core):
        assert lc.state() == UNCONFIGURED, processes.log_of(nodes[lc.name])
        assert not lc.set(Transition.TRANSITION_ACTIVATE)  # invalid from unconfigured: refused, node alive
        for transition, state in ((Transition.TRANSITION_CONFIGURE, INACTIVE), (Transition.TRANSITION_ACTIVATE, ACTIVE),
                                  (Transition.TRANSITION_DEACTIVATE, INACTIVE), (Transition.TRANSITION_ACTIVATE, ACTIVE)):
            assert lc.set(transition), f"{lc.name}: transition {transition}\n{processes.log_of(nodes[lc.name])[-1500:]}"
            assert lc.state() == state
        assert nodes[lc.name].poll() is None
    # the armed core: deactivate and shutdown refused with the reason, still active
    command = node.create_client(VehicleCommand, manifest.CORE_COMMAND.name)
    arm = call_service(core.spin, command, VehicleCommand.Request(command=VehicleCommand.Request.CMD_ARM, force=True))
    assert arm.result == VehicleCommand.Response.RESULT_ACCEPTED, arm.message
    core.spin(0.3)  # applied at the next tick
    assert not core.set(Transition.TRANSITION_DEACTIVATE)
    assert not core.set(Transition.TRANSITION_ACTIVE_SHUTDOWN)
    assert core.state() == ACTIVE
    core.spin(0.5)
    assert "lifecycle: deactivate failed: the vehicle is armed" in processes.log_of(nodes["core"])
    disarm = call_service(core.spin, command, VehicleCommand.Request(command=VehicleCommand.Request.CMD_DISARM, force=True))
    assert disarm.result == VehicleCommand.Response.RESULT_ACCEPTED, disarm.message
    core.spin(0.3)
    assert core.set(Transition.TRANSITION_DEACTIVATE) and core.state() == INACTIVE
    assert core.set(Transition.TRANSITION_CLEANUP) and core.state() == UNCONFIGURED
    assert core.set(Transition.TRANSITION_CONFIGURE) and core.state() == INACTIVE  # re-configure after cleanup
    codes = processes.stop()
    assert all(code == 0 for code in codes.values()), codes


def system_yaml(tmp_path, nodes: dict) -> str:
    doc = {"platform": "hardware", "run_root": str(tmp_path / "runs"), "shutdown_timeout_s": 5, "restart_spacing_s": 0,
           "nodes": nodes, "modes": {"preflight": {"inactive": ["payload"]}, "landing": {"inactive": ["payload"]}}}
    path = tmp_path / "system.yaml"
    path.write_text(yaml.safe_dump(doc))
    return str(path)


def test_c4d_up_stops_on_a_failed_configure_with_the_reason(processes, tmp_path):
    config = system_yaml(tmp_path, {"core": {"parameters": {"config": str(tmp_path / "missing.yaml")}},
                                    "payload": {}})
    up = processes.spawn("up", [installed_executable("c4d_bringup", "c4d"), "up", "--config", config,
                                "--run-dir", str(tmp_path / "run")])
    try:
        up.wait(timeout=60)
    except Exception:
        pytest.fail(f"c4d up still running:\n{processes.log_of(up)[-2000:]}")
    out = processes.log_of(up)
    assert up.returncode == 1, out
    line = next((x for x in out.splitlines() if "lifecycle: error: core: configure failed:" in x), None)
    assert line is not None and "missing.yaml" in line, out
    assert "down: every node stopped" in out


def test_payload_is_inactive_on_the_ground_and_active_in_flight(processes, ros_node, tmp_path):
    node, executor = ros_node
    config = system_yaml(tmp_path, {"payload": {"parameters": {"output_dir": str(tmp_path / "captures")}}})
    up = processes.spawn("up", [installed_executable("c4d_bringup", "c4d"), "up", "--config", config,
                                "--run-dir", str(tmp_path / "run")])
    status = node.create_publisher(VehicleStatus, manifest.STATUS.name, manifest.STATUS.qos)
    payload = Lifecycle(node, executor, "payload")
    status.publish(VehicleStatus(armed=False, landed_state=VehicleStatus.LANDED_ON_GROUND))
    assert wait_state(payload, INACTIVE, 30), processes.log_of(up)
    payload.spin(2.5)  # a check period of the manager: still inactive on the ground
    assert payload.state() == INACTIVE
    status.publish(VehicleStatus(armed=True, landed_state=VehicleStatus.LANDED_IN_AIR, nav_state=VehicleStatus.NAV_MISSION))
    assert wait_state(payload, ACTIVE, 10), (tmp_path / "run" / "logs" / "lifecycle_manager.log").read_text()
    status.publish(VehicleStatus(armed=True, landed_state=VehicleStatus.LANDED_LANDING, nav_state=VehicleStatus.NAV_LAND))
    assert wait_state(payload, INACTIVE, 10)
    assert up.poll() is None
    codes = processes.stop()
    assert all(code == 0 for code in codes.values()), codes


def test_health_reports_a_deactivated_navigation_until_it_is_active_again(processes, ros_node):
    node, executor = ros_node
    health = processes.spawn("health", [installed_executable("c4d_health", "health")])
    summary: list[DiagnosticStatus] = []
    node.create_subscription(DiagnosticStatus, manifest.HEALTH_SUMMARY.name, summary.append, manifest.HEALTH_SUMMARY.qos)
    hl = Lifecycle(node, executor, "health")
    assert wait_state(hl, ACTIVE, 30), processes.log_of(health)
    nav_proc = processes.spawn("navigation", [installed_executable("c4d_gnc", "navigation")])
    nav = Lifecycle(node, executor, "navigation")
    assert wait_state(nav, ACTIVE, 30), processes.log_of(nav_proc)

    def inactive() -> str:
        return {kv.key: kv.value for kv in summary[-1].values}["inactive_nodes"] if summary else "?"
    nav.spin(1.0)  # health's subscription to /navigation/transition_event matched
    assert inactive() == "", summary[-1] if summary else "no health/summary"
    assert nav.set(Transition.TRANSITION_DEACTIVATE)
    assert nav.spin(1.0, lambda: inactive() == "navigation (inactive)"), inactive()
    assert "node_inactive: navigation (inactive)" in summary[-1].message
    assert nav.set(Transition.TRANSITION_ACTIVATE)
    assert nav.spin(1.0, lambda: inactive() == ""), inactive()
    codes = processes.stop()
    assert all(code == 0 for code in codes.values()), codes
