"""Synthetic load for recorder tests and benchmarks: `python -m c4d_data.synthetic`.

Publishes std_msgs/UInt8MultiArray messages of a given payload size on `--topics` topics
(`load/t0`, `load/t1`, ...) at an aggregate rate for a duration, as serialized bytes (so the
generator itself costs little), then prints one line `sent <total> <topic>=<n> ...` that the
caller compares with what the recorder wrote. `--random` makes every payload incompressible.
"""

from __future__ import annotations

import argparse
import os
import sys
import time


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="synthetic")
    parser.add_argument("--rate", type=float, default=1000.0, help="messages per second, all topics together")
    parser.add_argument("--size", type=int, default=16, help="payload bytes per message")
    parser.add_argument("--topics", type=int, default=1)
    parser.add_argument("--duration", type=float, default=5.0)
    parser.add_argument("--delay", type=float, default=2.0, help="seconds to wait for subscribers first")
    parser.add_argument("--random", action="store_true", help="fresh random payload per message")
    parser.add_argument("--reliable", action="store_true")
    args = parser.parse_args(argv)
    if args.rate <= 0 or args.size < 0 or args.topics < 1:
        parser.error("rate > 0, size >= 0 and topics >= 1 required")

    import rclpy
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rclpy.serialization import serialize_message
    from std_msgs.msg import UInt8MultiArray

    rclpy.init()
    node = rclpy.create_node("synthetic_load")
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE if args.reliable else ReliabilityPolicy.BEST_EFFORT)
    pubs = [node.create_publisher(UInt8MultiArray, f"load/t{k}", qos) for k in range(args.topics)]
    template = serialize_message(UInt8MultiArray(data=bytes(args.size)))
    prefix = template[: len(template) - args.size]  # CDR up to the payload (the payload comes last)
    time.sleep(args.delay)
    counts = [0] * args.topics
    start = time.monotonic()
    k = 0
    try:
        while True:
            due = start + k / args.rate
            now = time.monotonic()
            if now - start >= args.duration:
                break
            if due > now:
                time.sleep(min(due - now, 0.001) if due - now > 0.0002 else 0)
                continue
            payload = os.urandom(args.size) if args.random else None
            data = template if payload is None else prefix + payload
            pubs[k % args.topics].publish(data)
            counts[k % args.topics] += 1
            k += 1
    except KeyboardInterrupt:
        pass
    elapsed = time.monotonic() - start
    print(f"sent {sum(counts)} in {elapsed:.2f} s " + " ".join(f"/load/t{i}={n}" for i, n in enumerate(counts)), flush=True)
    time.sleep(0.5)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
