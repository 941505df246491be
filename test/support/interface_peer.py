#!/usr/bin/env python3
"""Peer process for the interface tests: publishes and serves every type of a package.

For each message type `msg/Name` it publishes `fill(Name, --msg-seed)` on `<prefix>/Name`
(reliable, transient-local, so a late subscriber still gets it). For each service `srv/Name`
it serves `<prefix>/Name`: a request equal to `fill(Request, --request-seed)` is answered
with `fill(Response, --response-seed)`, anything else with a default Response, so the test
can tell a faithful hop from a corrupted one in both directions.
Runs until SIGINT/SIGTERM (exit 0) or --timeout seconds.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import msgfill
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

LATCHED = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--package", default="c4d_interfaces")
    parser.add_argument("--prefix", default="c4d_ifc")
    parser.add_argument("--msg-seed", type=int, default=3)
    parser.add_argument("--request-seed", type=int, default=7)
    parser.add_argument("--response-seed", type=int, default=11)
    parser.add_argument("--timeout", type=float, default=120.0)
    args = parser.parse_args()

    rclpy.init()
    node = rclpy.create_node("c4d_interface_peer")
    keep = []
    served = {"ok": 0, "bad": 0}
    for key, cls in msgfill.interface_types(args.package).items():
        kind, name = key.split("/")
        topic = f"{args.prefix}/{name}"
        if kind == "msg":
            pub = node.create_publisher(cls, topic, LATCHED)
            pub.publish(msgfill.fill(cls, args.msg_seed))
            keep.append(pub)
        else:
            expected = msgfill.to_plain(msgfill.fill(cls.Request, args.request_seed))

            def answer(request, response, cls=cls, expected=expected):
                if msgfill.to_plain(request) == expected:
                    served["ok"] += 1
                    return msgfill.fill(cls.Response, args.response_seed)
                served["bad"] += 1
                return cls.Response()

            keep.append(node.create_service(cls, topic, answer))
    print(f"interface_peer: ready with {len(keep)} endpoints", flush=True)
    deadline = time.monotonic() + args.timeout
    try:
        while rclpy.ok() and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    print(f"interface_peer: served {served}", flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
