"""Process supervisor with real short-lived children (sleep, python -c): restart policies and their
limits, critical failures, clean shutdown (SIGINT, then SIGKILL after the timeout), stray
grandchildren, and no orphans when the supervising process itself gets SIGTERM or SIGKILL."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from c4d_bringup.supervisor import ProcessSpec, RestartPolicy, Supervisor

PY = sys.executable


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return False
    return state != "Z"


def wait_until(predicate, seconds: float) -> bool:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.02)
    return predicate()


def make(tmp_path: Path, specs: list[ProcessSpec]) -> tuple[Supervisor, list[str]]:
    events: list[str] = []
    return Supervisor(specs, os.environ, log=events.append, state_file=tmp_path / "state.json"), events


def spec(tmp_path: Path, name: str, argv: list[str], critical=False, **policy) -> ProcessSpec:
    return ProcessSpec(name, tuple(argv), tmp_path / "logs" / f"{name}.log", critical, RestartPolicy(**policy))


def poll_until(sup: Supervisor, predicate, seconds: float) -> bool:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        sup.poll()
        if predicate():
            return True
        time.sleep(0.02)
    return False


def test_start_and_clean_stop(tmp_path):
    sup, events = make(tmp_path, [spec(tmp_path, "a", ["sleep", "60"]), spec(tmp_path, "b", ["sleep", "60"])])
    sup.start()
    pids = [sup.pid("a"), sup.pid("b")]
    assert all(alive(p) for p in pids) and sorted(sup.running()) == ["a", "b"]
    assert json.loads((tmp_path / "state.json").read_text())["nodes"]["a"]["pid"] == pids[0]
    t0 = time.monotonic()
    codes = sup.stop(timeout=5)
    assert time.monotonic() - t0 < 2 and codes == {"a": -signal.SIGINT, "b": -signal.SIGINT}
    assert not any(alive(p) for p in pids)
    assert (tmp_path / "logs" / "a.log").read_text().startswith("--- c4d: start #1")


def test_sigkill_after_timeout_for_a_child_ignoring_sigint(tmp_path):
    stubborn = [PY, "-c", "import signal, time; signal.signal(signal.SIGINT, signal.SIG_IGN); print('RE' + 'ADY', flush=True); "
                          "time.sleep(60)"]
    sup, events = make(tmp_path, [spec(tmp_path, "stubborn", stubborn)])
    sup.start()
    assert wait_until(lambda: "READY" in (tmp_path / "logs" / "stubborn.log").read_text(), 10)
    t0 = time.monotonic()
    codes = sup.stop(timeout=0.5)
    assert 0.5 <= time.monotonic() - t0 < 3 and codes == {"stubborn": -signal.SIGKILL}
    assert any("SIGKILL" in e for e in events)


def test_stray_grandchild_of_a_node_is_killed(tmp_path):
    # the node starts a helper that ignores SIGINT, then exits on SIGINT itself: the group kill gets the helper
    script = textwrap.dedent(f"""
        import signal, subprocess, sys, time
        helper = subprocess.Popen([{PY!r}, "-c", "import signal, time; signal.signal(signal.SIGINT, signal.SIG_IGN); "
                                   "time.sleep(60)"])
        open({str(tmp_path / 'helper.pid')!r}, "w").write(str(helper.pid))
        time.sleep(60)
    """)
    sup, _ = make(tmp_path, [spec(tmp_path, "node", [PY, "-c", script])])
    sup.start()
    assert wait_until(lambda: (tmp_path / "helper.pid").exists() and (tmp_path / "helper.pid").read_text(), 10)
    helper = int((tmp_path / "helper.pid").read_text())
    assert alive(helper)
    sup.stop(timeout=5)
    assert wait_until(lambda: not alive(helper), 2)


def test_always_restarts_a_killed_node_with_a_new_pid(tmp_path):
    sup, events = make(tmp_path, [spec(tmp_path, "payload", ["sleep", "60"], mode="always", backoff_s=0.05)])
    sup.start()
    first = sup.pid("payload")
    os.kill(first, signal.SIGKILL)
    assert poll_until(sup, lambda: sup.pid("payload") not in (None, first), 5)
    assert sup.restart_count("payload") == 1 and alive(sup.pid("payload")) and sup.failure is None
    assert "payload: killed by SIGKILL" in " ".join(events) and any("restarted (pid" in e for e in events)
    state = json.loads((tmp_path / "state.json").read_text())["nodes"]["payload"]
    assert state["restarts"] == 1 and state["last_exit"] == -signal.SIGKILL
    sup.stop(timeout=5)


def test_restart_limit_back_off_and_policies(tmp_path):
    crash = [PY, "-c", "import sys; sys.exit(3)"]
    clean = [PY, "-c", "pass"]
    sup, events = make(tmp_path, [
        spec(tmp_path, "crashy", crash, mode="on-failure", max_restarts=3, backoff_s=0.1),
        spec(tmp_path, "done", clean, mode="on-failure", backoff_s=0.05),
        spec(tmp_path, "never", crash, mode="never")])
    sup.start()
    assert poll_until(sup, lambda: sup.children["crashy"].gave_up, 20)
    sup.poll()
    assert sup.children["crashy"].starts == 4  # first run + 3 restarts, then it stays down
    delays = [float(e.split("in ")[1].split(" s")[0]) for e in events if e.startswith("crashy: restarting in")]
    assert delays == [0.1, 0.2, 0.4]  # doubled per consecutive restart
    assert sup.children["done"].starts == 1 and sup.children["done"].last_exit == 0  # clean exit: not restarted
    assert sup.children["never"].starts == 1 and sup.children["never"].last_exit == 3
    assert sup.failure is None  # none of them critical
    assert (tmp_path / "logs" / "crashy.log").read_text().count("--- c4d: start #") == 4
    sup.stop(timeout=5)


def test_restarts_are_staggered_by_the_global_spacing(tmp_path):
    """Two nodes killed together restart restart_spacing_s apart (injected clock), each after its own back-off."""
    now = [100.0]
    events: list[str] = []
    sup = Supervisor([spec(tmp_path, n, ["sleep", "60"], mode="always", backoff_s=1.0) for n in ("recorder", "bridge", "core")],
                     os.environ, log=events.append, clock=lambda: now[0], restart_spacing_s=2.0)
    sup.start()
    first = {n: sup.pid(n) for n in ("recorder", "bridge")}
    now[0] = 101.0  # the initial start-up counts as a start: a restart before 102.0 would wait
    for pid in first.values():
        os.kill(pid, signal.SIGKILL)
    assert poll_until(sup, lambda: sup.pid("recorder") is None and sup.pid("bridge") is None, 5)  # both reaped at 101.0

    def started() -> list[str]:
        return sorted(n for n, pid in first.items() if sup.pid(n) not in (None, pid))

    now[0] = 101.9  # back-off (1 s) not over yet
    sup.poll()
    assert started() == []
    now[0] = 102.0  # both due: the first in start order goes, the other waits for the spacing
    sup.poll()
    assert started() == ["recorder"]
    assert "bridge: restart deferred 2.0 s (restart spacing 2 s)" in events
    now[0] = 103.99
    sup.poll()
    assert started() == ["recorder"]
    now[0] = 104.0
    sup.poll()
    assert started() == ["bridge", "recorder"] and sup.pid("core") is not None and sup.failure is None
    assert sum("restart deferred" in e for e in events) == 1  # logged once, not per poll
    # a later lone restart is not delayed once the spacing has passed: only its own back-off counts
    now[0] = 110.0
    bridge = sup.pid("bridge")
    os.kill(bridge, signal.SIGKILL)
    assert poll_until(sup, lambda: sup.pid("bridge") is None, 5)
    now[0] = 112.0  # second consecutive restart of bridge: back-off doubled to 2 s
    sup.poll()
    assert sup.pid("bridge") not in (None, bridge)
    sup.stop(timeout=5)


def test_zero_spacing_restarts_together_and_negative_is_refused(tmp_path):
    now = [0.0]
    sup = Supervisor([spec(tmp_path, n, ["sleep", "60"], mode="always", backoff_s=0.5) for n in ("a", "b")],
                     os.environ, log=lambda text: None, clock=lambda: now[0])
    sup.start()
    first = [sup.pid("a"), sup.pid("b")]
    for pid in first:
        os.kill(pid, signal.SIGKILL)
    assert poll_until(sup, lambda: sup.running() == [], 5)
    now[0] = 0.5
    sup.poll()
    assert all(sup.pid(n) not in (None, old) for n, old in zip(("a", "b"), first, strict=True))
    sup.stop(timeout=5)
    with pytest.raises(ValueError, match="restart_spacing_s must be >= 0"):
        Supervisor([], os.environ, restart_spacing_s=-1.0)


def test_critical_exit_is_a_failure(tmp_path):
    sup, events = make(tmp_path, [spec(tmp_path, "core", [PY, "-c", "import sys; sys.exit(1)"], critical=True),
                                  spec(tmp_path, "other", ["sleep", "60"])])
    sup.start()
    assert poll_until(sup, lambda: sup.failure is not None, 10)
    assert sup.failure == "critical node core stopped (exit code 1)"
    other = sup.pid("other")
    sup.stop(timeout=5)
    assert not alive(other)


def test_missing_program_counts_as_a_failed_start(tmp_path):
    sup, events = make(tmp_path, [spec(tmp_path, "ghost", [str(tmp_path / "nope")], critical=True)])
    sup.start()
    assert sup.failure is not None and "cannot start" in events[0]
    sup.stop(timeout=1)


RUNNER = textwrap.dedent("""
    import sys, time
    from pathlib import Path
    from c4d_bringup.graph import run_graph
    from c4d_bringup.supervisor import ProcessSpec, RestartPolicy
    from c4d_bringup.system_config import SystemConfig
    import os
    run = Path(sys.argv[1])
    specs = [ProcessSpec(f"n{k}", ("sleep", "60"), run / "logs" / f"n{k}.log", k == 0, RestartPolicy("always" if k else "never"))
             for k in range(3)]
    config = SystemConfig(run / "system.yaml", "sitl", "LOCALHOST", str(run), 5.0, ())
    sys.exit(run_graph(config, specs, os.environ, run, lambda text: print(text, flush=True)))
""")


def start_runner(tmp_path: Path) -> tuple[subprocess.Popen, list[int]]:
    runner = subprocess.Popen([PY, "-c", RUNNER, str(tmp_path)], stdout=subprocess.PIPE, text=True, start_new_session=True)
    state = tmp_path / "supervisor.json"
    assert wait_until(lambda: state.exists() and all(n["pid"] for n in json.loads(state.read_text())["nodes"].values()), 20)
    pids = [n["pid"] for n in json.loads(state.read_text())["nodes"].values()]
    assert all(alive(p) for p in pids)
    return runner, pids


def test_sigterm_to_the_supervising_process_stops_every_child(tmp_path):
    runner, pids = start_runner(tmp_path)
    runner.send_signal(signal.SIGTERM)
    out, _ = runner.communicate(timeout=15)
    assert runner.returncode == 0, out
    assert "stopping on SIGTERM" in out and "down: every node stopped" in out
    assert not any(alive(p) for p in pids)


def test_sigkill_to_the_supervising_process_leaves_no_orphan(tmp_path):
    runner, pids = start_runner(tmp_path)
    runner.kill()  # no chance to clean up: the children's parent-death signal does it
    runner.wait(timeout=5)
    runner.stdout.close()
    assert wait_until(lambda: not any(alive(p) for p in pids), 5), [p for p in pids if alive(p)]
