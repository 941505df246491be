#!/usr/bin/env python3
"""Check that the built c4d workspace really works, end to end, in a few seconds.

What: resolves every package of src/ through the ament index, then sends a c4d_interfaces
message from a second process to this one over real DDS (loopback only) and back, and prints
a one-screen summary (ROS source, RMW, packages, round-trip time).
Why: setup.sh ends with this so "setup succeeded" means "a node can talk to a node", not
merely "the compiler was happy". Exit code 0 = healthy, 1 = broken (one-line reason).

Usage: python tools/check_workspace.py   (inside `. ./env.sh`)
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TOPIC = "c4d_check/ping"
REPLY_TOPIC = "c4d_check/pong"


def fail(reason: str) -> int:
    print(f"check_workspace: error: {reason}", file=sys.stderr)
    return 1


def source_packages() -> list[str]:
    """Names of the ROS packages under src/ (directories holding a package.xml)."""
    return sorted(p.parent.name for p in (ROOT / "src").glob("*/package.xml"))


def echo_main() -> int:
    """Child process: answer each ping with a pong carrying the same payload, then exit."""
    import rclpy

    from c4d_interfaces.msg import GeoPoint

    rclpy.init()
    node = rclpy.create_node("c4d_check_echo")
    pub = node.create_publisher(GeoPoint, REPLY_TOPIC, 10)
    answered: list[bool] = []

    def on_ping(msg: GeoPoint) -> None:
        pub.publish(msg)
        answered.append(True)

    node.create_subscription(GeoPoint, TOPIC, on_ping, 10)
    deadline = time.monotonic() + 20.0
    while time.monotonic() < deadline and len(answered) < 3:
        rclpy.spin_once(node, timeout_sec=0.1)
    # Let the last reply leave before tearing the participant down.
    end = time.monotonic() + 0.5
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
    node.destroy_node()
    rclpy.shutdown()
    return 0


def main() -> int:
    from ament_index_python.packages import PackageNotFoundError, get_package_prefix

    missing = []
    for pkg in source_packages():
        try:
            get_package_prefix(pkg)
        except PackageNotFoundError:
            missing.append(pkg)
    if missing:
        return fail(f"packages not in the ament index: {' '.join(missing)}")

    sys.path.insert(0, str(ROOT / "tools"))
    import ros_domain

    lease = ros_domain.acquire()  # a private DDS domain for the check, held until exit
    os.environ["ROS_DOMAIN_ID"] = str(lease.domain_id)

    import rclpy

    from c4d_interfaces.msg import GeoPoint

    env = dict(os.environ)
    child = subprocess.Popen([sys.executable, __file__, "--echo"], env=env, start_new_session=True)
    try:
        rclpy.init()
        node = rclpy.create_node("c4d_check")
        pub = node.create_publisher(GeoPoint, TOPIC, 10)
        replies: list[tuple[float, GeoPoint]] = []
        node.create_subscription(
            GeoPoint, REPLY_TOPIC, lambda m: replies.append((time.monotonic(), m)), 10
        )
        sent = GeoPoint(latitude=43.5629, longitude=1.4815, altitude=146.25)
        deadline = time.monotonic() + 20.0
        t_sent = 0.0
        while not replies and time.monotonic() < deadline:
            if pub.get_subscription_count() > 0 and time.monotonic() - t_sent > 0.2:
                t_sent = time.monotonic()
                pub.publish(sent)
            rclpy.spin_once(node, timeout_sec=0.02)
        node.destroy_node()
        rclpy.shutdown()
    finally:
        try:
            child.wait(timeout=5)
        except subprocess.TimeoutExpired:
            child.kill()
            child.wait()
    if not replies:
        return fail("no DDS round trip within 20 s between two processes")
    t_back, got = replies[0]
    if (got.latitude, got.longitude, got.altitude) != (sent.latitude, sent.longitude, sent.altitude):
        return fail(f"round trip corrupted the message: {got}")
    rmw = os.environ.get("RMW_IMPLEMENTATION", "default")
    source = "/opt/ros/jazzy" if os.environ.get("C4D_ROS_MODE") == "system" else "PyPI wheels"
    print(
        f"workspace ready: ROS 2 {os.environ.get('ROS_DISTRO', 'jazzy')} ({source}), {rmw}, "
        f"discovery {os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE', 'default')}, "
        f"packages: {' '.join(source_packages())}; DDS round trip between two processes "
        f"{(t_back - t_sent) * 1000:.1f} ms"
    )
    return 0


if __name__ == "__main__":
    sys.exit(echo_main() if sys.argv[1:] == ["--echo"] else main())
