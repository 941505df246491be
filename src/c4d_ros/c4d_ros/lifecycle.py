"""Managed (lifecycle) c4d nodes: rclpy's LifecycleNode with the c4d conventions (docs/lifecycle.md).

Every c4d node is a `ManagedNode`: it starts UNCONFIGURED with the standard lifecycle services
(`/<node>/change_state`, `get_state`, ... and the `transition_event` topic, lifecycle_msgs) and
does its work in the transitions through a `Work` object:

- configure: load and validate the configuration, create the publishers, subscriptions, timers
  and services (the node's owner object is built here);
- activate: timers run and publishers send (both are gated by the node itself: a timer created
  while the node is not ACTIVE starts cancelled, a publisher drops what it is given while the
  node is not ACTIVE — subscriptions keep their state fresh in INACTIVE);
- deactivate: timers cancelled, publishers silent;
- cleanup / shutdown: everything configure created is destroyed (parameters stay declared with
  the values in force; a later configure re-uses them).

A transition the Work refuses raises TransitionError(reason): the node logs
`lifecycle: <transition> failed: <reason>` at ERROR, keeps the reason in `last_error` and the
transition returns FAILURE (the state does not change). An invalid transition requested through
the service (e.g. activate while UNCONFIGURED) answers success = false instead of raising.

`autostart` (parameter, default true): the node configures and activates itself at start, so
`ros2 run c4d_gnc core` alone runs as before; a lifecycle manager (`c4d up`) starts the nodes with
autostart false and drives the transitions through the services (nav2's lifecycle_manager model).

`ManagedComponent` is the c4d_ros.component adapter: the factory declares the parameters and hands
over `build` (the previous factory body that created the owner object); the runner autostarts it.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any, Protocol

import lifecycle_msgs.msg
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn

from .params import ParameterError, Spec, declare_all

AUTOSTART = Spec(True, "configure and activate at start; false: wait for a lifecycle manager (c4d up) to drive the "
                       "transitions through <node>/change_state [bool]", read_only=True)
SUCCESS, FAILURE = TransitionCallbackReturn.SUCCESS, TransitionCallbackReturn.FAILURE
ACTIVE = lifecycle_msgs.msg.State.PRIMARY_STATE_ACTIVE
INACTIVE = lifecycle_msgs.msg.State.PRIMARY_STATE_INACTIVE
UNCONFIGURED = lifecycle_msgs.msg.State.PRIMARY_STATE_UNCONFIGURED
T = lifecycle_msgs.msg.Transition
SHUTDOWNS = (T.TRANSITION_UNCONFIGURED_SHUTDOWN, T.TRANSITION_INACTIVE_SHUTDOWN, T.TRANSITION_ACTIVE_SHUTDOWN)


class TransitionError(Exception):
    """A transition refused or failed, with the one-line reason."""


class Work(Protocol):
    """What a managed node does in each transition (each may raise TransitionError)."""

    def configure(self) -> None: ...

    def activate(self) -> None: ...

    def deactivate(self) -> None: ...

    def cleanup(self) -> None: ...


class ManagedNode(LifecycleNode):
    """rclpy LifecycleNode + timer/publisher gating, entity bookkeeping for cleanup, reasons for failures."""

    def __init__(self, name: str, **kwargs: Any) -> None:
        self._gating = False
        super().__init__(name, **kwargs)
        self.work: Work | None = None
        self.last_error = ""  # "<transition> failed: <reason>" of the last failed transition
        self.last_reason = ""  # its reason alone
        self.quiet_failures = False  # True while autostart runs the transitions (it reports the reason)
        self.active = False
        self._timers: list[Any] = []
        self._made: list[tuple[Callable[[Any], Any], Any]] = []
        self._callbacks_before: list[list[Any]] = [[], [], []]
        self._configured_parameters: set[str] = set()  # declared by configure: writable again for the next one
        # an invalid transition through the service must answer false, not raise out of the executor
        srv = self._service_change_state
        srv.callback = self._safe_change_state(srv.callback)
        self._gating = True

    # ------------------------------------------------------------------ gating
    def create_timer(self, *args: Any, **kwargs: Any) -> Any:
        timer = super().create_timer(*args, **kwargs)
        if self._gating:
            self._timers.append(timer)
            if not self.active:
                timer.cancel()
        return timer

    def create_publisher(self, *args: Any, **kwargs: Any) -> Any:
        pub = super().create_publisher(*args, **kwargs)
        if self._gating:
            publish = pub.publish

            def gated(msg: Any) -> None:
                if self.active:
                    publish(msg)
            pub.publish = gated
        return pub

    def destroy_timer(self, timer: Any) -> bool:
        if timer in self._timers:
            self._timers.remove(timer)
        return bool(super().destroy_timer(timer))

    def declare_parameters(self, namespace: str, parameters: list, ignore_override: bool = False) -> list:
        """A second configure (after cleanup) re-declares: the parameters already declared keep the value in force."""
        fresh = [p for p in parameters if not self.has_parameter(namespace + p[0] if namespace else p[0])]
        declared = iter(super().declare_parameters(namespace, fresh, ignore_override) if fresh else ())
        return [next(declared) if p in fresh else self.get_parameter(namespace + p[0] if namespace else p[0])
                for p in parameters]

    # ------------------------------------------------------------------ transitions
    def _safe_change_state(self, callback: Callable[[Any, Any], Any]) -> Callable[[Any, Any], Any]:
        def change_state(request: Any, response: Any) -> Any:
            transition = request.transition
            if transition.id in SHUTDOWNS or transition.label == "shutdown":
                # a FAILURE of on_shutdown still ends in FINALIZED (rcl's state machine): refuse before it starts
                reason = getattr(self.work, "refusal", lambda: None)()
                if reason:
                    self.last_error = f"shutdown failed: {reason}"
                    self.get_logger().error(f"lifecycle: {self.last_error}")
                    response.success = False
                    return response
            try:
                return callback(request, response)
            except _rclpy.RCLError as exc:
                self.get_logger().warning(f"lifecycle: transition {request.transition.label or request.transition.id} "
                                          f"refused in state {self.state_label()}: {str(exc).splitlines()[0]}")
                response.success = False
                return response
        return change_state

    def state_label(self) -> str:
        return str(self._state_machine.current_state[1])

    def state_id(self) -> int:
        return int(self._state_machine.current_state[0])

    def _run(self, transition: str, action: Callable[[], None]) -> TransitionCallbackReturn:
        try:
            action()
        except TransitionError as exc:
            self.last_reason = str(exc)
        except Exception as exc:
            self.last_reason = f"{type(exc).__name__}: {exc}"
        else:
            return SUCCESS
        self.last_error = f"{transition} failed: {self.last_reason}"
        if not self.quiet_failures:  # autostart prints the reason itself, as one line (bad-input rule)
            self.get_logger().error(f"lifecycle: {self.last_error}")
        return FAILURE

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        before = self._entities()
        self._callbacks_before = [list(c) for c in self._parameter_callbacks()]
        declared_before = set(self._parameters)

        def configure() -> None:
            if self.work is None:
                raise TransitionError("no work attached")
            try:
                self.work.configure()
            finally:  # on success kept for cleanup, on failure destroyed at once
                self._made = [e for e in self._entities() if e not in before]
                self._configured_parameters |= set(self._parameters) - declared_before
        code = self._run("configure", configure)
        if code != SUCCESS:
            self._destroy_made()
            for callbacks, before in zip(self._parameter_callbacks(), self._callbacks_before, strict=True):
                callbacks[:] = before
        else:
            self.get_logger().info("lifecycle: configured (inactive)")
        return code

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        def activate() -> None:
            assert self.work is not None
            self.active = True
            try:
                self.work.activate()
            except Exception:
                self.active = False
                raise
            for timer in self._timers:
                timer.reset()
        code = self._run("activate", activate)
        if code == SUCCESS:
            self.get_logger().info("lifecycle: active")
        return code

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        def deactivate() -> None:
            assert self.work is not None
            self.work.deactivate()  # may refuse (the core while armed): still active then
            self.active = False
            for timer in self._timers:
                timer.cancel()
        code = self._run("deactivate", deactivate)
        if code == SUCCESS:
            self.get_logger().info("lifecycle: deactivated (inactive)")
        return code

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        code = self._run("cleanup", self._cleanup)
        if code == SUCCESS:
            self.get_logger().info("lifecycle: cleaned up (unconfigured)")
        return code

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        def shutdown() -> None:
            if self.active:
                self.on_deactivate_or_raise()
            if state.state_id != UNCONFIGURED:
                self._cleanup()
        return self._run("shutdown", shutdown)

    def on_deactivate_or_raise(self) -> None:
        assert self.work is not None
        self.work.deactivate()
        self.active = False
        for timer in self._timers:
            timer.cancel()

    def _cleanup(self) -> None:
        assert self.work is not None
        self.work.cleanup()
        self._destroy_made()
        for callbacks, before in zip(self._parameter_callbacks(), self._callbacks_before, strict=True):
            callbacks[:] = before  # the parameter callbacks configure added go with it
        for name in self._configured_parameters:  # the next configure settles them again (then read-only again)
            self._descriptors[name].read_only = False

    def _parameter_callbacks(self) -> tuple[list[Any], ...]:
        return (self._pre_set_parameters_callbacks, self._on_set_parameters_callbacks, self._post_set_parameters_callbacks)

    # ------------------------------------------------------------------ bookkeeping
    def _entities(self) -> list[tuple[Callable[[Any], Any], Any]]:
        return ([(self.destroy_timer, t) for t in self.timers] + [(self.destroy_publisher, p) for p in self.publishers]
                + [(self.destroy_subscription, s) for s in self.subscriptions]
                + [(self.destroy_service, s) for s in self.services] + [(self.destroy_client, c) for c in self.clients]
                + [(lambda w: w.destroy(), w) for w in self.waitables if hasattr(w, "destroy")])

    def _destroy_made(self) -> None:
        for destroy, entity in reversed(self._made):
            try:
                destroy(entity)
            except Exception as exc:
                self.get_logger().warning(f"lifecycle: cleanup: {type(exc).__name__}: {exc}")
        self._made = []


def create_node(rclpy: Any, name: str) -> ManagedNode:
    """A ManagedNode with its `autostart` parameter declared (ComponentError, one line, on a bad value)."""
    from .errors import ComponentError

    del rclpy  # the default context, as rclpy.create_node
    node = ManagedNode(name)
    try:
        node.autostart = bool(declare_all(node, {"autostart": AUTOSTART})["autostart"])
    except ParameterError as exc:
        node.destroy_node()
        raise ComponentError(str(exc)) from None
    return node


def autostart(node: ManagedNode) -> str | None:
    """configure + activate when the node's autostart says so; None, or the failure's reason."""
    if not getattr(node, "autostart", False):
        return None
    node.quiet_failures = True
    try:
        if node.trigger_configure() != SUCCESS or node.trigger_activate() != SUCCESS:
            return node.last_reason
    finally:
        node.quiet_failures = False
    return None


class ServiceDrain:
    """Serves a node's services (lifecycle and parameters) without an executor, for nodes whose own loop
    is not running yet (before configure, while inactive)."""

    def __init__(self, node: Any) -> None:
        from .drain import Drainer

        self.drainer = Drainer(node)
        self.drainer.adopt_node_services()

    def serve(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while True:
            if not self.drainer.drain():
                left = end - time.monotonic()
                if left <= 0:
                    return
                time.sleep(min(left, 0.005))


class ManagedComponent:
    """c4d_ros.component protocol around a ManagedNode whose component (`build()`, the previous
    factory body) is created on configure and released on cleanup.

    spun=True: the runner's executor spins the node (the built component is a SpunNode); spun=False:
    the built component drives its node itself (the bridge, the recorder, the offboard gateway): its
    step() runs only while ACTIVE, its optional `idle(budget_s)` otherwise; before configure the
    node's services are drained here."""

    def __init__(self, name: str, node: ManagedNode, build: Callable[[], Any], *, events_executor: bool = False,
                 rt_priority: int = 0, period_s: float | None = None, spun: bool = True) -> None:
        self.name, self.node, self.build = name, node, build
        self.events_executor, self.rt_priority = events_executor, rt_priority
        self.spun = spun
        self.period_s = None if spun else (period_s or 0.01)
        self.nodes: Sequence[Any] = (node,) if spun else ()
        self.inner: Any = None
        self.idle_services = None if spun else ServiceDrain(node)
        node.work = self

    # Work
    def configure(self) -> None:
        from .errors import ComponentError

        try:
            self.inner = self.build()
        except ComponentError as exc:
            raise TransitionError(str(exc)) from None

    def activate(self) -> None:
        pass

    def deactivate(self) -> None:
        pass

    def cleanup(self) -> None:
        inner, self.inner = self.inner, None
        release = getattr(inner, "release", None)
        if release is not None:
            release()
        for extra in getattr(inner, "extra", ()):
            extra.destroy_node()

    # Component
    def step(self, budget_s: float) -> None:
        inner = self.inner
        if inner is None:
            if self.idle_services is not None:
                self.idle_services.serve(budget_s)
        elif self.node.active or not hasattr(inner, "idle"):
            inner.step(budget_s)
        else:
            inner.idle(budget_s)

    def close(self) -> int:
        inner, self.inner = self.inner, None
        if inner is not None:
            return int(inner.close())
        self.node.destroy_node()
        return 0


class LoopWork:
    """Work of a node whose ACTIVE state is a blocking loop in the main thread (the core's and the sim's
    cyclic executives, no executor): configure builds the owner (`build()`; an exception of `errors` is
    the failure's reason), `run()` below calls `owner.run()` while ACTIVE, deactivate stops that loop
    (`stop(owner)`) unless `refuse(owner)` gives a reason (the core while armed). Between activations the
    node's lifecycle and parameter services are drained here."""

    def __init__(self, node: ManagedNode, build: Callable[[], Any], errors: tuple[type[BaseException], ...],
                 stop: Callable[[Any], None], refuse: Callable[[Any], str | None] | None = None) -> None:
        self.node, self.build, self.errors, self.stop, self.refuse = node, build, errors, stop, refuse
        self.owner: Any = None
        self.running = self.deactivating = False
        node.work = self

    def configure(self) -> None:
        try:
            self.owner = self.build()
        except self.errors as exc:
            raise TransitionError(str(exc)) from None

    def activate(self) -> None:
        pass

    def refusal(self) -> str | None:
        """Why the node may not leave ACTIVE now (None: it may)."""
        return self.refuse(self.owner) if self.refuse is not None and self.owner is not None else None

    def deactivate(self) -> None:
        reason = self.refusal()
        if reason:
            raise TransitionError(reason)
        if self.running:
            self.deactivating = True
            self.stop(self.owner)

    def cleanup(self) -> None:
        self.owner = None

    def run(self, name: str) -> int:
        """Autostart (a failure: one line, exit 2, as a bad parameter), then the owner's loop while ACTIVE
        and the services otherwise, until SIGINT/SIGTERM; the node and the rclpy context are gone on return."""
        import signal

        import rclpy

        from . import node_runtime

        stopping: list[int] = []

        def on_signal(signum: int, frame: Any) -> None:
            stopping.append(signum)
        handlers = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
        reason = autostart(self.node)
        if reason is not None:
            return node_runtime.fail(name, reason, self.node)
        idle = ServiceDrain(self.node)
        try:
            while not stopping and rclpy.ok():
                if self.owner is not None and self.node.active:
                    self.running = True
                    try:
                        code = int(self.owner.run())  # installs its own SIGINT/SIGTERM handlers
                    finally:
                        self.running = False
                        for sig in handlers:
                            signal.signal(sig, on_signal)
                    if not self.deactivating:
                        return code  # stopped by a signal
                    self.deactivating = False
                else:
                    idle.serve(0.05)
            return 0
        finally:
            self.node.destroy_node()
            rclpy.try_shutdown()
