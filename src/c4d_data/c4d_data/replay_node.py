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
from typing import Any

import yaml

from .bag_reader import BagContents, BagError, iter_messages, open_bag
from .message_types import message_class
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


class ReplayNode:
    """Republishes a recording: one raw publisher per replayed topic with the QoS its original
    publishers offered, each message at its log time mapped to wall time by `replay_timing.Clock`,
    optionally /clock with the recording's time."""

    def __init__(self, node, contents: BagContents, options: ReplayOptions) -> None:
        self.node, self.contents, self.options = node, contents, options
        self.publishers: dict[str, Any] = {}
        for name in select_topics(list(contents.topics), options.include, options.exclude):
            topic = contents.topics[name]
            cls = message_class(topic.type_name)
            if cls is None:
                print(f"replay: warning: {name}: type {topic.type_name} is not installed here: skipped", file=sys.stderr)
                continue
            self.publishers[name] = node.create_publisher(cls, name, publisher_qos(topic.offered_qos))
        self.clock_pub = None
        if options.clock_hz:
            from rosgraph_msgs.msg import Clock as ClockMsg

            self.clock_pub = node.create_publisher(ClockMsg, "/clock", 10)
        self.counts = dict.fromkeys(self.publishers, 0)
        self.next_clock_ns = 0  # when /clock is published next (monotonic)
        self.stopping = False

    def stop(self, signum: int, frame: Any) -> None:
        self.stopping = True

    def play(self) -> None:
        """Replay from the start offset to the end (again and again with --loop) until stopped."""
        first = self.contents.start_ns + int(self.options.start_offset_s * 1e9)
        while not self.stopping:
            clock = Clock(first, time.monotonic_ns(), self.options.rate)
            self.next_clock_ns = time.monotonic_ns()
            for topic, message in iter_messages(self.contents, topics=list(self.publishers)):
                if message.log_time < first:
                    continue
                self.wait_until(clock.due(message.log_time), clock)
                if self.stopping:
                    break
                self.publishers[topic.name].publish(message.data)
                self.counts[topic.name] += 1
            if not self.options.loop:
                break

    def wait_until(self, due_ns: int, clock: Clock) -> None:
        """Sleep until `due_ns` (monotonic), publishing /clock on the way when asked to."""
        while not self.stopping:
            now = time.monotonic_ns()
            if self.clock_pub is not None and now >= self.next_clock_ns:
                self.publish_clock(clock)
                self.next_clock_ns += int(1e9 / self.options.clock_hz)
            if now >= due_ns:
                return
            wait = min(due_ns, self.next_clock_ns if self.clock_pub is not None else due_ns) - now
            time.sleep(max(0, min(wait, 50_000_000)) * 1e-9)

    def publish_clock(self, clock: Clock) -> None:
        from builtin_interfaces.msg import Time
        from rosgraph_msgs.msg import Clock as ClockMsg

        t = clock.log_time(time.monotonic_ns())
        self.clock_pub.publish(ClockMsg(clock=Time(sec=t // 1_000_000_000, nanosec=t % 1_000_000_000)))

    def run(self) -> int:
        """Wait for subscribers to match, replay, report; 0 (2 on a damaged file, one line)."""
        import rclpy

        from c4d_ros import node_runtime

        signal.signal(signal.SIGINT, self.stop)
        signal.signal(signal.SIGTERM, self.stop)
        time.sleep(self.options.delay_s)
        started = time.monotonic()
        try:
            self.play()
        except BagError as exc:
            return node_runtime.fail("replay", str(exc), self.node)
        elapsed = time.monotonic() - started
        print(f"replay: {sum(self.counts.values())} messages on {len(self.counts)} topics in {elapsed:.1f} s", flush=True)
        time.sleep(0.2)  # let reliable transports deliver the tail
        self.node.destroy_node()
        rclpy.try_shutdown()
        return 0


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
    replay = ReplayNode(node, contents, options)
    if not replay.publishers:
        return node_runtime.fail("replay", f"{path}: no topic to replay (selection empty or types not installed)", node)
    return replay.run()


if __name__ == "__main__":
    sys.exit(main())
