"""Composable c4d nodes: one factory per node, run alone (its executable) or with others in one process.

Why: nine Python processes of ~80 MB each do not fit a small board; nodes that only exchange
low-rate messages can share a process and one executor. Each stays a separate rclpy node with
its own name, parameters, topics and services, so the ROS graph is the same either way.

A node module exposes a `Factory`: `factory(rclpy, host) -> Component`. The component owns its
rclpy node(s) and says how it wants to be driven:

- `nodes`: the nodes the process's executor spins (empty when the component spins or drains
  its node itself, like the recorder and the bridge);
- `period_s` / `step(budget_s)`: periodic work done by the runner's loop (the bridge's socket
  poll and telemetry, the recorder's drain); `budget_s` is how long step may wait for its own
  input — the whole period when the component has the process to itself, 0 when it shares it;
- `events_executor`, `rt_priority`: the executor kind and SCHED_FIFO priority it would like
  (a shared process uses the EventsExecutor only if every spun member wants it, and the highest
  priority of its members);
- `close() -> int`: tear down its nodes (not the rclpy context), return its exit code.

A bad parameter is a ComponentError (one line). The factory of a package is found by name through
the Python entry point group `c4d.components` (`<executable> = <module>:<factory>` in setup.py),
as ROS 2 component containers load plugins by name — the container never imports block packages.

`run_components` is the one run loop for both cases: a node's standalone `main()` calls it with
its own factory, the container (`c4d_bringup/container`) with several. SIGINT / SIGTERM are caught
from before rclpy starts (a stop during start-up ends the run cleanly, no traceback); the exit
code is 2 for a bad parameter, else the highest of the components' close() codes.
"""

from __future__ import annotations

import signal
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

from .errors import ComponentError as ComponentError  # re-exported: node shells import it from here

COMPONENT_GROUP = "c4d.components"


@dataclass(frozen=True)
class Host:
    """Where a component runs: alone in its process, or composed into the process `process`."""

    process: str
    composed: bool = False


class Component(Protocol):
    name: str
    nodes: Sequence[Any]
    events_executor: bool
    rt_priority: int
    period_s: float | None

    def step(self, budget_s: float) -> None: ...

    def close(self) -> int: ...


Factory = Callable[[Any, Host], Component]


@dataclass
class SpunNode:
    """A component that is only its node spun by the executor (timers, subscriptions, services);
    `keep` holds the node's owner objects, `extra` nodes it created (side nodes nobody spins)."""

    name: str
    node: Any
    events_executor: bool = False
    rt_priority: int = 0
    keep: Any = None
    extra: tuple[Any, ...] = ()
    period_s: float | None = None
    nodes: Sequence[Any] = field(init=False)

    def __post_init__(self) -> None:
        self.nodes = (self.node,)

    def step(self, budget_s: float) -> None:  # no periodic work
        pass

    def close(self) -> int:
        for node in (*self.extra, self.node):
            node.destroy_node()
        return 0


def find_component(package: str, executable: str) -> Any:
    """The `c4d.components` entry point `executable` of the Python distribution `package`."""
    from importlib.metadata import PackageNotFoundError, distribution

    try:
        points = distribution(package).entry_points
    except PackageNotFoundError:
        raise ComponentError(f"no Python package {package} installed (source env.sh)") from None
    for point in points:
        if point.group == COMPONENT_GROUP and point.name == executable:
            return point
    names = sorted(p.name for p in points if p.group == COMPONENT_GROUP)
    raise ComponentError(f"{package} declares no component '{executable}' (entry points {COMPONENT_GROUP}: "
                         f"{', '.join(names) or 'none'})")


def load_factory(package: str, executable: str) -> Factory:
    point = find_component(package, executable)
    try:
        factory = point.load()
    except Exception as exc:  # an import error in the node module: say which, on one line
        raise ComponentError(f"{package}/{executable}: cannot load {point.value}: {type(exc).__name__}: {exc}") from None
    return factory  # type: ignore[no-any-return]


def run_components(factories: Sequence[tuple[str, Factory]], argv: list[str] | None, process: str,
                   composed: bool) -> int:
    """Create every component, spin and step them until SIGINT/SIGTERM, close them (see the module docstring)."""
    from . import node_runtime

    stopping: list[int] = []
    signal.signal(signal.SIGINT, lambda signum, frame: stopping.append(signum))
    signal.signal(signal.SIGTERM, lambda signum, frame: stopping.append(signum))
    rclpy = node_runtime.init(argv)
    host = Host(process, composed)
    components: list[Component] = []
    for label, factory in factories:
        try:
            components.append(factory(rclpy, host))
        except ComponentError as exc:
            print(f"{label}: error: {exc}", file=sys.stderr, flush=True)
            for component in reversed(components):
                component.close()
            rclpy.try_shutdown()
            return 2
    for label, component in zip([label for label, _ in factories], components, strict=False):
        reason = _autostart(component)
        if reason is not None:  # a failed configure/activate of a node started alone: as a bad parameter
            print(f"{label}: error: {reason}", file=sys.stderr, flush=True)
            for started in reversed(components):
                started.close()
            rclpy.try_shutdown()
            return 2
    spun = [node for c in components for node in c.nodes]
    events = bool(spun) and all(c.events_executor for c in components if c.nodes)
    executor = node_runtime.make_executor(events) if spun else None
    for node in spun:
        executor.add_node(node)  # type: ignore[union-attr]
    logger = rclpy.logging.get_logger(process)
    if composed:
        ignored = [c.name for c in components if c.nodes and c.events_executor and not events]
        logger.info(f"{process}: {', '.join(c.name for c in components)} in one process"
                    + (f", {'EventsExecutor' if events else 'SingleThreadedExecutor'}" if executor else "")
                    + (f" ({', '.join(ignored)}: events_executor not used, shared with nodes that need "
                       "the SingleThreadedExecutor)" if ignored else ""))
    node_runtime.apply_rt_priority(max((c.rt_priority for c in components), default=0), logger)
    codes: list[int] = []
    try:
        _loop(rclpy, executor, components, stopping)
    finally:
        if executor is not None:
            executor.shutdown()
        for component in reversed(components):
            codes.append(component.close())
        rclpy.try_shutdown()
    return max(codes, default=0)


def _autostart(component: Component) -> str | None:
    """A managed component (c4d_ros.lifecycle) configures and activates itself unless a manager drives it."""
    from .lifecycle import ManagedNode, autostart

    node = getattr(component, "node", None)
    return autostart(node) if isinstance(node, ManagedNode) else None


def _loop(rclpy: Any, executor: Any, components: Sequence[Component], stopping: list[int]) -> None:
    periodic = [c for c in components if c.period_s is not None]
    if executor is None and len(periodic) == 1:  # the component has the process to itself: it may wait
        only = periodic[0]
        while not stopping and rclpy.ok():
            only.step(float(only.period_s or 0.0))
        return
    due = [0.0] * len(periodic)
    while not stopping and rclpy.ok():
        now = time.monotonic()
        for i, component in enumerate(periodic):
            if now >= due[i]:
                component.step(0.0)
                due[i] = now + float(component.period_s or 0.0)
        wait = max(0.0, min(due, default=now + 0.1) - time.monotonic())
        if executor is not None:
            executor.spin_once(timeout_sec=min(wait, 0.1))
        else:
            time.sleep(min(wait, 0.1))
