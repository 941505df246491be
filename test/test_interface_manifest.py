"""The live graph is the interface manifest: `c4d up` starts the whole SITL graph, a test node reads
what DDS sees (topic names and types, publishing and subscribing nodes, the QoS every publisher
offers, the services each node serves and calls) and the test fails with a line diff on any
difference from `c4d_ros.manifest`.

Why: the manifest is where names and QoS come from and what docs/ARCHITECTURE.md is generated
from; this test keeps it the truth. Hidden LatestSampler side nodes (`_<owner>_samples`) count as
their owner; ROS infrastructure (/rosout, /parameter_events, the standard parameter and
type-description services) and this test's own node are not part of the manifest. Offered depth
is compared only where discovery reports it (Fast DDS does not send it for remote endpoints).
"""

from __future__ import annotations

import difflib
import time
from pathlib import Path

import yaml
from c4d_testing import installed_executable, spin_for

from c4d_ros.manifest import MANIFEST, side_node_name

ROOT = Path(__file__).resolve().parent.parent
INFRASTRUCTURE_TOPICS = {"/rosout", "/parameter_events"}
NODE_SERVICES = {"describe_parameters", "get_parameter_types", "get_parameters", "list_parameters", "set_parameters",
                 "set_parameters_atomically", "get_type_description"}  # every rclpy node has these
TEST_NODE_PREFIXES = ("c4d_test", "_c4d_test_samples_")
SETTLE_S = 30.0  # after the nine nodes are up: the recorder subscribes to topics as it discovers them


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
            if not pubs and not subs:
                continue  # only the test's own endpoints (none today)
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
                    if service.rsplit("/", 1)[-1] in NODE_SERVICES:
                        continue
                    out.add(f"service {service}: type {', '.join(sorted(types))}")
                    out.add(f"service {service}: {role} {who}")
        return sorted(out)


def expected_lines(with_depth: bool) -> list[str]:
    out: set[str] = set()
    for t in MANIFEST.topics:
        name = absolute(t.name)
        out.add(f"topic {name}: type {t.type}")
        out.add(f"topic {name}: producers {', '.join(sorted(t.producers))}")
        out.add(f"topic {name}: consumers {', '.join(sorted(t.all_consumers))}")
        q = t.qos
        for producer in t.producers:
            depth = q.depth if with_depth else None
            out.add(f"topic {name}: qos from {producer}: {qos_words(q.reliability.name, q.durability.name, depth)}")
    for s in MANIFEST.services:
        name = absolute(s.name)
        out.add(f"service {name}: type {s.type}")
        out.add(f"service {name}: server {s.server}")
        out |= {f"service {name}: client {c}" for c in s.clients}
    return sorted(out)


def test_live_graph_matches_the_manifest(processes, ros_node, tmp_path):
    node, executor = ros_node
    doc = yaml.safe_load((ROOT / "src" / "c4d_bringup" / "config" / "sitl.yaml").read_text())
    doc["nodes"]["bridge"]["parameters"]["endpoints"] = ["udpin:127.0.0.1:0"]  # 14550 may be in use by other tests
    (tmp_path / "system.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    c4d = installed_executable("c4d_bringup", "c4d")
    up = processes.spawn("up", [c4d, "up", "--config", str(tmp_path / "system.yaml"), "--run-dir", str(tmp_path / "run")])
    graph = GraphReader(node)
    assert set(doc["nodes"]) == set(MANIFEST.nodes), "the bundled system YAML and the manifest name different nodes"
    assert spin_for(executor, 45, lambda: set(MANIFEST.nodes) <= graph.nodes() or up.poll() is not None), \
        f"nodes up: {sorted(graph.nodes())}\n{processes.log_of(up)[-2000:]}"
    assert up.poll() is None, processes.log_of(up)[-2000:]
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
