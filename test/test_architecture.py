"""The package layout is the architecture: these rules fail the build when code breaks it.

- Shared packages sit at the bottom: `c4d_common` and `c4d_sched` are ROS-free (no rclpy, no
  generated interfaces, no other c4d package); `c4d_ros` may use `c4d_common` and the interfaces.
- Block packages (gnc, sim, mission, health, bridge, data) import only shared packages and
  `c4d_interfaces` — never each other: blocks meet on DDS topics and services only.
- `c4d_bringup` may import shared packages and the configuration loaders of blocks
  (`CONFIG_LOADERS`), never a node module.
- Tools (`c4d_resim`) compose blocks' ROS-free libraries offline: they may import shared packages and the
  modules of `TOOL_SOURCES` (c4d_gnc, c4d_data) except their node modules (`*_node`); nothing imports a tool.
- Client libraries (`c4d_client`) import only `c4d_interfaces` and ROS: a user's script needs nothing
  else of c4d.
- No import cycle between files of src/ (function-level imports count).
Only runtime code (src/<pkg>/<pkg>/) is checked; tests may build harnesses across blocks.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
ROS_FREE = {"c4d_common", "c4d_sched"}
SHARED = {"c4d_interfaces", "c4d_common", "c4d_ros", "c4d_sched"}
BLOCKS = {"c4d_gnc", "c4d_sim", "c4d_mission", "c4d_health", "c4d_bridge_mavlink", "c4d_data", "c4d_offboard"}
BRINGUP = "c4d_bringup"
CLIENTS = {"c4d_client"}
TOOLS = {"c4d_resim"}
TOOL_SOURCES = {"c4d_gnc", "c4d_data"}
CONFIG_LOADERS = {"c4d_sim.sim_config", "c4d_gnc.core_config", "c4d_gnc.live_gains", "c4d_gnc.live_navigation",
                  "c4d_health.live_policy", "c4d_health.policy"}
ROS_CLIENT = {"rclpy", "rosidl_runtime_py", "builtin_interfaces", "c4d_interfaces", "std_msgs", "sensor_msgs"}
PACKAGES = sorted(p.parent.name for p in SRC.glob("*/setup.py"))


def module_name(path: Path) -> str:
    rel = path.relative_to(SRC).with_suffix("")
    parts = list(rel.parts[1:])  # drop the package folder (src/<pkg>/<pkg>/x.py)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imports_of(path: Path) -> list[tuple[int, str]]:
    """Absolute module names imported by `path` (relative imports resolved), with line numbers."""
    module = module_name(path)
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            found.append((node.lineno, target))
            found += [(node.lineno, f"{target}.{alias.name}") for alias in node.names]
    return found


def runtime_files(package: str) -> list[Path]:
    return sorted((SRC / package / package).rglob("*.py"))


def violations(package: str, files: list[Path] | None = None) -> list[str]:
    out = []
    for path in files if files is not None else runtime_files(package):
        for line, name in imports_of(path):
            top = name.split(".")[0]
            where = f"{path.name}:{line} imports {name}"
            if top == package or not top.startswith("c4d_") and top not in ROS_CLIENT:
                continue
            if package in ROS_FREE and (top in ROS_CLIENT or top.startswith("c4d_")):
                out.append(f"{where}: {package} is ROS-free and depends on no other c4d package")
            elif package == "c4d_ros" and top.startswith("c4d_") and top not in {"c4d_common", "c4d_interfaces"}:
                out.append(f"{where}: c4d_ros may use only c4d_common and c4d_interfaces")
            elif package in CLIENTS and top != "c4d_interfaces" and top.startswith("c4d_"):
                out.append(f"{where}: client libraries import only c4d_interfaces and ROS")
            elif top in TOOLS:
                out.append(f"{where}: nothing imports a tool package")
            elif package in TOOLS and top in BLOCKS and (top not in TOOL_SOURCES or name.split(".")[1:2] and
                                                         name.split(".")[1].endswith("_node")):
                out.append(f"{where}: tools import only the ROS-free modules of {sorted(TOOL_SOURCES)}, never a node")
            elif package in BLOCKS and top in BLOCKS:
                out.append(f"{where}: block packages never import each other (meet on DDS)")
            elif package == BRINGUP and top in BLOCKS and not any(name == m or name.startswith(m + ".")
                                                                   for m in CONFIG_LOADERS):
                out.append(f"{where}: c4d_bringup may import only configuration loaders of blocks {sorted(CONFIG_LOADERS)}")
    return out


@pytest.mark.parametrize("package", PACKAGES)
def test_package_imports_follow_the_layering(package: str) -> None:
    problems = violations(package)
    assert not problems, "\n".join(problems)


def test_every_python_package_has_a_layer() -> None:
    layers = SHARED | BLOCKS | CLIENTS | TOOLS | {BRINGUP}
    assert set(PACKAGES) <= layers, f"unclassified package(s): {set(PACKAGES) - layers}"


def test_no_import_cycle_between_files() -> None:
    modules: dict[str, Path] = {}
    for package in PACKAGES:
        for path in runtime_files(package):
            modules[f"{module_name(path)}"] = path
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        deps = set()
        for _, target in imports_of(path):
            while target and target not in modules:
                target = target.rpartition(".")[0]
            if target and target != name and not name.startswith(target + ".") and target in modules:
                deps.add(target)
        graph[name] = deps
    cycles = strongly_connected(graph)
    assert not cycles, "import cycles between files: " + "; ".join(" <-> ".join(sorted(c)) for c in cycles)


def strongly_connected(graph: dict[str, set[str]]) -> list[set[str]]:
    """Tarjan's algorithm; returns the components with more than one file."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[set[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(component)

    for v in graph:
        if v not in index:
            visit(v)
    return found


def test_the_checker_sees_a_cross_block_import(tmp_path: Path) -> None:
    """The rules are not vacuous: a planted violation and a planted cycle are found."""
    assert strongly_connected({"a": {"b"}, "b": {"a"}, "c": set()}) == [{"a", "b"}]
    planted = tmp_path / "c4d_health" / "c4d_health" / "planted.py"
    planted.parent.mkdir(parents=True)
    planted.write_text("from c4d_mission.executor import MissionExecutor\nimport rclpy\n")
    global SRC
    saved, SRC = SRC, tmp_path
    try:
        assert any("never import each other" in v for v in violations("c4d_health", [planted]))
        assert any("ROS-free" in v for v in violations("c4d_common", [planted]))
        client = tmp_path / "c4d_client" / "c4d_client" / "planted.py"
        client.parent.mkdir(parents=True)
        client.write_text("import rclpy\nfrom c4d_interfaces.msg import VehicleStatus\nfrom c4d_ros.manifest import STATUS\n")
        assert [v.split(": ", 1)[1] for v in violations("c4d_client", [client])] == \
            ["client libraries import only c4d_interfaces and ROS"] * 2  # `from c4d_ros.manifest import STATUS` = 2 names
        tool = tmp_path / "c4d_resim" / "c4d_resim" / "planted.py"
        tool.parent.mkdir(parents=True)
        tool.write_text("from c4d_gnc.navigation_node import PARAMS\nfrom c4d_mission.executor import MissionExecutor\n"
                        "from c4d_gnc.ekf import NavigationEkf\n")
        assert len([v for v in violations("c4d_resim", [tool]) if "tools import only" in v]) == 4  # 2 names each
        assert any("nothing imports a tool" in v for v in violations("c4d_data", [
            _planted(tmp_path, "c4d_data", "from c4d_resim.run import resimulate\n")]))
    finally:
        SRC = saved


def _planted(root: Path, package: str, text: str) -> Path:
    path = root / package / package / "planted2.py"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path
