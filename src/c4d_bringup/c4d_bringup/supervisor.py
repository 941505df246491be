"""Process supervisor: one OS process per node, per-node logs, restart policy, clean shutdown.

Each child runs in its own session (so its own process group: a Ctrl-C in the terminal reaches
the supervisor only, which then stops the children in order) with stdout and stderr appended
to its log file, and with PR_SET_PDEATHSIG = SIGTERM so that even a supervisor killed with
SIGKILL leaves no orphan behind (Linux). Restart policy per process: never | on-failure (exit
code != 0 or a signal) | always, after a back-off doubled per consecutive restart (capped),
at most `max_restarts` within `restart_window_s`; past that the process stays down. Restarts are
also staggered globally: two (re)starts are at least `restart_spacing_s` apart (the initial
start-up counts as one), so nodes that died together come back one at a time — each start of a
DDS participant sets off a discovery burst that every other node has to process, and several at
once used to stall the flight-critical ones. A critical
process that exits (or gives up) marks the supervisor failed, which the caller turns into a
shutdown. stop(): SIGINT to every group, wait up to the timeout, SIGKILL what is left and any
stray grandchild of each group.

Placement per process (`Placement`): CPU affinity and niceness are set in the child between
fork and exec, so every thread the node ever starts inherits them. A niceness below the
supervisor's own that this user may not set (no CAP_SYS_NICE, RLIMIT_NICE too low) is a logged
fallback: the process runs at the inherited niceness and the log says why.

No ROS here: the children are plain argv lists. Single-threaded by design (poll() from one
loop) — `preexec_fn` is only safe in a process without other threads, which the `c4d up`
process is.
"""

from __future__ import annotations

import ctypes
import json
import os
import signal
import subprocess
import time
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

PR_SET_PDEATHSIG = 1
MAX_BACKOFF_S = 10.0
CAP_SYS_NICE = 23  # bit in /proc/<pid>/status CapEff


def has_capability(bit: int) -> bool:
    """Whether this process has the Linux capability `bit` in its effective set."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("CapEff:"):
                return bool(int(line.split()[1], 16) >> bit & 1)
    except (OSError, ValueError):
        pass
    return False


@dataclass(frozen=True)
class Placement:
    """Where and how eagerly a child runs: CPU ids it may use and its niceness (None: inherited).
    Why: on a small board the core gets a CPU of its own and best-effort nodes yield to the rest."""

    cpu_affinity: tuple[int, ...] | None = None
    nice: int | None = None

    def nice_refusal(self) -> str | None:
        """Why `nice` cannot be applied by this process (None: it can). Raising one's niceness is
        always allowed; lowering it needs CAP_SYS_NICE or an RLIMIT_NICE of at least 20 - nice."""
        if self.nice is None:
            return None
        current = os.getpriority(os.PRIO_PROCESS, 0)
        if self.nice >= current or has_capability(CAP_SYS_NICE):
            return None
        import resource

        limit = resource.getrlimit(resource.RLIMIT_NICE)[0]
        if limit == resource.RLIM_INFINITY or 20 - self.nice <= limit:
            return None
        return (f"nice {self.nice} not permitted (below the current {current}: needs CAP_SYS_NICE or RLIMIT_NICE >= "
                f"{20 - self.nice}, is {limit}); running at nice {current}")

    def describe(self) -> str:
        parts = []
        if self.cpu_affinity is not None:
            parts.append(f"CPUs {','.join(map(str, self.cpu_affinity))}")
        if self.nice is not None:
            parts.append(f"nice {self.nice}")
        return ", ".join(parts)

    def child_setup(self, apply_nice: bool) -> Callable[[], None]:
        """The function run in the child between fork and exec (no Python threads there)."""
        def setup() -> None:
            _pdeathsig()
            try:
                if self.cpu_affinity is not None:
                    os.sched_setaffinity(0, self.cpu_affinity)
                if self.nice is not None and apply_nice:
                    os.setpriority(os.PRIO_PROCESS, 0, self.nice)
            except OSError as exc:  # into the node's log (fd 2 is the log file here); it still starts
                os.write(2, f"c4d: placement {self.describe()} not applied: {exc}\n".encode())
        return setup


@dataclass(frozen=True)
class RestartPolicy:
    mode: str = "never"  # never | on-failure | always
    max_restarts: int = 5
    window_s: float = 60.0
    backoff_s: float = 1.0

    def wants_restart(self, returncode: int) -> bool:
        return self.mode == "always" or (self.mode == "on-failure" and returncode != 0)


@dataclass(frozen=True)
class ProcessSpec:
    name: str
    argv: tuple[str, ...]
    log_path: Path
    critical: bool = False
    restart: RestartPolicy = RestartPolicy()
    placement: Placement = Placement()
    members: tuple[str, ...] = ()  # the ROS nodes of a composed process (empty: the process is one node)


@dataclass
class _Child:
    spec: ProcessSpec
    proc: subprocess.Popen | None = None
    starts: int = 0
    restarts: deque = field(default_factory=deque)  # monotonic times of restarts in the window
    consecutive: int = 0
    restart_at: float | None = None
    deferred: bool = False  # its due restart waits for the global restart spacing (logged once)
    last_exit: int | None = None
    gave_up: bool = False


def _pdeathsig() -> None:  # runs in the child between fork and exec
    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
    except (OSError, AttributeError):  # not Linux: the signal handlers of the supervisor still apply
        pass


def describe_exit(returncode: int) -> str:
    if returncode < 0:
        try:
            return f"killed by {signal.Signals(-returncode).name}"
        except ValueError:
            return f"killed by signal {-returncode}"
    return f"exit code {returncode}"


def signal_group(pgid: int, sig: int) -> None:
    try:
        os.killpg(pgid, sig)
    except (ProcessLookupError, PermissionError):
        pass


class Supervisor:
    """Start, watch, restart and stop a set of processes (see the module docstring)."""

    def __init__(self, specs: Sequence[ProcessSpec], env: Mapping[str, str], log: Callable[[str], None] = print,
                 state_file: Path | None = None, clock: Callable[[], float] = time.monotonic,
                 restart_spacing_s: float = 0.0) -> None:
        if restart_spacing_s < 0:
            raise ValueError(f"restart_spacing_s must be >= 0, not {restart_spacing_s}")
        names = [s.name for s in specs]
        if len(set(names)) != len(names):
            raise ValueError(f"duplicate process names in {names}")
        self.children = {s.name: _Child(s) for s in specs}
        self.env = dict(env)
        self.log = log
        self.state_file = state_file
        self.clock = clock
        self.restart_spacing_s = restart_spacing_s
        self.last_start: float | None = None  # clock time of the latest (re)start, for the spacing
        self.failure: str | None = None  # why a critical process ended the run
        self.stopping = False

    # ------------------------------------------------------------------ start / watch
    def start(self) -> None:
        for child in self.children.values():
            self._spawn(child)
        self.last_start = self.clock()
        self._write_state()

    def _spawn(self, child: _Child) -> None:
        spec = child.spec
        spec.log_path.parent.mkdir(parents=True, exist_ok=True)
        refusal = spec.placement.nice_refusal()
        if refusal and child.starts == 0:
            self.log(f"{spec.name}: {refusal}")
        with open(spec.log_path, "ab") as out:
            out.write(f"--- c4d: start #{child.starts + 1} {time.strftime('%Y-%m-%d %H:%M:%S')}: "
                      f"{' '.join(spec.argv)}\n".encode())
            out.flush()
            try:
                child.proc = subprocess.Popen(spec.argv, stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                              env=self.env, start_new_session=True,
                                              preexec_fn=spec.placement.child_setup(apply_nice=refusal is None))
            except OSError as exc:
                child.proc = None
                child.last_exit = 127
                self.log(f"{spec.name}: cannot start {spec.argv[0]}: {exc.strerror or exc}")
                self._handle_exit(child, 127)
                return
        child.starts += 1
        child.restart_at = None
        child.deferred = False
        where = spec.placement.describe()
        where = f", {where}" if where else ""
        self.log(f"{spec.name}: started (pid {child.proc.pid}{where})" if child.starts == 1 else
                 f"{spec.name}: restarted (pid {child.proc.pid}, restart {len(child.restarts)}/{spec.restart.max_restarts})")

    def poll(self) -> None:
        """Reap exits, start due restarts; call often (every ~0.1 s)."""
        if self.stopping:
            return
        now = self.clock()
        changed = False
        for child in self.children.values():
            if child.proc is not None:
                code = child.proc.poll()
                if code is not None:
                    signal_group(child.proc.pid, signal.SIGKILL)  # stray grandchildren of that node
                    child.proc = None
                    child.last_exit = code
                    self._handle_exit(child, code)
                    changed = True
        changed = self._restart_due(now) or changed
        if changed:
            self._write_state()

    def _restart_due(self, now: float) -> bool:
        """Start the due restarts, earliest due first, each at least restart_spacing_s after the previous start."""
        if self.failure is not None:
            return False
        due = sorted((c for c in self.children.values() if c.proc is None and c.restart_at is not None and now >= c.restart_at),
                     key=lambda c: c.restart_at or 0.0)
        started = False
        for child in due:
            wait = self.spacing_wait(now)
            if wait > 0:
                if not child.deferred:
                    child.deferred = True
                    self.log(f"{child.spec.name}: restart deferred {wait:.1f} s (restart spacing {self.restart_spacing_s:g} s)")
                continue
            self._spawn(child)
            self.last_start = now
            started = True
        return started

    def spacing_wait(self, now: float) -> float:
        """Seconds until the global restart spacing allows another start (0: now)."""
        if self.last_start is None:
            return 0.0
        return max(0.0, self.last_start + self.restart_spacing_s - now)

    def _handle_exit(self, child: _Child, code: int) -> None:
        spec, now = child.spec, self.clock()
        policy = spec.restart
        self.log(f"{spec.name}: {describe_exit(code)} (log: {spec.log_path})")
        if not policy.wants_restart(code):
            if spec.critical and self.failure is None:
                self.failure = f"critical node {spec.name} stopped ({describe_exit(code)})"
            return
        while child.restarts and now - child.restarts[0] > policy.window_s:
            child.restarts.popleft()
        if len(child.restarts) >= policy.max_restarts:
            child.gave_up = True
            self.log(f"{spec.name}: {len(child.restarts)} restarts within {policy.window_s:g} s — giving up")
            if spec.critical and self.failure is None:
                self.failure = f"critical node {spec.name} keeps failing ({describe_exit(code)})"
            return
        # a process that ran for a whole window resets the back-off
        child.consecutive = child.consecutive + 1 if child.restarts else 1
        delay = min(MAX_BACKOFF_S, policy.backoff_s * 2 ** (child.consecutive - 1))
        child.restarts.append(now)
        child.restart_at = now + delay
        self.log(f"{spec.name}: restarting in {delay:.1f} s")

    # ------------------------------------------------------------------ queries
    def pid(self, name: str) -> int | None:
        proc = self.children[name].proc
        return proc.pid if proc is not None else None

    def restart_count(self, name: str) -> int:
        return self.children[name].starts - 1 if self.children[name].starts else 0

    def running(self) -> list[str]:
        return [n for n, c in self.children.items() if c.proc is not None and c.proc.poll() is None]

    def state(self) -> dict:
        return {"failure": self.failure, "stopping": self.stopping, "nodes": {
            n: {"pid": self.pid(n), "starts": c.starts, "restarts": self.restart_count(n), "last_exit": c.last_exit,
                "gave_up": c.gave_up, "critical": c.spec.critical, "log": str(c.spec.log_path),
                "members": list(c.spec.members or (n,))}
            for n, c in self.children.items()}}

    def _write_state(self) -> None:
        if self.state_file is None:
            return
        tmp = self.state_file.with_suffix(".tmp")
        tmp.write_text(json.dumps(self.state(), indent=1))
        tmp.replace(self.state_file)

    # ------------------------------------------------------------------ stop
    def stop(self, timeout: float, force: Callable[[], bool] = lambda: False) -> dict[str, int]:
        """SIGINT every process group (in reverse start order), wait up to `timeout` (or until
        `force()` says hurry), SIGKILL what is left; return name -> exit code of the last run."""
        self.stopping = True
        live = [(n, c.proc) for n, c in reversed(list(self.children.items())) if c.proc is not None]
        for _, proc in live:
            if proc.poll() is None:
                signal_group(proc.pid, signal.SIGINT)
        deadline = time.monotonic() + timeout
        codes: dict[str, int] = {n: c.last_exit for n, c in self.children.items() if c.last_exit is not None}
        for name, proc in live:
            while proc.poll() is None and time.monotonic() < deadline and not force():
                time.sleep(0.02)
            if proc.poll() is None:
                self.log(f"{name}: still running after SIGINT — SIGKILL")
                signal_group(proc.pid, signal.SIGKILL)
                proc.wait()
            signal_group(proc.pid, signal.SIGKILL)  # stray grandchildren of the group
            codes[name] = proc.returncode
            self.children[name].last_exit = proc.returncode
            self.children[name].proc = None
        for child in self.children.values():
            child.restart_at = None
        self._write_state()
        return codes
