"""Processes that disturb a running c4d graph the way other people's nodes do (issue 13).

  python disturbers.py churn SECONDS [PARTICIPANTS]   participants joining and leaving, each with a
      subscription to every topic of the interface manifest (discovery load; default 20 at a time)
  python disturbers.py slow SECONDS                    a subscription to control/actuators (reliable) whose
      messages are never taken, plus an `echo`-like consumer of every high-rate topic that sleeps 50 ms
      in each callback

Used by test/test_interference.py and bench/interference.py. Exits 0 after SECONDS.
"""

from __future__ import annotations

import sys
import time


def _message_type(type_name: str):
    import importlib

    package, _, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


def churn(seconds: float, participants: int) -> None:
    """Contexts (= DDS participants) created and destroyed in turn, `participants` alive at a time."""
    import rclpy
    from rclpy.context import Context

    from c4d_ros import manifest

    topics = [(t.name, _message_type(t.type), t.qos) for t in manifest.TOPICS]
    alive: list[tuple[Context, object]] = []
    end, k = time.monotonic() + seconds, 0
    while time.monotonic() < end:
        context = Context()
        rclpy.init(context=context)
        node = rclpy.create_node(f"c4d_churn_{k}", context=context)
        for name, msg_type, qos in topics:
            node.create_subscription(msg_type, name, lambda m: None, qos)
        alive.append((context, node))
        k += 1
        if len(alive) >= participants:
            old_context, old_node = alive.pop(0)
            old_node.destroy_node()
            rclpy.shutdown(context=old_context)
        time.sleep(0.1)
    for context, node in alive:
        node.destroy_node()
        rclpy.shutdown(context=context)
    print(f"churn: {k} participants joined and left", flush=True)


def slow(seconds: float) -> None:
    """A never-taken reliable subscription and a consumer that sleeps 50 ms per message."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    from c4d_ros import manifest

    rclpy.init()
    stuck = rclpy.create_node("c4d_stuck_consumer")  # never spun: its messages are never taken
    stuck.create_subscription(_message_type(manifest.ACTUATORS.type), manifest.ACTUATORS.name, lambda m: None,
                              QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    stuck.create_subscription(_message_type(manifest.ACTUATORS.type), manifest.ACTUATORS.name, lambda m: None,
                              manifest.ACTUATORS.qos)
    echo = rclpy.create_node("c4d_slow_echo")
    taken = [0]

    def slow_callback(msg) -> None:
        taken[0] += 1
        time.sleep(0.05)

    for topic in (manifest.ACTUATORS, manifest.IMU, manifest.NAV_STATE, manifest.P_IMU):
        echo.create_subscription(_message_type(topic.type), topic.name, slow_callback,
                                 QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    executor = SingleThreadedExecutor()
    executor.add_node(echo)
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        executor.spin_once(timeout_sec=0.1)
    print(f"slow: echo took {taken[0]} messages", flush=True)
    stuck.destroy_node()
    echo.destroy_node()
    rclpy.shutdown()


def main(argv: list[str]) -> int:
    mode, seconds = argv[1], float(argv[2])
    if mode == "churn":
        churn(seconds, int(argv[3]) if len(argv) > 3 else 20)
    elif mode == "slow":
        slow(seconds)
    else:
        print(f"disturbers: error: unknown mode '{mode}' (churn | slow)", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
