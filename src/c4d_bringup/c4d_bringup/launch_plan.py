"""What `ros2 launch c4d_bringup sitl.launch.py` starts, computed without ROS from the system YAML.

The launch file turns each LaunchEntry into a launch_ros Node, so `ros2 launch` and `c4d up`
start the same executables with the same parameters in the same order. Restart policy maps to
launch's respawn: never -> no respawn; on-failure and always -> respawn (launch respawns on any
exit) after `backoff_s`, at most `max_restarts` times (launch has no time window and no
doubling back-off); a critical node's exit shuts the whole launch down, as in `c4d up`.

Process composition (`compose`) and process placement (`cpu_affinity`, `nice`) are `c4d up`
features: a system YAML using them is refused here with one line (ConfigError) rather than
launched differently from what it says.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .graph import new_run_dir
from .system_config import (
    ConfigError,
    SystemConfig,
    check_variables,
    default_config_path,
    load_system_config,
    node_parameters,
    resolve_executable,
    variables_for,
)


@dataclass(frozen=True)
class LaunchEntry:
    name: str
    package: str
    executable: str
    parameters: dict[str, Any]
    critical: bool
    respawn: bool
    respawn_delay: float
    respawn_max_retries: int


@dataclass(frozen=True)
class LaunchPlan:
    config: SystemConfig
    run_dir: Path
    discovery_range: str
    entries: tuple[LaunchEntry, ...]


def launch_plan(config_path: str | None = None, run_dir: str | None = None) -> LaunchPlan:
    """Load and check the system config (ConfigError on any problem); nothing is started or written."""
    config = load_system_config(config_path or default_config_path())
    check_variables(config)
    if config.groups:
        raise ConfigError(f"system config {config.path}: compose (process composition) is supported by c4d up / c4d fly "
                          "only; ros2 launch starts one process per node — remove 'compose' to launch it")
    placed = [n.name for n in config.nodes if n.cpu_affinity is not None or n.nice is not None]
    if placed:
        raise ConfigError(f"system config {config.path}: cpu_affinity / nice (node {', '.join(placed)}) are applied by "
                          "c4d up / c4d fly only; remove them to launch with ros2 launch")
    for node in config.nodes:
        resolve_executable(node)
    run = Path(run_dir).resolve() if run_dir else new_run_dir(config)
    variables = variables_for(config, run)
    entries = tuple(LaunchEntry(n.name, n.package, n.executable, node_parameters(n, variables, config.path), n.critical,
                                n.restart != "never", n.backoff_s, n.max_restarts) for n in config.nodes)
    return LaunchPlan(config, run, config.discovery_range, entries)
