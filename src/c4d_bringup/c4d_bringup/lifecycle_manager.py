"""The lifecycle manager `c4d up` starts next to the graph (nav2's lifecycle_manager model; docs/lifecycle.md).

    python -m c4d_bringup.lifecycle_manager --config SYSTEM.yaml --run-dir DIR [--phase PHASE]

The managed nodes run with `autostart: false`: this process drives them through their standard
services (`/<node>/get_state`, `/<node>/change_state`, lifecycle_msgs): at start every node is
configured in start order, then the nodes the current phase wants are activated. A failed
transition at start ends this process with exit 1 and one line `lifecycle: error: <node>: <reason>`,
the reason being the node's own `lifecycle: ... failed: ...` log line (c4d_bringup.system_modes.read_reason);
`c4d up` then stops the graph and prints that line. Afterwards it follows vehicle/status: a phase
change (system_modes.phase_of) activates and deactivates nodes as the system YAML's `modes` say, and
a node found UNCONFIGURED again (restarted by the supervisor) is brought back to its state. A failure
then is logged and retried at the next check; a refusal (the core while armed) too.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import time
from pathlib import Path
from typing import Any

from .system_config import ConfigError, SystemConfig, load_system_config
from .system_modes import ACTIVE, PHASES, STATE_LABELS, ModeTable, Step, plan, read_reason

START_TIMEOUT_S = 60.0  # a node's lifecycle services must appear within this long of the manager's start
CALL_TIMEOUT_S = 20.0  # one transition (the core's configure loads and checks its whole config)
GET_STATE_RESEND_S = 2.0  # a get_state unanswered this long is sent again (idempotent; see _call)
CHECK_PERIOD_S = 2.0  # every node's state is read this often (a restarted node comes back unconfigured)
TRANSITION_IDS = {"configure": 1, "cleanup": 2, "activate": 3, "deactivate": 4}


class TransitionFailed(Exception):
    """A transition that failed (one line: node and reason)."""


def log_paths(config: SystemConfig, run_dir: Path) -> dict[str, Path]:
    """node -> the log file of the process it runs in (graph.prepare_run's layout)."""
    return {member.name: run_dir / "logs" / f"{process.name}.log" for process in config.processes()
            for member in process.members}


class LifecycleManager:
    def __init__(self, table: ModeTable, logs: dict[str, Path], pinned: str | None, stopping: list[int],
                 say=print) -> None:
        from lifecycle_msgs.srv import ChangeState, GetState

        from c4d_interfaces.msg import VehicleStatus
        from c4d_ros import manifest, node_runtime

        from .system_modes import phase_of

        self.rclpy = node_runtime.init([])
        from rclpy.executors import SingleThreadedExecutor

        self.table, self.logs, self.say, self.stopping = table, logs, say, stopping
        self.node = self.rclpy.create_node("lifecycle_manager")
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.change = {n: self.node.create_client(ChangeState, f"/{n}/change_state") for n in table.nodes}
        self.get = {n: self.node.create_client(GetState, f"/{n}/get_state") for n in table.nodes}
        self.ChangeState, self.GetState = ChangeState, GetState
        self.phase = pinned or "preflight"
        self.pinned = pinned is not None

        def on_status(msg: Any) -> None:
            if not self.pinned:
                self.phase = phase_of(msg.armed, msg.landed_state, msg.nav_state)
        self.node.create_subscription(VehicleStatus, manifest.STATUS.name, on_status, manifest.STATUS.qos)

    # ------------------------------------------------------------------ service calls
    def _call(self, client: Any, request: Any, timeout: float, resend_after: float = math.inf) -> Any:
        """The response within `timeout`, or None. `resend_after`: an idempotent request is sent again when no
        response came within that long — a server may answer before it has discovered the client's response
        reader, and DDS then drops the answer ("failed to send response (timeout)" in its log; one CI bring-up
        waited out its 60 s on such a lost get_state answer)."""
        end = time.monotonic() + timeout
        while not client.service_is_ready():
            if time.monotonic() >= end or self.stopping:
                return None
            self.executor.spin_once(timeout_sec=0.05)
        while True:
            future = client.call_async(request)
            resend = time.monotonic() + resend_after
            while not future.done():
                now = time.monotonic()
                if now >= end or self.stopping or now >= resend:
                    client.remove_pending_request(future)
                    break
                self.executor.spin_once(timeout_sec=0.05)
            if future.done():
                return future.result()
            if time.monotonic() >= end or self.stopping:
                return None

    def state(self, node: str, timeout: float = 2.0) -> int:
        response = self._call(self.get[node], self.GetState.Request(), timeout, resend_after=GET_STATE_RESEND_S)
        return 0 if response is None else int(response.current_state.id)

    def apply(self, step: Step) -> None:
        request = self.ChangeState.Request()
        request.transition.id = TRANSITION_IDS[step.transition]
        response = self._call(self.change[step.node], request, CALL_TIMEOUT_S)
        if response is None:
            raise TransitionFailed(f"{step.node}: {step.transition}: no answer within {CALL_TIMEOUT_S:g} s")
        if not response.success:
            time.sleep(0.2)  # the node's log line is written by its own process
            raise TransitionFailed(f"{step.node}: {read_reason(self.logs.get(step.node), step.node)}")
        self.say(f"lifecycle: {step} ok")

    # ------------------------------------------------------------------ bring-up and following the phase
    def bring_up(self) -> None:
        states = {}
        for name in self.table.nodes:
            states[name] = self.state(name, START_TIMEOUT_S)
            if states[name] == 0:
                raise TransitionFailed(f"{name}: no lifecycle services (/{name}/get_state) within {START_TIMEOUT_S:g} s "
                                       f"(see {self.logs.get(name)})")
        for step in plan(states, self.table.active_in(self.phase), self.table.nodes):
            self.apply(step)
        self.say(f"lifecycle: phase {self.phase}: " + ", ".join(
            f"{n} {'active' if n in self.table.active_in(self.phase) else 'inactive'}" for n in self.table.nodes))

    def follow(self) -> None:
        current, next_check = self.phase, time.monotonic() + CHECK_PERIOD_S
        while not self.stopping:
            self.executor.spin_once(timeout_sec=0.1)
            if self.phase == current and time.monotonic() < next_check:
                continue
            if self.phase != current:
                self.say(f"lifecycle: phase {current} -> {self.phase}")
                current = self.phase
            next_check = time.monotonic() + CHECK_PERIOD_S
            states = {n: self.state(n) for n in self.table.nodes}
            for step in plan(states, self.table.active_in(current), self.table.nodes):
                try:
                    self.apply(step)
                except TransitionFailed as exc:
                    self.say(f"lifecycle: warning: {exc} (retried in {CHECK_PERIOD_S:g} s)")
                    break
            dropped = [n for n, s in states.items() if s not in (0, ACTIVE) and n in self.table.active_in(current)]
            if dropped:
                self.say("lifecycle: " + ", ".join(f"{n} was {STATE_LABELS.get(states[n], states[n])}" for n in dropped))

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.rclpy.try_shutdown()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="c4d_bringup.lifecycle_manager")
    parser.add_argument("--config", type=Path, required=True)
    parser.add_argument("--run-dir", type=Path, required=True)
    parser.add_argument("--phase", choices=PHASES)
    args = parser.parse_args(argv)
    stopping: list[int] = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, frame: stopping.append(signum))
    try:
        config = load_system_config(args.config)
    except ConfigError as exc:
        print(f"lifecycle: error: {exc}", flush=True)
        return 2
    say = lambda text: print(text, flush=True)  # noqa: E731
    table = config.mode_table()
    manager = LifecycleManager(table, log_paths(config, args.run_dir), args.phase, stopping, say)
    try:
        manager.bring_up()
        say(f"lifecycle: all {len(table.nodes)} managed nodes configured; modes: {table.describe()}")
        manager.follow()
    except TransitionFailed as exc:
        if stopping:
            return 0
        say(f"lifecycle: error: {exc}")
        return 1
    finally:
        manager.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
