"""Bring-up configuration: the system YAML model and its validation, the CLI's one-line errors
before anything starts, the launch file's plan (same graph as `c4d up`), executables resolving
where `ros2 run` looks."""

from __future__ import annotations

import ast
import subprocess
from pathlib import Path

import pytest
import yaml
from c4d_testing import installed_executable

from c4d_bringup.graph import prepare_run, resolve_all
from c4d_bringup.launch_plan import launch_plan
from c4d_bringup.system_config import (
    CATALOGUE,
    ConfigError,
    child_environment,
    default_config_path,
    load_system_config,
    parse_system_config,
    substitute,
)

ROOT = Path(__file__).resolve().parent.parent
SITL = ROOT / "src" / "c4d_bringup" / "config" / "sitl.yaml"


def parse(doc) -> object:
    return parse_system_config(doc, Path("/cfg/system.yaml"))


def error_of(doc) -> str:
    with pytest.raises(ConfigError) as info:
        parse(doc)
    message = str(info.value)
    assert "\n" not in message
    return message


def test_bundled_sitl_config_is_the_whole_graph():
    config = load_system_config(SITL)
    assert default_config_path().read_text() == SITL.read_text()  # the installed copy is this one
    assert config.names == ["sim", "perception", "navigation", "core", "mission", "payload", "health", "bridge", "offboard",
                            "recorder"]
    assert [n.name for n in config.nodes if n.critical] == ["sim", "perception", "navigation", "core"]
    assert all(n.restart == "always" for n in config.nodes if not n.critical)
    # the flight-critical chain is real-time (docs/dds.md); live gain changes persist per vehicle (docs/parameters.md)
    assert config.node("core").parameters == {"rt_priority": 60, "vehicle": "sitl"}
    assert [config.node(n).parameters["rt_priority"] for n in ("sim", "perception", "navigation")] == [55, 52, 51]
    assert config.platform == "sitl" and config.discovery_range == "LOCALHOST" and config.restart_spacing_s == 2.0
    # every node's executable resolves exactly where `ros2 run <pkg> <exe>` looks
    for name, path in resolve_all(config).items():
        node = config.node(name)
        assert str(path) == installed_executable(node.package, node.executable)


def test_defaults_flattening_and_substitution():
    config = parse({"nodes": {"sim": {"parameters": {"fault": {"gps_loss": True, "gps_drift_m_s": [0, 0.5, 0]}}},
                              "payload": {"parameters": {"output_dir": "${run}/captures"}},
                              "mine": {"package": "c4d_sim", "executable": "sim", "critical": True}}})
    sim, payload, mine = config.nodes
    assert (sim.package, sim.executable, sim.critical, sim.restart) == ("c4d_sim", "sim", True, "never")
    assert sim.parameters == {"fault.gps_loss": True, "fault.gps_drift_m_s": [0.0, 0.5, 0.0]}
    assert (payload.critical, payload.restart, payload.max_restarts, payload.backoff_s) == (False, "always", 5, 1.0)
    assert mine.package == "c4d_sim" and mine.critical
    assert substitute("${run}/captures", {"run": "/r"}) == "/r/captures"
    assert substitute(["${config_dir}/a", 3], {"config_dir": "/c"}) == ["/c/a", 3]
    disabled = parse({"nodes": {"sim": {}, "bridge": {"enabled": False}}})
    assert disabled.names == ["sim"] and disabled.restart_spacing_s == 2.0  # the default
    assert parse({"restart_spacing_s": 0, "nodes": {"sim": {}}}).restart_spacing_s == 0.0  # no stagger


def test_lockstep_puts_the_graph_on_simulated_time():
    doc = {"lockstep": True, "nodes": {"sim": {}, "core": {"parameters": {"lockstep": False, "rt_priority": 60}},
                                       "mission": {}}}
    config = parse(doc)
    assert config.node("sim").parameters == {"lockstep": True}
    assert config.node("core").parameters == {"lockstep": True, "rt_priority": 60}  # the top-level switch wins
    assert config.node("mission").parameters == {"use_sim_time": True}
    assert parse({**doc, "lockstep": False}).node("core").parameters == {"lockstep": False, "rt_priority": 60}


def test_child_environment_forces_discovery_range_and_keeps_domain():
    config = parse({"nodes": {"sim": {}}})
    env = child_environment(config, {"ROS_DOMAIN_ID": "42", "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET", "X": "1"})
    assert env["ROS_DOMAIN_ID"] == "42" and env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST" and env["X"] == "1"
    assert child_environment(config, {"C4D_DISCOVERY_RANGE": "SUBNET"})["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SUBNET"


@pytest.mark.parametrize("doc, expected", [
    ([1, 2], "must be a mapping"),
    ({"nodes": {"sim": {}}, "nodez": {}}, "unknown field(s) nodez"),
    ({"nodes": {}}, "'nodes' must be a non-empty mapping"),
    ({"nodes": {"navigaton": {}}}, "unknown node 'navigaton' (known: sim, perception"),
    ({"nodes": {"sim": {"critcal": True}}}, "node 'sim': unknown field(s) critcal"),
    ({"nodes": {"sim": {"restart": "sometimes"}}}, "restart must be one of never, on-failure, always"),
    ({"nodes": {"sim": {"max_restarts": -1}}}, "max_restarts must be an integer >= 0"),
    ({"nodes": {"sim": {"backoff_s": "soon"}}}, "backoff_s must be a number >= 0"),
    ({"nodes": {"sim": {"parameters": {"a": []}}}}, "parameter a: an empty list has no ROS parameter type"),
    ({"nodes": {"sim": {"parameters": {"a": [1, "x"]}}}}, "parameter a: list mixes int and str values"),
    ({"nodes": {"sim": {"parameters": {"a": None}}}}, "parameter a: None is not a ROS parameter value"),
    ({"nodes": {"sim": {"parameters": {"bad-name": 1}}}}, "parameter name 'bad-name' is not valid"),
    ({"nodes": {"sim": {"package": "a/b"}}}, "package must be a plain name"),
    ({"platform": "mars", "nodes": {"sim": {}}}, "platform must be one of sitl, hardware"),
    ({"nodes": {"core": {}}}, "platform sitl needs the 'sim' node"),
    ({"platform": "hardware", "nodes": {"sim": {}}}, "platform hardware must not run the 'sim' node"),
    ({"discovery_range": "WORLD", "nodes": {"sim": {}}}, "discovery_range must be one of"),
    ({"shutdown_timeout_s": 0, "nodes": {"sim": {}}}, "shutdown_timeout_s must be a number >= 0.5"),
    ({"nodes": {"sim": {"enabled": False}}}, "every node is disabled"),
    ({"restart_spacing_s": -1, "nodes": {"sim": {}}}, "restart_spacing_s must be a number >= 0"),
    ({"restart_spacing_s": 61, "nodes": {"sim": {}}}, "restart_spacing_s must be <= 60 s"),
    ({"lockstep": "yes", "nodes": {"sim": {}}}, "lockstep must be true or false, not 'yes'"),
    ({"lockstep": True, "platform": "hardware", "nodes": {"core": {}}}, "lockstep needs platform sitl"),
])
def test_bad_configs_are_one_line_errors(doc, expected):
    assert expected in error_of(doc)


def test_unknown_variable_and_unknown_executable(tmp_path):
    from c4d_bringup.system_config import check_variables

    with pytest.raises(ConfigError, match=r"unknown variable \$\{runn\}"):
        check_variables(parse({"nodes": {"sim": {"parameters": {"config": "${runn}/x"}}}}))
    config = parse({"nodes": {"sim": {}, "ghost": {"package": "c4d_sim", "executable": "ghost"}}})
    with pytest.raises(ConfigError, match=r"node 'ghost': unknown executable c4d_sim/ghost \(no .*lib/c4d_sim/ghost\)"):
        resolve_all(config)
    config = parse({"nodes": {"sim": {}, "ghost": {"package": "c4d_nowhere", "executable": "x"}}})
    with pytest.raises(ConfigError, match="unknown executable c4d_nowhere/x .package c4d_nowhere is not on the ament index"):
        resolve_all(config)


def test_prepare_run_writes_ros_parameter_files(tmp_path):
    config = parse({"nodes": {"sim": {"parameters": {"fault": {"gps_loss": False}}}, "core": {"parameters": {"rt_priority": 0}},
                              "payload": {"parameters": {"output_dir": "${run}/captures"}}, "health": {}}})
    specs = prepare_run(config, tmp_path / "run")
    assert [s.name for s in specs] == ["sim", "core", "payload", "health"]
    payload = next(s for s in specs if s.name == "payload")
    assert payload.argv[0] == installed_executable("c4d_mission", "payload")
    assert payload.argv[1:3] == ("--ros-args", "--params-file")
    assert yaml.safe_load(Path(payload.argv[3]).read_text()) == \
        {"/**": {"ros__parameters": {"output_dir": str(tmp_path / "run" / "captures"), "autostart": False}}}
    assert yaml.safe_load((tmp_path / "run" / "params" / "sim.yaml").read_text())["/**"]["ros__parameters"] == \
        {"fault.gps_loss": False, "autostart": False}  # managed nodes: c4d up's lifecycle manager drives them
    health = next(s for s in specs if s.name == "health")
    assert health.argv[0] == installed_executable("c4d_health", "health") and health.log_path == tmp_path / "run/logs/health.log"
    assert (payload.restart.mode, payload.critical, specs[0].critical) == ("always", False, True)


def test_bridge_parameters_persist_per_run_not_per_user(tmp_path):
    """Issue 14 item 15: one per-user parameter file let one GCS's SYSID_THISMAV change every later
    vehicle of that account. Each run's bridge now has its own file in the run directory."""
    from c4d_bridge_mavlink.bridge_node import PARAMETERS

    assert PARAMETERS["param_file"].default == ""  # standalone: nothing shared, nothing persisted
    files = []
    for run in ("run_a", "run_b"):
        specs = prepare_run(load_system_config(SITL), tmp_path / run)
        bridge = next(s for s in specs if s.name == "bridge")
        files.append(yaml.safe_load(Path(bridge.argv[3]).read_text())["/**"]["ros__parameters"]["param_file"])
    assert files == [str(tmp_path / "run_a/bridge/params.yaml"), str(tmp_path / "run_b/bridge/params.yaml")]
    container = ROOT / "docker" / "sitl.container.yaml"
    assert load_system_config(container).node("bridge").parameters["param_file"] == "${run}/bridge/params.yaml"


def test_launch_plan_is_the_same_graph_as_c4d_up(tmp_path):
    plan = launch_plan(str(SITL), str(tmp_path / "run"))
    specs = prepare_run(load_system_config(SITL), tmp_path / "run2")
    assert [(e.package, e.executable) for e in plan.entries] == [CATALOGUE[s.name][:2] for s in specs]
    for entry, spec in zip(plan.entries, specs, strict=True):
        written = yaml.safe_load(Path(spec.argv[3]).read_text())["/**"]["ros__parameters"] if len(spec.argv) > 1 else {}
        assert written.pop("autostart") is False  # c4d up's lifecycle manager drives them; ros2 launch: autostart
        assert {k: str(v).replace("run2", "run") for k, v in written.items()} == \
               {k: str(v) for k, v in entry.parameters.items()}
        assert entry.respawn == (spec.restart.mode != "never") and entry.critical == spec.critical
    assert plan.discovery_range == "LOCALHOST"


def test_launch_file():
    path = ROOT / "src" / "c4d_bringup" / "launch" / "sitl.launch.py"
    installed = Path(installed_executable("c4d_bringup", "c4d")).parents[2] / "share" / "c4d_bringup" / "launch" / path.name
    assert installed.resolve() == path.resolve()  # installed where `ros2 launch c4d_bringup sitl.launch.py` looks
    tree = ast.parse(path.read_text())
    functions = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
    assert "generate_launch_description" in functions
    try:
        from launch import LaunchDescription
    except ImportError:  # (src/c4d_bringup/launch/ alone imports as an empty namespace package)
        pytest.skip("the ROS 2 `launch` package is not on PyPI: generate_launch_description() runs on standard installs only")
    import importlib.util

    spec = importlib.util.spec_from_file_location("sitl_launch", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert isinstance(module.generate_launch_description(), LaunchDescription)


# ---------------------------------------------------------------- CLI: bad input, before anything starts
def run_c4d(*args: str, cwd: Path, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([installed_executable("c4d_bringup", "c4d"), *args], capture_output=True, text=True, cwd=cwd,
                          timeout=60, env=env)


BAD_SYSTEM = {
    "bad_yaml.yaml": ("nodes:\n  sim: {critical: true\n", "malformed YAML at line"),
    "unknown_node.yaml": ("nodes: {sim: {}, navigaton: {}}\n", "unknown node 'navigaton'"),
    "unknown_exe.yaml": ("nodes: {sim: {}, ghost: {package: c4d_gnc, executable: ghost}}\n",
                         "node 'ghost': unknown executable c4d_gnc/ghost"),
    "bad_var.yaml": ("nodes: {sim: {}, payload: {parameters: {output_dir: '${rundir}/c'}}}\n", "unknown variable ${rundir}"),
}


@pytest.mark.parametrize("args, expected", [
    ((), "the following arguments are required"),
    (("takeoff",), "invalid choice: 'takeoff'"),
    (("fly",), "the following arguments are required: --mission"),
    (("up", "--config", "missing.yaml"), "cannot read system config missing.yaml: No such file or directory"),
    (("up", "--config", "bad_yaml.yaml"), "malformed YAML at line"),
    (("up", "--config", "unknown_node.yaml"), "unknown node 'navigaton'"),
    (("up", "--config", "unknown_exe.yaml"), "node 'ghost': unknown executable c4d_gnc/ghost"),
    (("up", "--config", "bad_var.yaml"), "unknown variable ${rundir}"),
    (("status", "--config", "unknown_node.yaml"), "unknown node 'navigaton'"),
    (("fly", "--mission", "nowhere.yaml"), "mission nowhere.yaml: cannot read"),
    (("fly", "--mission", "bad_plan.yaml"), "mission bad_plan.yaml: "),
    (("fly", "--mission", "outside.yaml"), "item 5: outside the geofence polygon"),
    (("fly", "--mission", str(ROOT / "missions" / "hop.yaml"), "--timeout", "-3"), "--timeout must be a positive number"),
])
def test_cli_bad_input_is_one_line_before_anything_starts(tmp_path, args, expected):
    for name, (text, _) in BAD_SYSTEM.items():
        (tmp_path / name).write_text(text)
    (tmp_path / "bad_plan.yaml").write_text("name: x\nitems:\n  - {type: teleport}\n")
    survey = (ROOT / "missions" / "survey.yaml").read_text()
    (tmp_path / "outside.yaml").write_text(survey.replace("east: 20, north: 20", "east: 300, north: 20"))
    done = run_c4d(*args, cwd=tmp_path)
    assert done.returncode == 2, (done.stdout, done.stderr)
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("c4d: error: ") and expected in lines[0], done.stderr
    assert done.stdout == ""
    assert not (tmp_path / "c4d_runs").exists()  # no run directory: nothing was started


def test_cli_help_and_wrapper(tmp_path):
    done = subprocess.run([str(ROOT / "c4d"), "--help"], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and "{up,fly,status,param,resim}" in done.stdout
    for command in ("up", "fly", "status"):
        done = run_c4d(command, "--help", cwd=tmp_path)
        assert done.returncode == 0 and "--config" in done.stdout


# ---------------------------------------------------------------- deployment: composition, CPU affinity, nice (issue 16)
BOARD = ROOT / "src" / "c4d_bringup" / "config" / "board.yaml"
FOUR = frozenset({0, 1, 2, 3})


def parse_on(doc, cpus=FOUR) -> object:
    return parse_system_config(doc, Path("/cfg/system.yaml"), cpus=cpus)


def test_cpu_affinity_ids_negative_ids_and_ranges():
    sim = parse_on({"nodes": {"sim": {"cpu_affinity": ["0..-2"], "nice": 5}, "core": {"cpu_affinity": [-1]}}}).nodes
    assert (sim[0].cpu_affinity, sim[0].nice, sim[1].cpu_affinity, sim[1].nice) == ((0, 1, 2), 5, (3,), None)
    two = parse_on({"nodes": {"sim": {"cpu_affinity": ["0..-2"]}, "core": {"cpu_affinity": [-1]}}}, frozenset({0, 1}))
    assert [n.cpu_affinity for n in two.nodes] == [(0,), (1,)]  # the same file on a 2-CPU machine
    cgroup = parse_on({"nodes": {"sim": {"cpu_affinity": [-1, 2]}}}, frozenset({2, 5}))  # a cpuset-restricted container
    assert cgroup.nodes[0].cpu_affinity == (2, 5)


@pytest.mark.parametrize("doc, expected", [
    ({"nodes": {"sim": {"cpu_affinity": [4]}}}, "cpu_affinity: CPU 4 does not exist on this machine (usable CPUs: 0, 1, 2, 3)"),
    ({"nodes": {"sim": {"cpu_affinity": [-5]}}}, "cpu_affinity -5: this machine has 4 usable CPUs"),
    ({"nodes": {"sim": {"cpu_affinity": []}}}, "cpu_affinity must be a non-empty list of CPU ids"),
    ({"nodes": {"sim": {"cpu_affinity": ["1-3"]}}}, "cpu_affinity entry '1-3' is not a CPU id or an 'a..b' range"),
    ({"nodes": {"sim": {"cpu_affinity": ["3..1"]}}}, "range '3..1' is empty on this machine"),
    ({"nodes": {"sim": {"cpu_affinity": [True]}}}, "cpu_affinity entries are CPU ids"),
    ({"nodes": {"sim": {"nice": 20}}}, "nice must be an integer from -20 to 19, not 20"),
    ({"nodes": {"sim": {"nice": "low"}}}, "nice must be an integer from -20 to 19"),
    ({"compose": {"g": ["perception", "ghost"]}, "nodes": {"sim": {}, "perception": {}}},
     "compose group 'g': unknown node 'ghost' (nodes of this config: sim, perception)"),
    ({"compose": {"a": ["perception"], "b": ["perception"]}, "nodes": {"sim": {}, "perception": {}}},
     "compose group 'b': node 'perception' is already in group 'a'"),
    ({"compose": {"g": ["perception", "core"]}, "nodes": {"sim": {}, "perception": {}, "core": {}}},
     "compose group 'g': node 'core' cannot be composed (the cyclic executive runs in its own process"),
    ({"compose": {"g": ["sim"]}, "nodes": {"sim": {}}}, "node 'sim' cannot be composed"),
    ({"compose": {"g": {"nodes": ["mission"], "cpu_affinity": [9]}}, "nodes": {"sim": {}, "mission": {}}},
     "compose group 'g': cpu_affinity: CPU 9 does not exist"),
    ({"compose": {"g": {"nodes": ["mission"], "nicety": 1}}, "nodes": {"sim": {}, "mission": {}}},
     "compose group 'g': unknown field(s) nicety"),
    ({"compose": {"g": ["mission"]}, "nodes": {"sim": {}, "mission": {"nice": 3}}},
     "compose group 'g': set nice on the group, not on its member 'mission'"),
    ({"compose": {"mission": ["mission"]}, "nodes": {"sim": {}, "mission": {}}}, "a group cannot have the name of a node"),
    ({"compose": {"g": []}, "nodes": {"sim": {}}}, "nodes must be a non-empty list of node names"),
    ({"compose": ["mission"], "nodes": {"sim": {}}}, "compose must be a mapping of group name -> list of nodes"),
])
def test_deployment_errors_are_one_line(doc, expected):
    with pytest.raises(ConfigError) as info:
        parse_on(doc)
    assert expected in str(info.value) and "\n" not in str(info.value), str(info.value)


def test_group_merge_and_process_order():
    config = parse_on({"compose": {"ground": {"nodes": ["health", "mission"], "nice": 5, "cpu_affinity": [0]},
                                   "sensing": ["perception", "navigation"]},
                       "nodes": {"sim": {}, "perception": {}, "navigation": {"backoff_s": 3.0}, "core": {},
                                 "mission": {"max_restarts": 2, "restart_window_s": 30},
                                 "health": {"restart": "on-failure", "restart_window_s": 90, "backoff_s": 0.5},
                                 "payload": {"enabled": False}}})
    procs = config.processes()
    assert [p.name for p in procs] == ["sim", "sensing", "core", "ground"]  # a group starts where its first member is
    sensing, ground = procs[1], procs[3]
    assert [n.name for n in ground.members] == ["mission", "health"]  # in the nodes' order
    assert (sensing.composed, sensing.critical, sensing.restart, sensing.backoff_s) == (True, True, "never", 3.0)
    assert (ground.critical, ground.restart, ground.max_restarts, ground.restart_window_s, ground.backoff_s) == \
        (False, "always", 2, 90.0, 1.0)  # most restarting mode, strictest limit, longest window and back-off
    assert (ground.cpu_affinity, ground.nice, procs[0].composed) == ((0,), 5, False)
    mixed = parse_on({"compose": {"g": ["perception", "payload"]}, "nodes": {"sim": {}, "perception": {}, "payload": {}}})
    assert mixed.processes()[1].critical and mixed.processes()[1].restart == "always"  # critical if any member is
    assert parse_on({"compose": {"g": ["payload"]}, "nodes": {"sim": {}, "payload": {"enabled": False}}}).groups == ()


def test_board_config_prepares_composed_processes(tmp_path):
    config = load_system_config(BOARD)
    assert config.names == load_system_config(SITL).names  # the same nodes as sitl.yaml ...
    for name in config.names:  # ... with the same parameters
        assert config.node(name).parameters == load_system_config(SITL).node(name).parameters, name
    specs = prepare_run(config, tmp_path / "run")
    assert [(s.name, s.members) for s in specs] == [
        ("sim", ()), ("sensing", ("perception", "navigation")), ("core", ()),
        ("ground", ("mission", "payload", "health", "bridge", "offboard", "recorder"))]
    cpus = sorted(__import__("os").sched_getaffinity(0))
    by_name = {s.name: s for s in specs}
    assert by_name["core"].placement.cpu_affinity == (cpus[-1],)  # alone on the last CPU
    assert all(by_name[n].placement.cpu_affinity == tuple(cpus[:-1] or cpus) for n in ("sim", "sensing", "ground"))
    assert by_name["ground"].placement.nice == 5 and not by_name["ground"].critical
    assert by_name["sensing"].critical and by_name["sensing"].restart.mode == "never"
    ground = by_name["ground"]
    assert ground.argv[0] == installed_executable("c4d_bringup", "container")
    assert ground.argv[1:10] == ("--group", "ground", "c4d_mission/mission", "c4d_mission/payload", "c4d_health/health",
                                 "c4d_bridge_mavlink/bridge", "c4d_offboard/offboard", "c4d_data/recorder", "--ros-args")
    params = yaml.safe_load(Path(ground.argv[-1]).read_text())  # keyed by node: one rclpy context, six nodes
    # every managed node is driven by c4d up's lifecycle manager (autostart false); health persists its thresholds
    assert set(params) == {"/mission", "/payload", "/health", "/bridge", "/offboard", "/recorder"}
    assert all(p["ros__parameters"].get("autostart") is False for p in params.values()), params
    assert params["/recorder"]["ros__parameters"] == {"output_dir": str(tmp_path / "run" / "flights"), "autostart": False}
    with pytest.raises(ConfigError, match="compose .process composition. is supported by c4d up / c4d fly only"):
        launch_plan(str(BOARD), str(tmp_path / "run2"))


def test_container_bad_input_is_one_line(tmp_path):
    container = installed_executable("c4d_bringup", "container")
    for args, expected in (((), "container: error: the following arguments are required"),
                           (("c4d_gnc/core",), "container: error: c4d_gnc declares no component 'core'"),
                           (("c4d_nowhere/x",), "container: error: no Python package c4d_nowhere installed"),
                           (("perception",), "container: error: 'perception' is not PACKAGE/EXECUTABLE")):
        done = subprocess.run([container, *args], capture_output=True, text=True, timeout=60, cwd=tmp_path)
        assert done.returncode == 2 and done.stderr.strip().splitlines() == [done.stderr.strip()], done.stderr
        assert done.stderr.startswith(expected), done.stderr
    (tmp_path / "sys.yaml").write_text("compose: {g: [mission, core]}\nnodes: {sim: {}, core: {}, mission: {}}\n")
    done = run_c4d("up", "--config", "sys.yaml", cwd=tmp_path)
    assert done.returncode == 2 and "node 'core' cannot be composed" in done.stderr and not (tmp_path / "c4d_runs").exists()


def test_placement_is_applied_to_the_child(tmp_path):
    """A real child through the supervisor: its CPU set and niceness as configured; a niceness
    below the supervisor's own that may not be set is a logged fallback, not a failure."""
    import os
    import sys

    from c4d_bringup.supervisor import Placement, ProcessSpec, Supervisor

    cpu = max(os.sched_getaffinity(0))
    lines: list[str] = []
    child = ProcessSpec("child", (sys.executable, "-c", "import time; time.sleep(30)"), tmp_path / "child.log",
                        placement=Placement((cpu,), 7))
    sup = Supervisor([child], {}, log=lines.append)
    sup.start()
    try:
        pid = sup.pid("child")
        assert os.sched_getaffinity(pid) == {cpu} and os.getpriority(os.PRIO_PROCESS, pid) == 7
        assert lines == [f"child: started (pid {pid}, CPUs {cpu}, nice 7)"]
    finally:
        sup.stop(5.0)
    assert Placement(None, os.getpriority(os.PRIO_PROCESS, 0) + 1).nice_refusal() is None  # raising is always allowed


SCRIPT_WITHOUT_PRIVILEGES = """
import os, sys
from pathlib import Path
from c4d_bringup.supervisor import Placement, ProcessSpec, Supervisor
from c4d_ros import node_runtime
lines = []
child = (sys.executable, "-c", "import time; time.sleep(30)")
sup = Supervisor([ProcessSpec("g", child, Path(sys.argv[1]), placement=Placement(None, -5))], {}, log=lines.append)
sup.start()
lines.append(f"child nice {os.getpriority(os.PRIO_PROCESS, sup.pid('g'))}")
sup.stop(5.0)
class Log:
    def info(self, text): lines.append("info " + text)
    def warning(self, text): lines.append("warning " + text)
node_runtime.apply_rt_priority(10, Log())
lines.append(str(node_runtime.lock_memory()))
print("\\n".join(lines))
"""


def test_not_permitted_is_a_logged_fallback(tmp_path):
    """Without CAP_SYS_NICE / CAP_IPC_LOCK (dropped from the bounding set, default rlimits): a
    negative nice, SCHED_FIFO and mlockall are each refused with the reason in the log, the child
    still runs (at the inherited niceness)."""
    import shutil
    import sys

    if shutil.which("setpriv") is None:
        pytest.skip("setpriv (util-linux) is not installed")
    done = subprocess.run(["setpriv", "--bounding-set=-sys_nice,-ipc_lock", sys.executable, "-c", SCRIPT_WITHOUT_PRIVILEGES,
                           str(tmp_path / "g.log")], capture_output=True, text=True, timeout=60)
    import resource

    lines = done.stdout.splitlines()
    assert done.returncode == 0, done.stderr
    assert lines[0].startswith("g: nice -5 not permitted (below the current 0: needs CAP_SYS_NICE or RLIMIT_NICE >= 25")
    assert lines[1].startswith("g: started (pid") and "nice -5" in lines[1]
    assert "child nice 0" in lines
    assert any(line.startswith("warning real-time: rt_priority 10 not applied (") for line in lines), lines
    if resource.getrlimit(resource.RLIMIT_MEMLOCK)[0] != resource.RLIM_INFINITY:
        assert lines[-1].startswith("memory not locked: RLIMIT_MEMLOCK"), lines
