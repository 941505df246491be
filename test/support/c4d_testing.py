"""pytest plugin shared by every c4d test: private DDS domains, process groups, leak check.

Why: whole-graph tests start real processes talking real DDS. Three rules make that safe on a
shared machine, and this plugin enforces them instead of trusting each test:
- discovery stays on loopback (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, forced here);
- each test module gets its own ROS_DOMAIN_ID, locked machine-wide (see tools/ros_domain.py);
- no test leaves a process behind: every child carries a per-run token in its environment,
  and at session end any process still holding it is killed and the run fails.
"""

from __future__ import annotations

import atexit
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))

import ros_domain  # noqa: E402  (lives in tools/, added to sys.path above)

RUN_TOKEN = f"c4d-test-{uuid.uuid4().hex[:12]}"
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ["C4D_TEST_RUN"] = RUN_TOKEN
# per-vehicle parameter stores (docs/parameters.md: $XDG_DATA_HOME/c4d/vehicles/<vehicle>/) go to a
# directory of this session: a gain one test stores never reaches another test, nor the user's vehicles
_DATA_HOME = tempfile.mkdtemp(prefix="c4d-test-data-")
atexit.register(shutil.rmtree, _DATA_HOME, True)
os.environ["XDG_DATA_HOME"] = _DATA_HOME


LOG_TAIL_LINES = 25
_groups_created: list[ProcessGroup] = []  # every group of this session, in creation order


class ProcessGroup:
    """Processes started by one test or fixture; stop() ends them all (SIGINT, then SIGKILL).

    When a test fails, the tail of every log of the groups created during its setup or call is
    attached to the failure report (see pytest_runtest_makereport): a whole-graph failure on a
    CI machine then shows what each node said, not only the assertion."""

    def __init__(self, log_dir: Path, env: dict[str, str]) -> None:
        self.log_dir = log_dir
        self.env = env
        self.procs: list[tuple[subprocess.Popen, Path]] = []
        self.stopped = False
        _groups_created.append(self)

    def log_tails(self, lines: int = LOG_TAIL_LINES) -> str:
        """The last `lines` lines of every process log of this group, one block per process."""
        blocks = []
        for proc, log in self.procs:
            try:
                text = log.read_text(errors="replace").splitlines()[-lines:]
            except FileNotFoundError:
                text = ["(log missing)"]
            state = "running" if proc.poll() is None else f"exit {proc.returncode}"
            blocks.append(f"--- {log.stem} (pid {proc.pid}, {state}) ---\n" + "\n".join(text))
        return "\n".join(blocks)

    def spawn(self, name: str, argv: list[str], **env_overrides: str) -> subprocess.Popen:
        log = self.log_dir / f"{name}.log"
        env = {**self.env, **env_overrides}
        with open(log, "wb") as out:
            proc = subprocess.Popen(
                argv, stdout=out, stderr=subprocess.STDOUT, env=env, start_new_session=True
            )
        self.procs.append((proc, log))
        return proc

    def log_of(self, proc: subprocess.Popen) -> str:
        for p, log in self.procs:
            if p is proc:
                return log.read_text(errors="replace")
        raise KeyError(proc)

    def stop(self, timeout: float = 10.0) -> dict[int, int]:
        """Interrupt every process group, wait, kill what is left; return pid -> exit code."""
        self.stopped = True
        for proc, _ in self.procs:
            if proc.poll() is None:
                _signal_group(proc.pid, signal.SIGINT)
        deadline = time.monotonic() + timeout
        codes: dict[int, int] = {}
        for proc, _ in self.procs:
            try:
                codes[proc.pid] = proc.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                _signal_group(proc.pid, signal.SIGKILL)
                codes[proc.pid] = proc.wait()
            _signal_group(proc.pid, signal.SIGKILL)  # stray grandchildren of the group
        return codes


def _signal_group(pgid: int, sig: int) -> None:
    try:
        os.killpg(pgid, sig)
    except (ProcessLookupError, PermissionError):
        pass


def leftover_processes(token: str, domain_id: int | None = None) -> list[tuple[int, str]]:
    """(pid, command line) of live processes, other than this one, carrying `token` (and, when
    given, running in ROS domain `domain_id`)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            environ = (entry / "environ").read_bytes().split(b"\0")
            if f"C4D_TEST_RUN={token}".encode() not in environ:
                continue
            if domain_id is not None and f"ROS_DOMAIN_ID={domain_id}".encode() not in environ:
                continue
            state = (entry / "stat").read_text().rsplit(")", 1)[1].split()[0]
            if state == "Z":
                continue
            cmd = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except (FileNotFoundError, ProcessLookupError, PermissionError):
            continue
        found.append((int(entry.name), cmd.strip()))
    return found


_domains_used: set[int] = set()


def _kill_all(leftovers: list[tuple[int, str]]) -> None:
    for pid, _ in leftovers:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


@pytest.fixture(scope="module")
def ros_domain_id(request: pytest.FixtureRequest) -> Iterator[int]:
    """A ROS_DOMAIN_ID private to this test module (machine-wide lock, never one an earlier module
    of this session used). At module end, a process of this run still in the domain is killed and
    the module errors, naming it: a straggler can neither leak into the next module's graph nor
    go unattributed."""
    lease = ros_domain.acquire(avoid=_domains_used)
    _domains_used.add(lease.domain_id)
    try:
        yield lease.domain_id
        leftovers = []
        for _ in range(50):  # processes signalled at teardown may still be exiting: allow 5 s
            leftovers = leftover_processes(RUN_TOKEN, lease.domain_id)
            if not leftovers:
                break
            time.sleep(0.1)
        _kill_all(leftovers)
        assert not leftovers, (f"{request.module.__name__} left {len(leftovers)} process(es) running in ROS domain "
                               f"{lease.domain_id} (killed now): " + "; ".join(f"pid {p}: {c}" for p, c in leftovers))
    finally:
        lease.release()


@pytest.fixture(scope="module")
def ros_env(ros_domain_id: int) -> dict[str, str]:
    """Environment for child processes of this module: its domain, loopback discovery."""
    return {
        **os.environ,
        "ROS_DOMAIN_ID": str(ros_domain_id),
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
        "PYTHONUNBUFFERED": "1",
    }


@pytest.fixture(scope="module")
def module_processes(ros_env: dict[str, str], tmp_path_factory) -> Iterator[ProcessGroup]:
    """A ProcessGroup living as long as the test module."""
    group = ProcessGroup(tmp_path_factory.mktemp("procs"), ros_env)
    try:
        yield group
    finally:
        group.stop()


@pytest.fixture
def processes(ros_env: dict[str, str], tmp_path: Path) -> Iterator[ProcessGroup]:
    """A ProcessGroup living as long as one test."""
    group = ProcessGroup(tmp_path, ros_env)
    try:
        yield group
    finally:
        group.stop()


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item: pytest.Item) -> None:
    item.stash[_FIRST_GROUP] = len(_groups_created)


_FIRST_GROUP = pytest.StashKey[int]()


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    report = yield
    if report.failed and report.when in ("setup", "call"):
        # groups created for this test, and longer-lived (module) groups still running
        first = item.stash.get(_FIRST_GROUP, len(_groups_created))
        for index, group in enumerate(_groups_created):
            if group.procs and (index >= first or not group.stopped):
                report.sections.append((f"c4d process logs ({group.log_dir.name})", group.log_tails()))
    return report


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    leftovers = leftover_processes(RUN_TOKEN)
    if not leftovers:
        return
    _kill_all(leftovers)
    lines = "\n".join(f"  pid {pid}: {cmd}" for pid, cmd in leftovers)
    session.config.pluginmanager.get_plugin("terminalreporter").write_line(
        f"c4d_testing: tests left {len(leftovers)} process(es) running (killed now):\n{lines}",
        red=True,
    )
    session.exitstatus = pytest.ExitCode.TESTS_FAILED


def installed_executable(package: str, name: str) -> str:
    """<prefix>/lib/<package>/<name>, exactly where `ros2 run package name` looks."""
    from ament_index_python.packages import get_package_prefix

    return str(Path(get_package_prefix(package)) / "lib" / package / name)


@pytest.fixture(scope="module")
def ros_node(ros_domain_id):
    """(node, executor) of an rclpy context private to this test module, in its domain."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor

    context = Context()
    rclpy.init(context=context, domain_id=ros_domain_id)
    node = rclpy.create_node("c4d_test", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        yield node, executor
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=context)


def spin_for(executor, seconds: float, until=None, watch: tuple[ProcessGroup, dict] | None = None) -> bool:
    """Spin `executor` for up to `seconds`. With `until`, return True as soon as it holds (False
    on timeout); without, spin the whole time and return True. `watch` = (group, {name: proc}):
    fail at once, with the process log, if one of those processes dies meanwhile."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        executor.spin_once(timeout_sec=0.01)
        if until is not None and until():
            return True
        if watch is not None:
            group, procs = watch
            for name, proc in procs.items():
                assert proc.poll() is None, f"{name} died:\n{group.log_of(proc)}"
    return until is None


_samplers: list = []


def sample_latest(node, msg_type, topic: str):
    """A c4d_gnc LatestSampler of `topic` on a hidden side node in `node`'s context: `.latest()`
    is the newest sample. For 500 Hz topics a test only looks at now and then — subscribing
    through the executor would burn a fifth of a core in the test process, CPU the graph under
    test needs on a 2-core machine."""
    import rclpy
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    from c4d_ros.drain import LatestSampler

    side = rclpy.create_node(f"_c4d_test_samples_{len(_samplers)}", context=node.context)
    sampler = LatestSampler(side, msg_type, topic, QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
    _samplers.append((side, sampler))  # keep the side node alive as long as the context
    return sampler


def call_service(spin, client, request, wait_s: float = 30.0, reply_s: float = 15.0):
    """Call a ROS service from a test: wait for the server, send, spin (`spin(seconds, until)`,
    e.g. a partial of spin_for) until the reply; fail the test if either does not come."""
    assert client.wait_for_service(timeout_sec=wait_s), f"service {client.srv_name} not available"
    future = client.call_async(request)
    assert spin(reply_s, future.done), f"no reply from {client.srv_name} in {reply_s} s"
    return future.result()


def upload_plan(spin, client, request, retry_s: float = 15.0):
    """mission/upload as a caller should: an upload refused with a retry kind (no home, battery
    state unknown yet — UploadRefusal.retry) is sent again each second for up to `retry_s`."""
    from c4d_common.vehicle import UploadRefusal

    deadline = time.monotonic() + retry_s
    while True:
        reply = call_service(spin, client, request)
        if reply.accepted or not UploadRefusal(reply.refusal).retry or time.monotonic() > deadline:
            return reply
        spin(1.0)
