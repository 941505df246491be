"""`ros2 run c4d_data replay FLIGHT.mcap [options]` — republish a recording with its original
timing, so recorded flights can be examined with the live tools.

Publishes the stored CDR bytes as they are (no deserialisation), each topic with the QoS its
original publishers offered (reliability, durability, depth), at original timing scaled by
`--rate`, from `--start-offset` seconds into the recording, optionally looping; `--clock HZ`
also publishes rosgraph_msgs/Clock with the recording's time (for use_sim_time tools).
Topics whose type is not installed here are skipped with a warning; a file that cannot be
replayed at all exits non-zero with one line on stderr.
"""

from __future__ import annotations

import argparse
import signal
import sys
import time

import yaml

from .bag_reader import BagError, iter_messages, open_bag
from .recorder_node import message_class
from .replay_timing import Clock, ReplayOptions, select_topics


def parse_args(argv: list[str]) -> tuple[str, ReplayOptions]:
    parser = argparse.ArgumentParser(prog="replay", description="Republish a rosbag2 MCAP recording with original timing.")
    parser.add_argument("bag", help="MCAP file")
    parser.add_argument("--rate", type=float, default=1.0, help="playback speed factor (default 1)")
    parser.add_argument("--start-offset", type=float, default=0.0, help="seconds into the recording to start from")
    parser.add_argument("--topics", nargs="*", default=[], help="regular expressions of topics to replay (default all)")
    parser.add_argument("--exclude", nargs="*", default=[], help="regular expressions of topics not to replay")
    parser.add_argument("--loop", action="store_true", help="start again at the end, until interrupted")
    parser.add_argument("--clock", type=float, nargs="?", const=100.0, default=0.0, metavar="HZ",
                        help="publish /clock at HZ (default 100 when given)")
    parser.add_argument("--delay", type=float, default=1.0, help="seconds to let subscribers match first (default 1)")
    args = parser.parse_args(argv)
    options = ReplayOptions(args.rate, args.start_offset, args.loop, args.topics, args.exclude, args.clock, args.delay)
    try:
        options.validate()
    except ValueError as exc:
        parser.error(str(exc))
    return args.bag, options


def publisher_qos(offered: str):
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    try:
        profiles = yaml.safe_load(offered) if offered else []
    except yaml.YAMLError:
        profiles = []
    first = profiles[0] if profiles and isinstance(profiles[0], dict) else {}
    reliable = first.get("reliability", "reliable") in ("reliable", 1)
    latched = first.get("durability", "volatile") in ("transient_local", 1)
    depth = int(first.get("depth") or 0) if first.get("history") in ("keep_last", 1) else 0
    return QoSProfile(depth=depth if depth > 0 else 10,
                      reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


def main(argv: list[str] | None = None) -> int:
    from c4d_ros import node_runtime

    argv = list(sys.argv[1:] if argv is None else argv)
    ros_args = argv[argv.index("--ros-args"):] if "--ros-args" in argv else []
    path, options = parse_args(argv[:len(argv) - len(ros_args)])
    try:
        contents = open_bag(path)
    except BagError as exc:
        print(f"replay: error: {exc}", file=sys.stderr)
        return 1
    if not contents.complete:
        print(f"replay: warning: {contents.problem}; replaying the complete part", file=sys.stderr)
    rclpy = node_runtime.init(["replay", *ros_args])
    node = rclpy.create_node("replay")
    publishers = {}
    for name in select_topics(list(contents.topics), options.include, options.exclude):
        topic = contents.topics[name]
        cls = message_class(topic.type_name)
        if cls is None:
            print(f"replay: warning: {name}: type {topic.type_name} is not installed here: skipped", file=sys.stderr)
            continue
        publishers[name] = node.create_publisher(cls, name, publisher_qos(topic.offered_qos))
    if not publishers:
        return node_runtime.fail("replay", f"{path}: no topic to replay (selection empty or types not installed)", node)
    clock_pub = None
    if options.clock_hz:
        from builtin_interfaces.msg import Time
        from rosgraph_msgs.msg import Clock as ClockMsg

        clock_pub = node.create_publisher(ClockMsg, "/clock", 10)
    stopping: list[int] = []
    signal.signal(signal.SIGINT, lambda *_: stopping.append(1))
    signal.signal(signal.SIGTERM, lambda *_: stopping.append(1))
    time.sleep(options.delay_s)
    first = contents.start_ns + int(options.start_offset_s * 1e9)
    counts = dict.fromkeys(publishers, 0)
    started = time.monotonic()

    def publish_clock(clock: Clock) -> None:
        t = clock.log_time(time.monotonic_ns())
        clock_pub.publish(ClockMsg(clock=Time(sec=t // 1_000_000_000, nanosec=t % 1_000_000_000)))

    try:
        while not stopping:
            clock = Clock(first, time.monotonic_ns(), options.rate)
            next_tick = time.monotonic_ns()
            for topic, message in iter_messages(contents, topics=list(publishers)):
                if message.log_time < first:
                    continue
                due = clock.due(message.log_time)
                while not stopping:
                    now = time.monotonic_ns()
                    if clock_pub is not None and now >= next_tick:
                        publish_clock(clock)
                        next_tick += int(1e9 / options.clock_hz)
                    if now >= due:
                        break
                    wait = min(due, next_tick if clock_pub is not None else due) - now
                    time.sleep(max(0, min(wait, 50_000_000)) * 1e-9)
                if stopping:
                    break
                publishers[topic.name].publish(message.data)
                counts[topic.name] += 1
            if not options.loop:
                break
    except BagError as exc:
        return node_runtime.fail("replay", str(exc), node)
    elapsed = time.monotonic() - started
    print(f"replay: {sum(counts.values())} messages on {len(counts)} topics in {elapsed:.1f} s", flush=True)
    time.sleep(0.2)  # let reliable transports deliver the tail
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
