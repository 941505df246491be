"""The live graph is the interface manifest: `c4d up` starts the whole SITL graph, a test node reads
what DDS sees (topic names and types, publishing and subscribing nodes, the QoS every publisher
offers, the services each node serves and calls, the actions each node serves) and the test fails with
a line diff on any difference from `c4d_ros.manifest`. An action's hidden topics and services
(`<action>/_action/...`) are compared as the action, not one by one.

Why: the manifest is where names and QoS come from and what docs/ARCHITECTURE.md is generated
from; this test keeps it the truth. Hidden LatestSampler side nodes (`_<owner>_samples`) count as
their owner; ROS infrastructure (/rosout, /parameter_events, the standard parameter and
type-description services) and this test's own node are not part of the manifest. Offered depth
is compared only where discovery reports it (Fast DDS does not send it for remote endpoints).

On the same graph: every node's parameters report the values in force (issue 14 item 4), read
through the nodes' parameter services as `ros2 param dump` does — the core's config, airframe
and phase_method are core.yaml's, and no parameter is empty where a file gives its value.
"""

from __future__ import annotations

import difflib
import time
from functools import partial
from pathlib import Path

import pytest
import yaml
from c4d_testing import installed_executable, spin_for
from rclpy.action import get_action_server_names_and_types_by_node

from c4d_ros.manifest import MANIFEST, is_lifecycle_endpoint, side_node_name

ROOT = Path(__file__).resolve().parent.parent
INFRASTRUCTURE_TOPICS = {"/rosout", "/parameter_events"}
NODE_SERVICES = {"describe_parameters", "get_parameter_types", "get_parameters", "list_parameters", "set_parameters",
                 "set_parameters_atomically", "get_type_description"}  # every rclpy node has these
TEST_NODE_PREFIXES = ("c4d_test", "_c4d_test_samples_")
ACTION_INFIX = "/_action/"  # an action's own topics and services: compared as the action
SETTLE_S = 30.0  # after the ten nodes are up: the recorder subscribes to topics as it discovers them
EMPTY_MEANS_NONE = {  # parameters whose empty value in force means "none" (no file behind it)
    "/mission": {"plan_file"}, "/health": {"link_topic", "unwatched_nodes"}, "/bridge": {"signing_key_file"},
    "/recorder": {"include", "exclude"}, "/sim": {"world"},
}


def absolute(name: str) -> str:
    return name if name.startswith("/") else "/" + name


def qos_words(reliability: str, durability: str, depth: int | None) -> str:
    words = f"{reliability.lower().replace('_', ' ')}, {durability.lower().replace('_', ' ')}"
    return words if depth is None else f"{words}, depth {depth}"


class GraphReader:
    """Reads one node's view of the DDS graph as sorted lines (`topic /x: producers a, b`), the
    same wording `expected_lines` gives the manifest, so a unified diff shows each difference."""

    def __init__(self, node) -> None:
        self.node = node
        self.owner = {side_node_name(n): n for n in MANIFEST.nodes}

    def who(self, node_name: str) -> str:
        return self.owner.get(node_name, node_name)

    def harness(self, node_name: str) -> bool:
        return node_name.startswith(TEST_NODE_PREFIXES)

    def depth_visible(self) -> bool:
        return any(info.qos_profile.depth > 0 for name, _ in self.node.get_topic_names_and_types()
                   if name not in INFRASTRUCTURE_TOPICS for info in self.node.get_publishers_info_by_topic(name))

    def nodes(self) -> set[str]:
        return {name for name, _ in self.node.get_node_names_and_namespaces()}

    def lines(self, with_depth: bool) -> list[str]:
        out: set[str] = set()
        for name, types in self.node.get_topic_names_and_types():
            if name in INFRASTRUCTURE_TOPICS:
                continue
            pubs = [i for i in self.node.get_publishers_info_by_topic(name) if not self.harness(i.node_name)]
            subs = [i for i in self.node.get_subscriptions_info_by_topic(name) if not self.harness(i.node_name)]
            if not pubs and not subs or ACTION_INFIX in name or is_lifecycle_endpoint(name):
                continue  # only the test's own endpoints, or an action's topics
            out.add(f"topic {name}: type {', '.join(sorted(types))}")
            out.add(f"topic {name}: producers {', '.join(sorted({self.who(i.node_name) for i in pubs}))}")
            out.add(f"topic {name}: consumers {', '.join(sorted({self.who(i.node_name) for i in subs}))}")
            for info in pubs:
                q = info.qos_profile
                depth = q.depth if with_depth else None
                out.add(f"topic {name}: qos from {self.who(info.node_name)}: "
                        f"{qos_words(q.reliability.name, q.durability.name, depth)}")
        for node_name, namespace in self.node.get_node_names_and_namespaces():
            if self.harness(node_name):
                continue
            who = self.who(node_name)
            for role, listing in (("server", self.node.get_service_names_and_types_by_node),
                                  ("client", self.node.get_client_names_and_types_by_node)):
                for service, types in listing(node_name, namespace):
                    if service.rsplit("/", 1)[-1] in NODE_SERVICES or ACTION_INFIX in service or is_lifecycle_endpoint(service):
                        continue
                    out.add(f"service {service}: type {', '.join(sorted(types))}")
                    out.add(f"service {service}: {role} {who}")
            for action, types in get_action_server_names_and_types_by_node(self.node, node_name, namespace):
                out.add(f"action {action}: type {', '.join(sorted(types))}")
                out.add(f"action {action}: server {who}")
        return sorted(out)


def expected_lines(with_depth: bool) -> list[str]:
    out: set[str] = set()
    for t in MANIFEST.topics:
        if t.lockstep_only:  # the bundled YAML runs in real time
            continue
        name = absolute(t.name)
        out.add(f"topic {name}: type {t.type}")
        out.add(f"topic {name}: producers {', '.join(sorted(t.producers))}")
        # the recorder subscribes to a topic once it has a publisher: not to a public input nobody sends
        consumers = t.all_consumers if t.producers else t.consumers
        out.add(f"topic {name}: consumers {', '.join(sorted(consumers))}")
        q = t.qos
        for producer in t.producers:
            depth = q.depth if with_depth else None
            out.add(f"topic {name}: qos from {producer}: {qos_words(q.reliability.name, q.durability.name, depth)}")
    for s in MANIFEST.services:
        name = absolute(s.name)
        out.add(f"service {name}: type {s.type}")
        out.add(f"service {name}: server {s.server}")
        out |= {f"service {name}: client {c}" for c in s.clients}
    for a in MANIFEST.actions:
        name = absolute(a.name)
        out.add(f"action {name}: type {a.type}")
        out.add(f"action {name}: server {a.server}")
    return sorted(out)


@pytest.fixture(scope="module")
def graph_up(module_processes, ros_node, tmp_path_factory):
    """`c4d up` with the bundled board.yaml (bridge on a free port), all ten nodes discovered. The
    board layout — sitl.yaml's nodes and parameters, composed into 4 processes, pinned and niced
    (issue 16) — is the one that could change the graph: composed nodes share one rclpy context
    and a parameters file keyed by node name. sitl.yaml's one-process-per-node layout runs the same
    node code and is flown by test_bringup_fly / test_bringup_up."""
    node, executor = ros_node
    tmp_path = tmp_path_factory.mktemp("up")
    doc = yaml.safe_load((ROOT / "src" / "c4d_bringup" / "config" / "board.yaml").read_text())
    doc["nodes"]["bridge"]["parameters"]["endpoints"] = ["udpin:127.0.0.1:0"]  # 14550 may be in use by other tests
    (tmp_path / "system.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    c4d = installed_executable("c4d_bringup", "c4d")
    up = module_processes.spawn("up", [c4d, "up", "--config", str(tmp_path / "system.yaml"), "--run-dir",
                                       str(tmp_path / "run")])
    graph = GraphReader(node)
    assert set(doc["nodes"]) == set(MANIFEST.nodes), "the bundled system YAML and the manifest name different nodes"
    assert spin_for(executor, 45, lambda: set(MANIFEST.nodes) <= graph.nodes() or up.poll() is not None), \
        f"nodes up: {sorted(graph.nodes())}\n{module_processes.log_of(up)[-2000:]}"
    assert up.poll() is None, module_processes.log_of(up)[-2000:]
    up.run_dir = tmp_path / "run"
    return up


def test_board_layout_is_fewer_processes_pinned_and_niced(graph_up):
    """board.yaml: 10 nodes in 4 processes (supervisor.json); each process's threads on the CPUs
    and at the niceness the YAML gives (/proc): the core alone on the last CPU at SCHED_FIFO with its
    memory locked, the ground group niced."""
    import json
    import os

    state = json.loads((graph_up.run_dir / "supervisor.json").read_text())["nodes"]
    assert {name: tuple(p["members"]) for name, p in state.items()} == {
        "sim": ("sim",), "sensing": ("perception", "navigation"), "core": ("core",),
        "ground": ("mission", "payload", "health", "bridge", "offboard", "recorder")}
    assert sorted(n for p in state.values() for n in p["members"]) == sorted(MANIFEST.nodes)
    cpus = sorted(os.sched_getaffinity(0))
    others = set(cpus[:-1] or cpus)
    for name, affinity, nice in (("sim", others, 0), ("sensing", others, 0), ("core", {cpus[-1]}, 0), ("ground", others, 5)):
        pid = state[name]["pid"]
        tids = [int(t) for t in os.listdir(f"/proc/{pid}/task")]
        assert {frozenset(os.sched_getaffinity(t)) for t in tids} == {frozenset(affinity)}, name
        assert {os.getpriority(os.PRIO_PROCESS, t) for t in tids} == {nice}, name
    core = state["core"]["pid"]
    log_file = graph_up.run_dir / "logs" / "core.log"
    # the core applies its real-time settings on activation, which c4d up's lifecycle manager drives after the
    # graph is up: wait for the line that says what was applied
    end = time.monotonic() + 30.0
    while "real-time:" not in (log := log_file.read_text()) and time.monotonic() < end:
        time.sleep(0.2)
    if "real-time: SCHED_FIFO priority 60" in log:  # where permitted (else the log says why, as a warning)
        tids = [int(t) for t in os.listdir(f"/proc/{core}/task")]
        assert {(os.sched_getscheduler(t), os.sched_getparam(t).sched_priority) for t in tids} == {(os.SCHED_FIFO, 60)}
        status = dict(line.split(":", 1) for line in open(f"/proc/{core}/status"))
        assert ("memory locked" in log) == (int(status["VmLck"].split()[0]) > 0), log[-500:]
    else:
        assert "real-time: rt_priority 60 not applied" in log, log[-500:]


def test_live_graph_matches_the_manifest(graph_up, ros_node):
    node, executor = ros_node
    graph = GraphReader(node)
    seen: list[str] = []
    expected: list[str] = []
    last_read = 0.0

    def settled() -> bool:  # the graph is read twice a second, not at every spin
        nonlocal seen, expected, last_read
        if time.monotonic() - last_read < 0.5:
            return False
        last_read = time.monotonic()
        with_depth = graph.depth_visible()
        seen, expected = graph.lines(with_depth), expected_lines(with_depth)
        return seen == expected

    spin_for(executor, SETTLE_S, settled)
    diff = "\n".join(difflib.unified_diff(expected, seen, "manifest", "live graph", lineterm="", n=0))
    assert seen == expected, f"live graph differs from c4d_ros.manifest (- manifest, + live):\n{diff}"


def dump_parameters(node, executor, target: str) -> dict[str, object]:
    """{name: value} of every parameter of node `target`, through its parameter services (what
    `ros2 param dump` calls: list_parameters, then get_parameters)."""
    from rclpy.parameter import parameter_value_to_python
    from rclpy.parameter_client import AsyncParameterClient

    client = AsyncParameterClient(node, target)
    spin = partial(spin_for, executor)
    assert client.wait_for_services(timeout_sec=10.0), f"{target}: no parameter services"
    listed = client.list_parameters()
    assert spin(15, listed.done), f"{target}: list_parameters timed out"
    names = list(listed.result().result.names)
    got = client.get_parameters(names)
    assert spin(15, got.done), f"{target}: get_parameters timed out"
    return {name: parameter_value_to_python(value) for name, value in zip(names, got.result().values, strict=True)}


def test_parameters_report_the_values_in_force(graph_up, ros_node):
    node, executor = ros_node
    dumps = {f"/{name}": dump_parameters(node, executor, f"/{name}") for name in MANIFEST.nodes}
    core_yaml = ROOT / "src" / "c4d_gnc" / "config" / "core.yaml"
    doc = yaml.safe_load(core_yaml.read_text())
    core = dumps["/core"]
    assert core["phase_method"] == doc["executive"]["phase_method"], core
    assert core["airframe"] == doc["airframe"], core
    assert Path(str(core["config"])).resolve() == core_yaml.resolve(), core  # the installed file is a symlink here
    assert Path(str(dumps["/sim"]["config"])).name == "sim.yaml"
    assert Path(str(dumps["/bridge"]["config"])).name == "bridge.yaml"
    assert Path(str(dumps["/health"]["policy_file"])).name == "failsafe.yaml"
    empty = [f"{target} {name}" for target, values in dumps.items() for name, value in values.items()
             if value in ("", [""]) and name not in EMPTY_MEANS_NONE.get(target, set())]
    assert not empty, f"parameters reporting an empty value although a file gives one: {empty}"
