"""Shared start/stop plumbing for the c4d nodes: rclpy start without its signal handlers, the
executor choice, one-line parameter errors, real-time scheduling and memory locking.

The run loop of the composable nodes is c4d_ros.component.run_components. `make_executor(True)`
selects rclpy's experimental EventsExecutor, which costs markedly less CPU for high-rate topics
than the default SingleThreadedExecutor (bench/loop_latency_cpu.py).
"""

from __future__ import annotations

import os
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


def fail(name: str, message: str, node=None) -> int:
    """One-line error, clean teardown, exit code 2 (bad configuration)."""
    import rclpy

    print(f"{name}: error: {message}", file=sys.stderr)
    if node is not None:
        node.destroy_node()
    rclpy.try_shutdown()
    return 2


MCL_CURRENT, MCL_FUTURE, MCL_ONFAULT = 1, 2, 4  # <sys/mman.h> on x86-64 and arm64
CAP_IPC_LOCK = 14  # bit in /proc/<pid>/status CapEff


def _capability(bit: int) -> bool:
    try:
        for line in open("/proc/self/status"):
            if line.startswith("CapEff:"):
                return bool(int(line.split()[1], 16) >> bit & 1)
    except (OSError, ValueError):
        pass
    return False


def lock_memory() -> str | None:
    """mlockall(MCL_CURRENT | MCL_FUTURE | MCL_ONFAULT): pages of this process, present and future,
    stay in RAM once touched, so the real-time loop never waits for a page brought back from swap
    or a reclaimed file page. MCL_ONFAULT locks pages as they are touched instead of populating
    every mapping at once (each thread's 8 MB stack reservation would otherwise become resident).
    Only attempted with CAP_IPC_LOCK or an unlimited RLIMIT_MEMLOCK: under a finite limit MCL_FUTURE
    would make a later allocation fail. Returns None when locked, else why not."""
    import ctypes
    import resource

    limit = resource.getrlimit(resource.RLIMIT_MEMLOCK)[0]
    if limit != resource.RLIM_INFINITY and not _capability(CAP_IPC_LOCK):
        return (f"memory not locked: RLIMIT_MEMLOCK {limit >> 10} kB and no CAP_IPC_LOCK "
                "(ulimit -l unlimited, or docker --ulimit memlock=-1 / --cap-add IPC_LOCK)")
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.mlockall(MCL_CURRENT | MCL_FUTURE | MCL_ONFAULT) != 0:
            return f"memory not locked: mlockall: {os.strerror(ctypes.get_errno())}"
    except (OSError, AttributeError) as exc:
        return f"memory not locked: {exc}"
    return None


def apply_rt_priority(priority: int, log) -> bool:
    """Real-time FIFO scheduling for every thread of this process (the rclpy thread and the DDS
    threads that deliver its messages; threads started later inherit it) and its memory locked
    (lock_memory). Why: on a 2-core board a busy non-critical node must not delay the
    flight-critical chain (docs/dds.md), nor may a page fault. Logs one line saying what was
    applied — a warning with the reason when something was not permitted; returns whether the
    priority was applied; 0 does nothing."""
    if priority <= 0:
        return False
    threads = len(os.listdir("/proc/self/task"))
    try:
        for tid in os.listdir("/proc/self/task"):
            os.sched_setscheduler(int(tid), os.SCHED_FIFO, os.sched_param(priority))
    except (PermissionError, OSError) as exc:
        log.warning(f"real-time: rt_priority {priority} not applied ({exc}); running with normal priority")
        return False
    refusal = lock_memory()
    cpus = ",".join(map(str, sorted(os.sched_getaffinity(0))))
    if refusal:
        log.warning(f"real-time: SCHED_FIFO priority {priority} for {threads} threads, CPUs {cpus}; {refusal}")
    else:
        log.info(f"real-time: SCHED_FIFO priority {priority} for {threads} threads, CPUs {cpus}; "
                 "memory locked (mlockall current+future, on fault)")
    return True
