"""The built workspace follows ament conventions, and setup.sh is idempotent and fails loudly.

- every package of src/ resolves through the ament index to its own install prefix;
- every console script of every ament_python package is installed exactly where `ros2 run`
  looks for it: <prefix>/lib/<pkg>/<exe>;
- every interface file of c4d_interfaces is registered and importable;
- a second ./setup.sh succeeds and changes nothing in install/ or the venv;
- a missing toolchain piece, an unreachable registry or a build failure stops setup with a
  one-line reason and a non-zero exit, and never leaves a workspace marked as built.
"""

from __future__ import annotations

import ast
import hashlib
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest
from ament_index_python.packages import get_package_prefix, get_package_share_directory, get_resource

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = sorted(p.parent.name for p in (ROOT / "src").glob("*/package.xml"))
PYTHON_PACKAGES = [p for p in PACKAGES if (ROOT / "src" / p / "setup.py").is_file()]
CONSOLE_SCRIPT = re.compile(r"^\s*([\w.-]+)\s*=\s*[\w.]+:[\w.]+\s*$")


def console_scripts(package: str) -> list[str]:
    """Executable names declared in the package's setup.py console_scripts."""
    tree = ast.parse((ROOT / "src" / package / "setup.py").read_text())
    names = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            match = CONSOLE_SCRIPT.match(node.value)
            if match:
                names.append(match.group(1))
    return names


def clean_env(**overrides: str) -> dict[str, str]:
    """The caller's environment before env.sh (no venv, no ROS paths) plus overrides."""
    keep = {"HOME", "LANG", "LC_ALL", "TMPDIR", "USER", "CI", "TERM", "C4D_TEST_RUN"}
    env = {k: v for k, v in os.environ.items() if k in keep}
    env["PATH"] = os.environ.get("C4D_ORIG_PATH", os.environ["PATH"])
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.update(overrides)
    return env


def copy_repo(dest: Path) -> Path:
    """Copy the tracked and untracked-but-not-ignored files of the repo (a fresh clone's view)."""
    files = subprocess.run(
        ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
        cwd=ROOT, check=True, capture_output=True,
    ).stdout.split(b"\0")
    for rel in filter(None, files):
        src = ROOT / rel.decode()
        if src.is_file():
            target = dest / rel.decode()
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, target)
    return dest


def run_setup(cwd: Path, env: dict[str, str], *args: str, timeout: float = 400) -> subprocess.CompletedProcess:
    return subprocess.run(
        ["bash", str(cwd / "setup.sh"), *args], cwd=cwd, env=env, capture_output=True, text=True,
        timeout=timeout, stdin=subprocess.DEVNULL,
    )


def tree_manifest(base: Path, pattern: str = "**/*") -> dict[str, str]:
    """Relative path -> content hash (or symlink target) of every file under base."""
    manifest = {}
    for path in sorted(base.glob(pattern)):
        rel = str(path.relative_to(base))
        if path.is_symlink():
            manifest[rel] = "-> " + os.readlink(path)
        elif path.is_file():
            manifest[rel] = hashlib.sha256(path.read_bytes()).hexdigest()
    return manifest


def assert_one_line_error(result: subprocess.CompletedProcess, needle: str) -> None:
    assert result.returncode != 0, result.stdout + result.stderr
    errors = [line for line in result.stderr.splitlines() if line.startswith("setup: error:")]
    assert len(errors) == 1, result.stderr
    assert needle in errors[0], errors[0]


@pytest.mark.parametrize("package", PACKAGES)
def test_ament_index_resolves_package(package):
    prefix = Path(get_package_prefix(package))
    assert prefix == ROOT / "install" / package
    assert (Path(get_package_share_directory(package)) / "package.xml").is_file()


@pytest.mark.parametrize(
    "package,exe", [(p, e) for p in PYTHON_PACKAGES for e in console_scripts(p)]
)
def test_executable_is_where_ros2_run_looks(package, exe):
    # `ros2 run PKG EXE` executes <prefix of PKG>/lib/PKG/EXE, the prefix found via the index.
    path = Path(get_package_prefix(package)) / "lib" / package / exe
    assert path.is_file() and os.access(path, os.X_OK), path


def test_installed_executable_without_environment_prints_the_hint():
    # started from a plain shell (no env.sh): one line naming env.sh, exit 2 — not a 20-line traceback
    exe = Path(get_package_prefix("c4d_gnc")) / "lib" / "c4d_gnc" / "core"
    bare = {"PATH": "/usr/bin:/bin", "HOME": os.environ.get("HOME", "/tmp")}
    done = subprocess.run([str(exe)], capture_output=True, text=True, timeout=60, env=bare, cwd="/")
    assert done.returncode == 2, (done.stdout, done.stderr)
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("core: error: the c4d environment is not set") and "env.sh" in lines[0], lines


def test_every_interface_file_is_registered():
    content, _ = get_resource("rosidl_interfaces", "c4d_interfaces")
    registered = {line.split(";")[0] for line in content.splitlines() if line.endswith((".msg", ".srv"))}
    src = ROOT / "src" / "c4d_interfaces"
    on_disk = {str(p.relative_to(src)) for p in [*src.glob("msg/*.msg"), *src.glob("srv/*.srv")]}
    assert registered == on_disk
    share = Path(get_package_share_directory("c4d_interfaces"))
    assert all((share / rel).is_file() for rel in on_disk)


def test_setup_is_idempotent():
    venv = ROOT / ".venv"
    first = run_setup(ROOT, clean_env(), "--no-check")  # converge (the tree may have changed since)
    assert first.returncode == 0, first.stderr
    before = (tree_manifest(ROOT / "install"), tree_manifest(venv, "share/*/cmake/**/*"))
    result = run_setup(ROOT, clean_env(), "--no-check")
    assert result.returncode == 0, result.stderr
    assert "pinned packages already installed" in result.stdout
    assert "0 file(s) rewritten" in result.stdout
    after = (tree_manifest(ROOT / "install"), tree_manifest(venv, "share/*/cmake/**/*"))
    assert after[0] == before[0], "second setup changed install/"
    assert after[1] == before[1], "second setup changed the venv's CMake files"
    assert (ROOT / "install" / ".c4d-ready").is_file()


def test_setup_rejects_unknown_argument(tmp_path):
    result = run_setup(ROOT, clean_env(), "--frobnicate")
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == ["setup: error: unknown argument '--frobnicate' (try --help)"]


def test_setup_stops_on_missing_cmake(tmp_path):
    repo = copy_repo(tmp_path / "repo")
    farm = tmp_path / "bin"  # every tool of the caller's PATH except cmake
    farm.mkdir()
    for directory in clean_env()["PATH"].split(os.pathsep):
        if not os.path.isdir(directory):
            continue
        for entry in os.scandir(directory):
            if entry.name != "cmake" and not (farm / entry.name).exists():
                (farm / entry.name).symlink_to(entry.path)
    result = run_setup(repo, clean_env(PATH=str(farm)))
    assert_one_line_error(result, "cmake not found")
    assert not (repo / ".venv").exists() and not (repo / "install").exists()


def test_setup_stops_when_registry_is_unreachable(tmp_path):
    repo = copy_repo(tmp_path / "repo")
    env = clean_env(
        PIP_CONFIG_FILE=os.devnull,              # ignore the machine's pip.conf mirrors
        PIP_INDEX_URL="http://127.0.0.1:9/simple",  # loopback port with nobody listening
        PIP_NO_CACHE_DIR="1", PIP_RETRIES="0", PIP_TIMEOUT="3",
    )
    result = run_setup(repo, env)
    assert_one_line_error(result, "pip could not install the pinned packages")
    assert not (repo / "install").exists()
    assert not (repo / ".venv" / "c4d-requirements.sha256").exists()


def test_setup_stops_on_build_failure(tmp_path):
    repo = copy_repo(tmp_path / "repo")
    broken = repo / "src" / "c4d_broken_fixture"
    broken.mkdir()
    (broken / "package.xml").write_text(
        '<?xml version="1.0"?><package format="3"><name>c4d_broken_fixture</name><version>0.0.0</version>'
        '<description>deliberately broken</description><maintainer email="test@c4d.dev">t</maintainer>'
        "<license>Apache-2.0</license><buildtool_depend>ament_cmake</buildtool_depend>"
        "<export><build_type>ament_cmake</build_type></export></package>"
    )
    (broken / "CMakeLists.txt").write_text(
        "cmake_minimum_required(VERSION 3.8)\nproject(c4d_broken_fixture)\n"
        'message(FATAL_ERROR "deliberately broken package")\n'
    )
    # Reuse the installed venv (pins unchanged, so no download); the build is what fails.
    result = run_setup(repo, clean_env(C4D_VENV=str(ROOT / ".venv")), "--no-check")
    assert_one_line_error(result, "colcon build failed for: c4d_broken_fixture")
    assert not (repo / "install" / ".c4d-ready").exists()
    sourced = subprocess.run(
        ["bash", "-c", f". {repo}/env.sh"], env=clean_env(C4D_VENV=str(ROOT / ".venv")),
        capture_output=True, text=True,
    )
    assert sourced.returncode != 0 and "workspace not built" in sourced.stderr
