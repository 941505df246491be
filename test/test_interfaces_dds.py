"""Every c4d_interfaces message and service crosses a real process boundary over DDS.

A peer process (support/interface_peer.py) publishes a fully, distinctly filled instance of
each message type and serves each service; this process subscribes and calls, then compares
every leaf field with the instance it builds itself from the same seeds.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent / "support"))

import msgfill

PACKAGE = "c4d_interfaces"
PREFIX = "c4d_ifc"
MSG_SEED, REQUEST_SEED, RESPONSE_SEED = 3, 7, 11
TYPES = msgfill.interface_types(PACKAGE)
MESSAGES = [k for k in TYPES if k.startswith("msg/")]
SERVICES = [k for k in TYPES if k.startswith("srv/")]
PEER = Path(__file__).resolve().parent / "support" / "interface_peer.py"


@pytest.fixture(scope="module")
def exchange(module_processes, ros_domain_id):
    """Run the whole exchange once: {type key: received message or service response}."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    peer = module_processes.spawn("interface_peer", [sys.executable, str(PEER), "--prefix", PREFIX])
    context = Context()
    rclpy.init(context=context, domain_id=ros_domain_id)
    node = rclpy.create_node("c4d_interface_test", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    latched = QoSProfile(
        depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
    )
    received: dict[str, object] = {}
    for key in MESSAGES:
        name = key.split("/")[1]
        node.create_subscription(
            TYPES[key], f"{PREFIX}/{name}", lambda m, key=key: received.setdefault(key, m), latched
        )
    futures = {}
    clients = {key: node.create_client(TYPES[key], f"{PREFIX}/{key.split('/')[1]}") for key in SERVICES}
    deadline = time.monotonic() + 45.0
    try:
        while time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
            for key, client in clients.items():
                if key not in futures and client.service_is_ready():
                    request = msgfill.fill(TYPES[key].Request, REQUEST_SEED)
                    futures[key] = client.call_async(request)
            done = all(f.done() for f in futures.values()) and len(futures) == len(SERVICES)
            if done and len(received) == len(MESSAGES):
                break
            assert peer.poll() is None, module_processes.log_of(peer)
        for key, future in futures.items():
            if future.done():
                received[key] = future.result()
        yield received
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=context)


def test_package_has_the_required_interfaces():
    required = {
        "msg/VehicleState", "msg/GuidanceSetpoint", "msg/ActuatorCommand", "msg/VehicleStatus",
        "msg/ExecutorStats", "msg/ExecutorTaskStats", "msg/ScheduleTable", "msg/ScheduleEntry",
        "msg/MissionItem", "msg/MissionPlan", "msg/MissionState", "msg/CaptureEvent",
        "msg/GeoPoint", "msg/Geofence", "srv/VehicleCommand", "srv/UploadMission",
        "srv/DownloadMission", "srv/MissionControl",
    }
    assert required <= set(TYPES), sorted(required - set(TYPES))


@pytest.mark.parametrize("key", MESSAGES)
def test_message_crosses_process_boundary(exchange, key):
    assert key in exchange, f"{key} never arrived from the peer process"
    expected = msgfill.to_plain(msgfill.fill(TYPES[key], MSG_SEED))
    actual = msgfill.to_plain(exchange[key])
    assert msgfill.differences(expected, actual) == []
    # The comparison covered real content: every leaf is there and not a default value.
    leaves = msgfill.leaf_paths(expected)
    assert leaves and len(leaves) == len(msgfill.leaf_paths(actual))
    assert actual != msgfill.to_plain(TYPES[key]())


@pytest.mark.parametrize("key", SERVICES)
def test_service_answers_another_process(exchange, key):
    assert key in exchange, f"{key}: no response from the peer process"
    expected = msgfill.to_plain(msgfill.fill(TYPES[key].Response, RESPONSE_SEED))
    actual = msgfill.to_plain(exchange[key])
    # The peer answers with the filled response only if our request arrived intact.
    assert msgfill.differences(expected, actual) == []
    assert actual != msgfill.to_plain(TYPES[key].Response())


def test_documented_constants_are_distinct():
    """Enumerations in one interface never reuse a value within the same prefix group."""
    total = 0
    for key, cls in TYPES.items():
        for part in ([cls] if key.startswith("msg/") else [cls.Request, cls.Response]):
            groups: dict[str, dict[int, str]] = {}
            # rosidl exposes constants as properties of the message metaclass
            for name in dir(type(part)):
                if name.isupper() and isinstance(getattr(part, name), int):
                    total += 1
                    prefix = name.split("_")[0]
                    seen = groups.setdefault(prefix, {})
                    value = getattr(part, name)
                    assert value not in seen, f"{key}: {name} == {seen.get(value)} == {value}"
                    seen[value] = name
    assert total > 40, f"only {total} constants found"
