"""Deployment files without a Docker engine (none on the CI machines): the compose file and the
Dockerfile reference files that exist, cover every package and expose the bridge's MAVLink port;
the container's system config is the bundled one but for the bridge endpoint. Example missions
parse and pass the mission validation against the simulated home."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import pytest
import yaml

from c4d_bringup.system_config import load_system_config
from c4d_common.geodesy import GeoOrigin
from c4d_common.plan_files import load_plan
from c4d_common.plan_validation import validate

ROOT = Path(__file__).resolve().parent.parent
DOCKER = ROOT / "docker"
SITL_HOME = GeoOrigin(43.5629, 1.4815, 146.0)  # c4d_sim/config/sim.yaml start


def dockerfile_instructions() -> list[tuple[str, str]]:
    text = re.sub(r"\\\n", " ", (DOCKER / "Dockerfile").read_text())
    return [(m.group(1).upper(), m.group(2).strip()) for m in re.finditer(r"^([A-Za-z]+)\s+(.*)$", text, re.M)
            if not m.group(0).startswith("#")]


def test_dockerfile_base_copies_and_entrypoint():
    instructions = dockerfile_instructions()
    assert instructions[0] == ("FROM", "ros:jazzy")  # official multi-arch (amd64, arm64) ROS 2 Jazzy image
    copies = [args.split() for op, args in instructions if op == "COPY"]
    for *sources, _dest in copies:
        for source in sources:
            assert (ROOT / source).exists(), f"COPY {source}: no such file in the repository"
    copied_manifests = {s for *sources, _ in copies for s in sources if s.endswith("package.xml")}
    manifests = {str(p.relative_to(ROOT)) for p in (ROOT / "src").glob("*/package.xml")}
    assert copied_manifests == manifests, "every package's package.xml must reach rosdep (update the Dockerfile)"
    run = " ".join(args for op, args in instructions if op == "RUN")
    assert "rosdep install" in run and "./setup.sh --no-check" in run
    entrypoint = dict(instructions)["ENTRYPOINT"]
    assert entrypoint == '["/usr/local/bin/c4d-entrypoint"]'
    assert ["docker/entrypoint.sh", "/usr/local/bin/c4d-entrypoint"] in copies
    assert (DOCKER / "entrypoint.sh").stat().st_mode & 0o111
    assert dict(instructions)["EXPOSE"] == "14550/udp" and dict(instructions)["STOPSIGNAL"] == "SIGINT"
    cmd = yaml.safe_load(dict(instructions)["CMD"])
    assert cmd[:2] == ["c4d", "up"] and (ROOT / cmd[3].removeprefix("/c4d/")).is_file()
    ignore = (DOCKER / "Dockerfile.dockerignore").read_text().split()
    assert {".venv", "build", "install", "log", ".git"} <= set(ignore)


def test_compose_exposes_mavlink_and_runs_the_container_config():
    compose = yaml.safe_load((DOCKER / "compose.sitl.yaml").read_text())
    service = compose["services"]["sitl"]
    context = (DOCKER / service["build"]["context"]).resolve()
    assert context == ROOT and (context / service["build"]["dockerfile"]).resolve() == DOCKER / "Dockerfile"
    assert "14550:14550/udp" in service["ports"] and service["stop_signal"] == "SIGINT"
    config_path = service["command"][service["command"].index("--config") + 1]
    container = load_system_config(ROOT / config_path.removeprefix("/c4d/"))
    bundled = load_system_config(ROOT / "src" / "c4d_bringup" / "config" / "sitl.yaml")
    # the same graph; only the bridge listens on every interface so the published port reaches it
    assert container.node("bridge").parameters["endpoints"] == ["udpin:0.0.0.0:14550"]
    assert bundled.node("bridge").parameters["endpoints"] == ["udpin:127.0.0.1:14550"]

    def without_endpoints(nodes):
        return [replace(n, parameters={k: v for k, v in n.parameters.items() if k != "endpoints"}) for n in nodes]

    assert without_endpoints(container.nodes) == without_endpoints(bundled.nodes)
    assert (container.platform, container.discovery_range, container.run_root) == \
           (bundled.platform, bundled.discovery_range, bundled.run_root)
    volume_target = service["volumes"][0].split(":")[1]
    assert volume_target == "/c4d/" + container.run_root


@pytest.mark.parametrize("name", ["survey", "hop", "square"])
def test_example_missions_validate(name):
    plan = load_plan(ROOT / "missions" / f"{name}.yaml")
    result = validate(plan, SITL_HOME)
    assert result.ok, result.errors
    assert not result.warnings, result.warnings
    assert plan.items[0].type == "takeoff" and plan.items[-1].type in ("land", "rtl")
    if name == "hop":
        assert result.duration < 20  # short enough for the CI flight
    if name == "survey":
        assert any(i.type == "camera_distance" for i in plan.items)


def test_every_mission_file_is_covered():
    assert sorted(p.stem for p in (ROOT / "missions").glob("*.yaml")) == ["hop", "square", "survey"]
