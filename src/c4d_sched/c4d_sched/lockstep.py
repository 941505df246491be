"""Lockstep: simulated time that advances only when the flight chain has consumed the previous step.

What (PX4-SITL style): the simulator publishes the sensors of step k and the simulated time
(/clock), then holds until the actuator command computed from step k arrives; the GNC core runs
its tick for step k only when the simulated clock has reached it and the inputs of step k are
in. Nothing is ever late, so nothing is skipped, whatever the machine's load: a flight is a
function of its inputs, bit for bit (test/test_lockstep.py), at whatever real-time factor the
machine manages.

Pieces (ROS-free, unit-tested in test/test_lockstep.py):
- `LockstepClock`: a `Clock` for the CyclicExecutive whose time is simulated time. Its
  `sleep_until_ns(deadline)` polls (the node's drain: subscriptions, services) until its gate
  has nothing missing for the deadline, then time jumps to the deadline. So the executive's loop
  is the same in both modes; only the clock differs. In simulated time a tick takes no time:
  no overrun, no release jitter, no skipped tick (the profiler's load and jitter read 0).
- `InputGate` (core side): tick d may run when the clock has reached d and every input stream
  that is *running* has delivered its sample stamped d. A stream runs when it delivered the
  sample of the previous tick (d - tick): a stream not there yet (navigation before alignment)
  or gone (a dropout fault, a dead node) is not waited for. A running stream that misses a step
  is waited for up to a wall-clock timeout, then given up (logged) — the chain never hangs on it.
- `StepGate` (simulator side): which step's command is awaited, which command matches (stamp ≥
  the step's time: the core stamps each command with its tick time), and an optional hold
  (`pause_at_ns`: the simulator stops after the first step at or past it, so a test can issue
  commands that take effect at a known simulated tick).
Times are integer nanoseconds of simulated time; stamps match within MATCH_TOLERANCE_NS because
float seconds round to the nanosecond on the way through messages.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable
from typing import Protocol

MATCH_TOLERANCE_NS = 1_000  # stamps equal within 1 µs (float seconds ↔ integer ns round trips)
POLL_S = 100e-6  # wall time between two polls while waiting (Linux sleeps ~60-100 µs at best)
CLOCK = "clock"  # the name `InputGate.missing` gives the simulated clock itself


class Gate(Protocol):
    def missing(self, deadline_ns: int) -> tuple[str, ...]: ...


class LockstepClock:
    """Executive clock on simulated time (see the module docstring).

    `poll()` is called while waiting (drain the node: inputs feed the gate, services get answers).
    `on_stall(deadline_ns, missing, waited_s)` is called every `report_s` of wall time spent
    waiting for the same deadline; it returns True to stop waiting (run the tick without what is
    missing) or False to keep waiting. `sleep` and `wall` are injectable for tests.
    """

    def __init__(self, gate: Gate, poll: Callable[[], object], on_stall: Callable[[int, tuple[str, ...], float], bool],
                 report_s: float = 1.0, sleep: Callable[[float], None] = time.sleep,
                 wall: Callable[[], float] = time.monotonic) -> None:
        self.gate, self.poll, self.on_stall = gate, poll, on_stall
        self.report_s, self._sleep, self._wall = report_s, sleep, wall
        self.t_ns = 0
        self.stalls = 0  # waits that reached report_s
        self.given_up = 0  # ticks run without something the gate missed (on_stall said stop waiting)
        self.interrupted = False

    def interrupt(self) -> None:
        """End the current and every later wait at once (shutdown: safe from a signal handler)."""
        self.interrupted = True

    def now_ns(self) -> int:
        return self.t_ns

    def cpu_ns(self) -> int:
        return time.process_time_ns()

    def sleep_until_ns(self, deadline_ns: int) -> None:
        """Poll until the gate misses nothing for `deadline_ns` (or on_stall gives up), then time is the deadline."""
        start = self._wall()
        next_report = start + self.report_s
        while not self.interrupted:
            self.poll()
            missing = self.gate.missing(deadline_ns)
            if not missing:
                break
            now = self._wall()
            if now >= next_report:
                self.stalls += 1
                next_report = now + self.report_s
                if self.on_stall(deadline_ns, missing, now - start):
                    self.given_up += 1
                    break
            self._sleep(POLL_S)
        self.t_ns = max(self.t_ns, deadline_ns)


class InputGate:
    """The core's side of lockstep: which inputs tick `deadline` waits for (module docstring)."""

    def __init__(self, tick_ns: int, streams: Iterable[str]) -> None:
        self.tick_ns = tick_ns
        self.clock_ns: int | None = None  # newest simulated time seen (/clock)
        self.newest: dict[str, int] = {name: -1 << 62 for name in streams}  # newest sample stamp per stream

    def on_clock(self, t_ns: int) -> None:
        self.clock_ns = t_ns if self.clock_ns is None else max(self.clock_ns, t_ns)

    def on_sample(self, stream: str, stamp_ns: int) -> None:
        """A sample of `stream` stamped `stamp_ns` arrived (a stream the gate does not wait for is ignored)."""
        if stream in self.newest:
            self.newest[stream] = max(self.newest[stream], stamp_ns)

    def missing(self, deadline_ns: int) -> tuple[str, ...]:
        """What tick `deadline_ns` still waits for: ('clock',) while simulated time is behind it,
        else the running streams without their sample of the deadline (empty: run the tick)."""
        if self.clock_ns is None or self.clock_ns < deadline_ns - MATCH_TOLERANCE_NS:
            return (CLOCK,)
        previous = deadline_ns - self.tick_ns - MATCH_TOLERANCE_NS
        due = deadline_ns - MATCH_TOLERANCE_NS
        return tuple(name for name, newest in self.newest.items() if previous <= newest < due)


class StepGate:
    """The simulator's side of lockstep: the step whose command is awaited, matching, hold.

    `declare(t_ns)` after publishing the sensors of the step at simulated time t_ns; `on_command
    (stamp_ns)` for each actuator command taken; `missing()` says why the simulator cannot go on:
    ('command',) while the declared step's command has not come, ('paused',) once a step at or past
    `pause_at_ns` was answered.
    """

    def __init__(self, pause_at_ns: int | None = None) -> None:
        self.pause_at_ns = pause_at_ns
        self.awaited: int | None = None  # time of the declared step whose command has not come
        self.last_step = -1 << 62  # time of the newest declared step
        self.steps = 0  # steps declared
        self.matched = 0  # steps answered by a command

    def declare(self, t_ns: int) -> bool:
        """A new step at t_ns (ignored unless newer than the last one): its command is awaited."""
        if t_ns <= self.last_step:
            return False
        self.last_step, self.awaited = t_ns, t_ns
        self.steps += 1
        return True

    def on_command(self, stamp_ns: int) -> bool:
        """A command computed at `stamp_ns`; True when it answers the awaited step (stamp ≥ step)."""
        if self.awaited is not None and stamp_ns >= self.awaited - MATCH_TOLERANCE_NS:
            self.awaited = None
            self.matched += 1
            return True
        return False

    @property
    def paused(self) -> bool:
        return self.pause_at_ns is not None and self.last_step >= self.pause_at_ns

    def missing(self, deadline_ns: int = 0) -> tuple[str, ...]:
        if self.awaited is not None:
            return ("command",)
        return ("paused",) if self.paused else ()


def step_time_ns(t_s: float, period_s: float) -> int:
    """The newest multiple of `period_s` at or before simulated time `t_s`, in ns (the step grid of
    the IMU: a step exists even when a dropout fault suppressed its sample)."""
    period_ns = round(period_s * 1e9)
    return math.floor((t_s * 1e9 + MATCH_TOLERANCE_NS) / period_ns) * period_ns


def pause_ns(pause_at_s: float) -> int | None:
    """The hold time of a `pause_at_s` parameter: None (never) when negative."""
    return None if pause_at_s < 0 else round(pause_at_s * 1e9)
