"""`c4d up` without ROS: prepare a run directory from a system config and supervise the graph.

prepare_run() checks everything that can be checked before a process starts (executables
resolve where `ros2 run` looks, parameter variables), creates the run directory
(<run_root>/<UTC stamp>/ with logs/, params/) and writes one ROS parameters file per node;
run_graph() starts the processes, restarts them by policy and stops them all on
SIGINT/SIGTERM/SIGHUP (a second signal skips the grace period) or when a critical node dies.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from collections.abc import Callable, Mapping
from datetime import UTC, datetime
from pathlib import Path

import yaml

from .supervisor import Placement, ProcessSpec, RestartPolicy, Supervisor, _pdeathsig, signal_group
from .system_config import (
    ConfigError,
    SystemConfig,
    component_argv,
    group_params_document,
    node_parameters,
    params_document,
    resolve_process,
    variables_for,
)


def new_run_dir(config: SystemConfig, root: str | None = None) -> Path:
    """A fresh <run_root>/<UTC stamp>[-k]/ (relative roots are relative to the working directory)."""
    base = Path(root or config.run_root).expanduser()
    stamp = datetime.now(UTC).strftime("%Y%m%d-%H%M%S")
    path, k = base / stamp, 2
    while path.exists():
        path, k = base / f"{stamp}-{k}", k + 1
    return path.resolve()


def resolve_all(config: SystemConfig) -> dict[str, Path]:
    """Executable of every process — a node's own, or the container of a composition group —
    (ConfigError naming the first that does not resolve)."""
    return {process.name: resolve_process(process) for process in config.processes()}


def prepare_run(config: SystemConfig, run_dir: Path, executables: Mapping[str, Path] | None = None) -> list[ProcessSpec]:
    """Resolve, substitute, write the parameter files; return the process specs (nothing started)."""
    executables = executables or resolve_all(config)
    variables = variables_for(config, run_dir)
    parameters = {node.name: node_parameters(node, variables, config.path) for node in config.nodes}
    for name in config.managed():  # the lifecycle manager drives them (c4d_bringup.lifecycle_manager)
        parameters[name] = {**parameters[name], "autostart": False}
    try:
        (run_dir / "params").mkdir(parents=True, exist_ok=True)
        (run_dir / "logs").mkdir(exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot create the run directory {run_dir}: {exc.strerror or exc}") from None
    specs = []
    for process in config.processes():
        argv = [str(executables[process.name])]
        names = tuple(n.name for n in process.members)
        if process.composed:
            argv += component_argv(process)
            document = group_params_document({n: parameters[n] for n in names})
        else:
            document = params_document(parameters[names[0]]) if parameters[names[0]] else {}
        if document:
            params_file = run_dir / "params" / f"{process.name}.yaml"
            params_file.write_text(yaml.safe_dump(document, sort_keys=False))
            argv += ["--ros-args", "--params-file", str(params_file)]
        specs.append(ProcessSpec(process.name, tuple(argv), run_dir / "logs" / f"{process.name}.log", process.critical,
                                 RestartPolicy(process.restart, process.max_restarts, process.restart_window_s,
                                               process.backoff_s),
                                 Placement(process.cpu_affinity, process.nice), names if process.composed else ()))
    return specs


def start_lifecycle_manager(config: SystemConfig, run_dir: Path, env: Mapping[str, str],
                            phase: str | None) -> subprocess.Popen | None:
    """The lifecycle manager (c4d_bringup.lifecycle_manager) in its own session, logging to logs/lifecycle_manager.log;
    None when no node is managed."""
    if not config.managed():
        return None
    argv = [sys.executable, "-m", "c4d_bringup.lifecycle_manager", "--config", str(config.path), "--run-dir", str(run_dir)]
    with open(run_dir / "logs" / "lifecycle_manager.log", "ab") as out:
        return subprocess.Popen(argv + (["--phase", phase] if phase else []), stdout=out, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, env=dict(env), start_new_session=True, preexec_fn=_pdeathsig)


def manager_failure(run_dir: Path) -> str:
    """The manager's `lifecycle: error: ...` line (the failed node and its reason)."""
    try:
        lines = (run_dir / "logs" / "lifecycle_manager.log").read_text(errors="replace").splitlines()
    except OSError:
        lines = []
    return next((line for line in reversed(lines) if line.startswith("lifecycle: error: ")),
                f"lifecycle: error: the lifecycle manager failed (see {run_dir / 'logs' / 'lifecycle_manager.log'})")


def stop_process(proc: subprocess.Popen | None, timeout: float) -> None:
    if proc is None:
        return
    if proc.poll() is None:
        signal_group(proc.pid, signal.SIGINT)
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            pass
    signal_group(proc.pid, signal.SIGKILL)
    proc.wait()


def run_graph(config: SystemConfig, specs: list[ProcessSpec], env: Mapping[str, str], run_dir: Path,
              log: Callable[[str], None], phase: str | None = None) -> int:
    """Supervise until a stop signal (exit 0) or a critical failure (exit 1) — a failed lifecycle transition
    at start is one (its reason printed); every child is gone on return."""
    signals: list[int] = []

    def on_signal(signum, frame) -> None:
        signals.append(signum)

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    supervisor = Supervisor(specs, env, log=log, state_file=run_dir / "supervisor.json",
                            restart_spacing_s=config.restart_spacing_s)
    manager = None
    try:
        supervisor.start()
        nodes = sum(len(s.members) or 1 for s in specs)
        log(f"up: {nodes} nodes in {len(specs)} processes, logs in {run_dir / 'logs'} (Ctrl-C to stop)")
        manager = start_lifecycle_manager(config, run_dir, env, phase)
        while not signals and supervisor.failure is None:
            supervisor.poll()
            if manager is not None and manager.poll() not in (None, 0):
                log(manager_failure(run_dir))
                supervisor.failure = "a lifecycle transition failed"
            time.sleep(0.1)
        if supervisor.failure:
            log(f"stopping: {supervisor.failure}")
        else:
            log(f"stopping on {signal.Signals(signals[0]).name}")
    finally:
        stop_process(manager, 2.0)
        codes = supervisor.stop(config.shutdown_timeout_s, force=lambda: len(signals) > 1)
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    bad = {n: c for n, c in codes.items() if c not in (0, -signal.SIGINT)}
    log("down: every node stopped" + (f" ({', '.join(f'{n}: {c}' for n, c in bad.items())})" if bad else ""))
    return 1 if supervisor.failure else 0


def stamped_logger(stream=None) -> Callable[[str], None]:
    def log(text: str) -> None:
        out = stream or sys.stdout
        print(f"c4d [{time.strftime('%H:%M:%S')}] {text}", file=out, flush=True)
    return log
