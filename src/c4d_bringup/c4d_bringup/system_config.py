"""System configuration: which nodes run, with which parameters, on which platform.

One YAML file describes the whole graph; `c4d up`, `c4d fly`, `c4d status` and
`ros2 launch c4d_bringup sitl.launch.py` all read it through this module, so they start the
same processes with the same parameters. Format (the bundled config/sitl.yaml is the reference):

    platform: sitl                 # sitl (the simulated vehicle `sim` must run) | hardware (no sim)
    discovery_range: LOCALHOST     # ROS_AUTOMATIC_DISCOVERY_RANGE of every node (env C4D_DISCOVERY_RANGE overrides)
    run_root: c4d_runs             # each run writes <run_root>/<UTC stamp>/ (logs, params, flights, captures, report)
    shutdown_timeout_s: 10         # SIGINT, then SIGKILL after this long
    restart_spacing_s: 2.0         # at least this long between any two (re)starts: restarts are staggered
    lockstep: false                # true: simulated time advances only when the core answered each step (sim and core
                                   # get lockstep: true, every other node use_sim_time: true; docs/sim.md)
    compose:                       # optional: several nodes in one process (one executor), by group name
      ground: [mission, payload, health, bridge, recorder]      # short form, or the long form:
      sensing: {nodes: [perception, navigation], cpu_affinity: ["0..-2"], nice: 0}
    nodes:                         # started in this order, each in its own process (or in its group's)
      core:                        # a known node name (see CATALOGUE) ...
        critical: true             # its death stops the whole graph (default: see CATALOGUE)
        restart: never             # never | on-failure | always (default: never if critical, else always)
        max_restarts: 5            # in any restart_window_s; then it stays down (a critical one stops the graph)
        restart_window_s: 60
        backoff_s: 1.0             # delay before a restart, doubled per consecutive restart (max 10 s)
        enabled: true
        cpu_affinity: [-1]         # CPUs the process may run on: ids, -1 = the last usable CPU, "0..-2" = a range
        nice: 0                    # niceness of the process, -20..19 (below the current one needs CAP_SYS_NICE)
        parameters: {rt_priority: 50}
      my_node: {package: my_pkg, executable: my_exe}   # ... or any node given with package and executable

Parameter values are ROS parameter values: booleans, integers, floats, strings, non-empty
lists of one of those, or nested mappings (flattened to dotted names, e.g. fault.gps_loss).
Strings may use ${run} (this run's directory) and ${config_dir} (the directory of the system
YAML). Every problem is a ConfigError with one line; nothing here starts a process.

Composition (`compose`): a group is one supervised process running the c4d component container
(c4d_bringup/container) with its members as separate rclpy nodes on one executor, so node names,
parameters, topics and services are those of the separate processes. sim and core cannot be
composed (their own real-time run loops). The group's process is critical if any member is; its
restart policy is the members' most restarting mode (always > on-failure > never), the smallest
max_restarts, the longest restart_window_s and backoff_s. cpu_affinity and nice of a composed
process are set on the group (setting them on a member is an error: it would apply to the whole
group). CPU ids are checked against the CPUs this process may use (os.sched_getaffinity).
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import yaml

from c4d_common.config_file import yaml_error_text
from c4d_common.share import share_file
from c4d_ros.dds_profile import with_profile

from .system_modes import ModesError, ModeTable, parse_modes

# node name -> (package, executable, critical by default)
CATALOGUE: dict[str, tuple[str, str, bool]] = {
    "sim": ("c4d_sim", "sim", True),
    "perception": ("c4d_gnc", "perception", True),
    "navigation": ("c4d_gnc", "navigation", True),
    "core": ("c4d_gnc", "core", True),
    "mission": ("c4d_mission", "mission", False),
    "payload": ("c4d_mission", "payload", False),
    "health": ("c4d_health", "health", False),
    "bridge": ("c4d_bridge_mavlink", "bridge", False),
    "offboard": ("c4d_offboard", "offboard", False),
    "recorder": ("c4d_data", "recorder", False),
}
PLATFORMS = ("sitl", "hardware")
RESTART_MODES = ("never", "on-failure", "always")
DISCOVERY_RANGES = ("LOCALHOST", "SUBNET", "SYSTEM_DEFAULT", "OFF")
TOP_KEYS = {"platform", "discovery_range", "run_root", "shutdown_timeout_s", "restart_spacing_s", "compose", "nodes",
            "lockstep", "modes"}
LOCKSTEP_NODES = ("sim", "core")  # they take `lockstep: true`; every other node follows /clock (use_sim_time)
RESTART_SPACING_S = 2.0  # default: a DDS participant's discovery burst is over well within 2 s on localhost
NODE_KEYS = {"package", "executable", "critical", "restart", "max_restarts", "restart_window_s", "backoff_s",
             "enabled", "cpu_affinity", "nice", "parameters"}
GROUP_KEYS = {"nodes", "cpu_affinity", "nice"}
OWN_PROCESS = {"sim": "the simulated vehicle's real-time step loop", "core": "the cyclic executive"}  # never composed
NICE_RANGE = (-20, 19)
CPU_RANGE = re.compile(r"^\s*(-?\d+)\s*\.\.\s*(-?\d+)\s*$")
NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
PARAM_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$")
VARIABLE = re.compile(r"\$\{([^}]*)\}")
Scalar = bool | int | float | str


class ConfigError(ValueError):
    """A system configuration that cannot be used (one line, says where)."""


@dataclass(frozen=True)
class NodeConfig:
    name: str
    package: str
    executable: str
    critical: bool
    restart: str = "never"
    max_restarts: int = 5
    restart_window_s: float = 60.0
    backoff_s: float = 1.0
    parameters: Mapping[str, Any] = field(default_factory=dict)  # flattened dotted names
    cpu_affinity: tuple[int, ...] | None = None  # CPU ids the process may run on (None: inherited)
    nice: int | None = None  # niceness of the process (None: inherited)


@dataclass(frozen=True)
class GroupConfig:
    """A composition group of the system YAML: these nodes share one process and one executor."""

    name: str
    members: tuple[str, ...]
    cpu_affinity: tuple[int, ...] | None = None
    nice: int | None = None


@dataclass(frozen=True)
class ProcessPlan:
    """One supervised process: a node alone (its own executable) or a composition group (the
    container running its members). Restart settings of a group are merged from its members."""

    name: str
    members: tuple[NodeConfig, ...]
    composed: bool
    critical: bool
    restart: str
    max_restarts: int
    restart_window_s: float
    backoff_s: float
    cpu_affinity: tuple[int, ...] | None
    nice: int | None


@dataclass(frozen=True)
class SystemConfig:
    path: Path
    platform: str
    discovery_range: str
    run_root: str
    shutdown_timeout_s: float
    nodes: tuple[NodeConfig, ...]
    restart_spacing_s: float = RESTART_SPACING_S  # minimum time between any two (re)starts [s]
    groups: tuple[GroupConfig, ...] = ()
    modes: ModeTable | None = None  # system modes (c4d_bringup.system_modes); None: every node active in every phase

    def managed(self) -> list[str]:
        """The lifecycle-managed nodes in start order: the c4d nodes of the catalogue (docs/lifecycle.md)."""
        return [n.name for n in self.nodes if CATALOGUE.get(n.name, ("", "", False))[:2] == (n.package, n.executable)]

    def mode_table(self) -> ModeTable:
        return self.modes or ModeTable(tuple(self.managed()), {})

    def node(self, name: str) -> NodeConfig | None:
        return next((n for n in self.nodes if n.name == name), None)

    @property
    def names(self) -> list[str]:
        return [n.name for n in self.nodes]

    def group_of(self, name: str) -> GroupConfig | None:
        return next((g for g in self.groups if name in g.members), None)

    def processes(self) -> list[ProcessPlan]:
        """The supervised processes in start order: a group starts where its first member is listed."""
        out: list[ProcessPlan] = []
        for node in self.nodes:
            group = self.group_of(node.name)
            if group is None:
                out.append(ProcessPlan(node.name, (node,), False, node.critical, node.restart, node.max_restarts,
                                       node.restart_window_s, node.backoff_s, node.cpu_affinity, node.nice))
            elif group.members[0] == node.name:
                out.append(merge_group(group, tuple(n for n in self.nodes if n.name in group.members)))
        return out


def merge_group(group: GroupConfig, members: tuple[NodeConfig, ...]) -> ProcessPlan:
    """One process for the group: critical if any member is; the most restarting mode of the members
    (always > on-failure > never); the strictest limit (smallest max_restarts in the longest window)
    and the longest back-off — so no member is restarted more eagerly than it asked for."""
    mode = max((m.restart for m in members), key=RESTART_MODES.index)
    return ProcessPlan(group.name, members, True, any(m.critical for m in members), mode,
                       min(m.max_restarts for m in members), max(m.restart_window_s for m in members),
                       max(m.backoff_s for m in members), group.cpu_affinity, group.nice)


def usable_cpus() -> frozenset[int]:
    """CPU ids this process (and so every node it starts) may run on."""
    return frozenset(os.sched_getaffinity(0))


def parse_cpus(value: Any, where: str, usable: frozenset[int]) -> tuple[int, ...]:
    """cpu_affinity: a non-empty list of CPU ids (a negative one counts from the end of the usable
    CPUs: -1 is the last) or "a..b" ranges of them, inclusive ("0..-2": every CPU but the last)."""
    ordered = sorted(usable)
    shown = ", ".join(map(str, ordered))

    def one(item: Any) -> int:
        if isinstance(item, bool) or not isinstance(item, int):
            raise ConfigError(f"{where}: cpu_affinity entries are CPU ids or 'a..b' ranges, not {item!r}")
        if item < 0:
            if -item > len(ordered):
                raise ConfigError(f"{where}: cpu_affinity {item}: this machine has {len(ordered)} usable CPUs ({shown})")
            return ordered[item]
        if item not in usable:
            raise ConfigError(f"{where}: cpu_affinity: CPU {item} does not exist on this machine (usable CPUs: {shown})")
        return item

    if not isinstance(value, list) or not value:
        raise ConfigError(f"{where}: cpu_affinity must be a non-empty list of CPU ids, not {value!r}")
    cpus: set[int] = set()
    for item in value:
        match = CPU_RANGE.match(item) if isinstance(item, str) else None
        if isinstance(item, str) and match is None:
            raise ConfigError(f"{where}: cpu_affinity entry {item!r} is not a CPU id or an 'a..b' range")
        if match is None:
            cpus.add(one(item))
            continue
        low, high = one(int(match.group(1))), one(int(match.group(2)))
        if low > high:
            raise ConfigError(f"{where}: cpu_affinity range {item!r} is empty on this machine (CPU {low} > CPU {high})")
        cpus.update(c for c in ordered if low <= c <= high)
    return tuple(sorted(cpus))


def parse_nice(value: Any, where: str) -> int:
    low, high = NICE_RANGE
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise ConfigError(f"{where}: nice must be an integer from {low} to {high}, not {value!r}")
    return value


def default_config_path() -> Path:
    """The installed config/sitl.yaml of c4d_bringup (the source tree's copy when not installed)."""
    return share_file("c4d_bringup", "config", "sitl.yaml")


def load_system_config(path: str | Path) -> SystemConfig:
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError(f"cannot read system config {path}: {exc.strerror or exc}") from None
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"system config {path}: {yaml_error_text(exc)}") from None
    return parse_system_config(doc, path)


def _where(path: Path) -> str:
    return f"system config {path}"


def parse_system_config(doc: Any, path: Path, cpus: frozenset[int] | None = None) -> SystemConfig:
    """Check a parsed YAML document completely and return the model (ConfigError on the first problem).
    `cpus`: the usable CPU ids cpu_affinity is checked against (default: this process's)."""
    w = _where(path)
    cpus = usable_cpus() if cpus is None else cpus
    if not isinstance(doc, dict):
        raise ConfigError(f"{w}: must be a mapping with a 'nodes' entry")
    unknown = set(doc) - TOP_KEYS
    if unknown:
        raise ConfigError(f"{w}: unknown field(s) {', '.join(sorted(map(str, unknown)))} (known: {', '.join(sorted(TOP_KEYS))})")
    platform = doc.get("platform", "sitl")
    if platform not in PLATFORMS:
        raise ConfigError(f"{w}: platform must be one of {', '.join(PLATFORMS)}, not {platform!r}")
    discovery = doc.get("discovery_range", "LOCALHOST")
    if discovery not in DISCOVERY_RANGES:
        raise ConfigError(f"{w}: discovery_range must be one of {', '.join(DISCOVERY_RANGES)}, not {discovery!r}")
    run_root = doc.get("run_root", "c4d_runs")
    if not isinstance(run_root, str) or not run_root:
        raise ConfigError(f"{w}: run_root must be a non-empty path")
    timeout = _number(doc.get("shutdown_timeout_s", 10.0), f"{w}: shutdown_timeout_s", minimum=0.5)
    spacing = _number(doc.get("restart_spacing_s", RESTART_SPACING_S), f"{w}: restart_spacing_s", minimum=0.0)
    if spacing > 60.0:
        raise ConfigError(f"{w}: restart_spacing_s must be <= 60 s, not {spacing:g}")
    nodes_doc = doc.get("nodes")
    if not isinstance(nodes_doc, dict) or not nodes_doc:
        raise ConfigError(f"{w}: 'nodes' must be a non-empty mapping of node name -> settings")
    nodes = []
    for name, entry in nodes_doc.items():
        node = _parse_node(name, entry, w, cpus)
        if node is not None:
            nodes.append(node)
    nodes = _lockstep(doc.get("lockstep", False), nodes, platform, w)
    groups = _parse_groups(doc.get("compose"), nodes_doc, {n.name: n for n in nodes}, w, cpus)
    if not nodes:
        raise ConfigError(f"{w}: every node is disabled")
    names = {n.name for n in nodes}
    if platform == "sitl" and "sim" not in names:
        raise ConfigError(f"{w}: platform sitl needs the 'sim' node (or use platform: hardware)")
    if platform == "hardware" and "sim" in names:
        raise ConfigError(f"{w}: platform hardware must not run the 'sim' node")
    config = SystemConfig(path.resolve(), platform, discovery, run_root, timeout, tuple(nodes), spacing, groups)
    try:
        return replace(config, modes=parse_modes(doc.get("modes"), config.managed(), w))
    except ModesError as exc:
        raise ConfigError(str(exc)) from None


def _lockstep(value: Any, nodes: list[NodeConfig], platform: str, w: str) -> list[NodeConfig]:
    """`lockstep: true`: the parameters that put the graph on simulated time (they win over the nodes' own)."""
    if not isinstance(value, bool):
        raise ConfigError(f"{w}: lockstep must be true or false, not {value!r}")
    if not value:
        return nodes
    if platform != "sitl":
        raise ConfigError(f"{w}: lockstep needs platform sitl (the sim drives simulated time)")
    return [replace(n, parameters={**n.parameters, **({"lockstep": True} if n.name in LOCKSTEP_NODES
                                                      else {"use_sim_time": True})}) for n in nodes]


def _parse_groups(doc: Any, nodes_doc: dict, enabled: dict[str, NodeConfig], w: str,
                  cpus: frozenset[int]) -> tuple[GroupConfig, ...]:
    if doc is None:
        return ()
    if not isinstance(doc, dict) or not doc:
        raise ConfigError(f"{w}: compose must be a mapping of group name -> list of nodes")
    groups: list[GroupConfig] = []
    owner: dict[str, str] = {}
    for name, entry in doc.items():
        if not isinstance(name, str) or not NAME.match(name):
            raise ConfigError(f"{w}: compose group name {name!r} is not a valid name")
        where = f"{w}: compose group '{name}'"
        if name in nodes_doc:
            raise ConfigError(f"{where}: a group cannot have the name of a node")
        entry = {"nodes": entry} if isinstance(entry, list) else entry
        if not isinstance(entry, dict):
            raise ConfigError(f"{where}: must be a list of nodes or a mapping with 'nodes'")
        _known_fields(entry, GROUP_KEYS, where)
        members = entry.get("nodes")
        if not isinstance(members, list) or not members or not all(isinstance(m, str) for m in members):
            raise ConfigError(f"{where}: nodes must be a non-empty list of node names")
        for member in members:
            if member not in nodes_doc:
                raise ConfigError(f"{where}: unknown node '{member}' (nodes of this config: {', '.join(map(str, nodes_doc))})")
            if member in owner:
                raise ConfigError(f"{where}: node '{member}' is already in group '{owner[member]}' (a node runs in one process)")
            owner[member] = name
            if member in OWN_PROCESS:
                raise ConfigError(f"{where}: node '{member}' cannot be composed ({OWN_PROCESS[member]} runs in its own "
                                  "process, at its own real-time priority)")
            node = enabled.get(member)
            for key in ("cpu_affinity", "nice"):
                if node is not None and getattr(node, key) is not None:
                    raise ConfigError(f"{where}: set {key} on the group, not on its member '{member}' "
                                      "(it applies to the whole process)")
        affinity, nice = _placement(entry, where, cpus)
        running = tuple(m for m in members if m in enabled)
        if running:  # a group whose members are all disabled does not run
            groups.append(GroupConfig(name, tuple(m for m in enabled if m in running), affinity, nice))
    return tuple(groups)


def _known_fields(entry: dict, known: set[str], where: str) -> None:
    unknown = set(entry) - known
    if unknown:
        raise ConfigError(f"{where}: unknown field(s) {', '.join(sorted(map(str, unknown)))} "
                          f"(known: {', '.join(sorted(known))})")


def _placement(entry: dict, where: str, cpus: frozenset[int]) -> tuple[tuple[int, ...] | None, int | None]:
    """cpu_affinity and nice of a node or group entry (None where not given)."""
    affinity = parse_cpus(entry["cpu_affinity"], where, cpus) if "cpu_affinity" in entry else None
    return affinity, parse_nice(entry["nice"], where) if "nice" in entry else None


def _parse_node(name: Any, entry: Any, w: str, cpus: frozenset[int]) -> NodeConfig | None:
    if not isinstance(name, str) or not NAME.match(name):
        raise ConfigError(f"{w}: node name {name!r} is not a valid ROS name")
    where = f"{w}: node '{name}'"
    entry = {} if entry is None else entry
    if not isinstance(entry, dict):
        raise ConfigError(f"{where}: settings must be a mapping")
    _known_fields(entry, NODE_KEYS, where)
    enabled = entry.get("enabled", True)
    if not isinstance(enabled, bool):
        raise ConfigError(f"{where}: enabled must be true or false")
    known = CATALOGUE.get(name)
    if known is None and not ("package" in entry and "executable" in entry):
        raise ConfigError(f"{w}: unknown node '{name}' (known: {', '.join(CATALOGUE)}; "
                          "any other node needs package and executable)")
    package = entry.get("package", known[0] if known else None)
    executable = entry.get("executable", known[1] if known else None)
    for key, value in (("package", package), ("executable", executable)):
        if not isinstance(value, str) or not value or "/" in value:
            raise ConfigError(f"{where}: {key} must be a plain name, not {value!r}")
    critical = entry.get("critical", known[2] if known else False)
    if not isinstance(critical, bool):
        raise ConfigError(f"{where}: critical must be true or false")
    restart = entry.get("restart", "never" if critical else "always")
    if restart not in RESTART_MODES:
        raise ConfigError(f"{where}: restart must be one of {', '.join(RESTART_MODES)}, not {restart!r}")
    max_restarts = entry.get("max_restarts", 5)
    if isinstance(max_restarts, bool) or not isinstance(max_restarts, int) or max_restarts < 0:
        raise ConfigError(f"{where}: max_restarts must be an integer >= 0")
    window = _number(entry.get("restart_window_s", 60.0), f"{where}: restart_window_s", minimum=1.0)
    backoff = _number(entry.get("backoff_s", 1.0), f"{where}: backoff_s", minimum=0.0)
    params = entry.get("parameters") or {}
    if not isinstance(params, dict):
        raise ConfigError(f"{where}: parameters must be a mapping of name -> value")
    flat: dict[str, Any] = {}
    _flatten(params, "", flat, where)
    affinity, nice = _placement(entry, where, cpus)
    if not enabled:
        return None
    return NodeConfig(name, package, executable, critical, restart, max_restarts, window, backoff, flat, affinity, nice)


def _number(value: Any, where: str, minimum: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < minimum:
        raise ConfigError(f"{where} must be a number >= {minimum:g}, not {value!r}")
    return float(value)


def _flatten(params: dict, prefix: str, out: dict[str, Any], where: str) -> None:
    for key, value in params.items():
        name = f"{prefix}{key}"
        if not isinstance(key, str) or not PARAM_NAME.match(name):
            raise ConfigError(f"{where}: parameter name {name!r} is not valid")
        if isinstance(value, dict):
            _flatten(value, name + ".", out, where)
        elif isinstance(value, list):
            if not value:
                raise ConfigError(f"{where}: parameter {name}: an empty list has no ROS parameter type")
            kinds = {_kind(v, name, where) for v in value}
            if len(kinds) > 1 and kinds != {"int", "float"}:
                raise ConfigError(f"{where}: parameter {name}: list mixes {' and '.join(sorted(kinds))} values")
            out[name] = [float(v) for v in value] if kinds == {"int", "float"} else list(value)
        else:
            _kind(value, name, where)
            out[name] = value


def _kind(value: Any, name: str, where: str) -> str:
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, int):
        return "int"
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ConfigError(f"{where}: parameter {name}: {value} is not a finite number")
        return "float"
    if isinstance(value, str):
        return "str"
    raise ConfigError(f"{where}: parameter {name}: {value!r} is not a ROS parameter value")


def substitute(value: Any, variables: Mapping[str, str], where: str = "system config") -> Any:
    """Replace ${name} in strings (recursively in lists); an unknown name is a ConfigError."""
    if isinstance(value, list):
        return [substitute(v, variables, where) for v in value]
    if not isinstance(value, str):
        return value

    def one(match: re.Match) -> str:
        if match.group(1) not in variables:
            raise ConfigError(f"{where}: unknown variable ${{{match.group(1)}}} (known: "
                              f"{', '.join('${' + k + '}' for k in sorted(variables))})")
        return variables[match.group(1)]

    return VARIABLE.sub(one, value)


def node_parameters(node: NodeConfig, variables: Mapping[str, str], config_path: Path) -> dict[str, Any]:
    """The node's parameters with ${...} substituted (ConfigError on an unknown variable)."""
    where = f"{_where(config_path)}: node '{node.name}'"
    return {k: substitute(v, variables, where) for k, v in node.parameters.items()}


def check_variables(config: SystemConfig) -> None:
    """Fail early on an unknown ${...} anywhere in the parameters."""
    dummy = {"run": "/run", "config_dir": "/config"}
    for node in config.nodes:
        node_parameters(node, dummy, config.path)


def params_document(parameters: Mapping[str, Any]) -> dict[str, Any]:
    """A ROS 2 parameters file applying `parameters` to every node of the process."""
    return {"/**": {"ros__parameters": dict(parameters)}}


def group_params_document(parameters: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
    """A ROS 2 parameters file for a composed process: each node's parameters under its own name
    (the nodes share one rclpy context, so a `/**` entry would reach all of them)."""
    return {f"/{name}": {"ros__parameters": dict(values)} for name, values in parameters.items() if values}


def variables_for(config: SystemConfig, run_dir: Path) -> dict[str, str]:
    return {"run": str(run_dir), "config_dir": str(config.path.parent)}


def resolve_executable(node: NodeConfig) -> Path:
    """<prefix>/lib/<package>/<executable> found through the ament index, as `ros2 run` does."""
    return _executable(node.name, node.package, node.executable)


CONTAINER = ("c4d_bringup", "container")  # the component container executable (lib/c4d_bringup/container)


def resolve_process(process: ProcessPlan) -> Path:
    """The executable of one supervised process: the node's own, or the container after checking
    that every member is a loadable component (its package declares a `c4d.components` entry point)."""
    if not process.composed:
        return resolve_executable(process.members[0])
    from c4d_ros.component import ComponentError, find_component

    for node in process.members:
        try:
            find_component(node.package, node.executable)
        except ComponentError as exc:
            raise ConfigError(f"compose group '{process.name}': node '{node.name}' cannot be composed: {exc}") from None
    return _executable(process.name, *CONTAINER)


def component_argv(process: ProcessPlan) -> list[str]:
    """The container's arguments for a group: its name and its members as package/executable."""
    return ["--group", process.name, *(f"{n.package}/{n.executable}" for n in process.members)]


def _executable(name: str, package: str, executable: str) -> Path:
    try:
        from ament_index_python.packages import PackageNotFoundError, get_package_prefix
    except ImportError:  # pragma: no cover - every c4d environment has ament_index_python
        raise ConfigError("ament_index_python is not importable: source env.sh first") from None
    try:
        prefix = Path(get_package_prefix(package))
    except (PackageNotFoundError, ValueError):
        raise ConfigError(f"node '{name}': unknown executable {package}/{executable} "
                          f"(package {package} is not on the ament index; source env.sh / install/setup.bash)") from None
    path = prefix / "lib" / package / executable
    if not (path.is_file() and os.access(path, os.X_OK)):
        raise ConfigError(f"node '{name}': unknown executable {package}/{executable} (no {path})")
    return path


def child_environment(config: SystemConfig, base: Mapping[str, str]) -> dict[str, str]:
    """Environment of every node: the caller's (ROS_DOMAIN_ID, test tokens, paths) with the discovery range set."""
    env = with_profile(base)  # loopback-UDP Fast DDS profile (docs/dds.md)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = base.get("C4D_DISCOVERY_RANGE") or config.discovery_range
    env.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
    env["PYTHONUNBUFFERED"] = "1"
    env.setdefault("RCUTILS_COLORIZED_OUTPUT", "0")
    return env
