"""Shared start/stop plumbing for the event-driven c4d nodes (perception, navigation, sim).

`spin_node(node, events_executor)` spins until SIGINT/SIGTERM and returns 0: rclpy's own
signal handling is replaced so both signals end the spin cleanly (no traceback, exit 0).
`events_executor` selects rclpy's experimental EventsExecutor, which costs markedly less CPU
for high-rate topics than the default SingleThreadedExecutor (bench/loop_latency_cpu.py).
"""

from __future__ import annotations

import os
import signal
import sys

from .params import Spec

RT_PRIORITY = Spec(0, "SCHED_FIFO priority of every thread of the process [0..99]; 0 = normal scheduling "
                      "(the flight-critical nodes preempt the rest of the graph on a busy board)", 0, 99, read_only=True)


def init(argv: list[str] | None):
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    rclpy.init(args=argv if argv is not None else sys.argv, signal_handler_options=SignalHandlerOptions.NO)
    return rclpy


def make_executor(events_executor: bool):
    if events_executor:
        from rclpy.experimental import EventsExecutor

        return EventsExecutor()
    from rclpy.executors import SingleThreadedExecutor

    return SingleThreadedExecutor()


def spin_node(node, events_executor: bool, on_stop=None, rt_priority: int = 0) -> int:
    """Spin `node` (at `rt_priority`, see apply_rt_priority) until SIGINT/SIGTERM; call on_stop(); tear down; return 0."""
    import rclpy

    executor = make_executor(events_executor)
    executor.add_node(node)
    apply_rt_priority(rt_priority, node.get_logger())
    stopping = []

    def stop(signum, frame) -> None:
        stopping.append(signum)

    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    try:
        while not stopping and rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
    finally:
        if on_stop:
            on_stop()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


def fail(name: str, message: str, node=None) -> int:
    """One-line error, clean teardown, exit code 2 (bad configuration)."""
    import rclpy

    print(f"{name}: error: {message}", file=sys.stderr)
    if node is not None:
        node.destroy_node()
    rclpy.try_shutdown()
    return 2


def apply_rt_priority(priority: int, log) -> bool:
    """Real-time FIFO scheduling for every thread of this process (the rclpy thread and the DDS
    threads that deliver its messages; threads started later inherit it). Why: on a 2-core board
    a busy non-critical node must not delay the flight-critical chain (docs/dds.md). Returns False,
    with a warning, when not permitted; 0 does nothing."""
    if priority <= 0:
        return False
    try:
        for tid in os.listdir("/proc/self/task"):
            os.sched_setscheduler(int(tid), os.SCHED_FIFO, os.sched_param(priority))
    except (PermissionError, OSError) as exc:
        log.warning(f"rt_priority {priority} not applied ({exc}); running with normal priority")
        return False
    log.info(f"SCHED_FIFO priority {priority} for {len(os.listdir('/proc/self/task'))} threads")
    return True
