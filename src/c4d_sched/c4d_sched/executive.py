"""Single-threaded cyclic executive: absolute deadlines, input / latch / tasks / output phases.

What: tick k starts at t0 + k·tick on a monotonic clock (no drift: deadlines are computed,
never accumulated). Each tick runs (1) the input phase (e.g. drain rclpy subscriptions into a
blackboard), (2) the latch hook (flight-mode requests take effect here, never mid-chain),
(3) the tasks due at k in schedule order, (4) the output phase, then accounts the tick and
sleeps to the next deadline. After an overrun there is no burst catch-up: ticks whose
deadline already passed are skipped and counted, and the tick index keeps following time so
phases stay aligned. Tasks named in `catch_up` (e.g. a simulator's sensor samples, which a real
sensor would never skip) whose release fell on skipped ticks run once at the next executed
tick, in schedule order, instead of being lost.
Why: this is the Paparazzi / ArduPilot / thesis main loop, and the only way to get
deterministic, low-jitter control inside a ROS 2 process (PLATFORM.md: rclpy timers jitter by
hundreds of µs and drift).
The clock is injectable: tests use FakeClock to check order, phases and accounting exactly.
"""

from __future__ import annotations

import gc
import math
import time
from collections.abc import Callable, Mapping
from typing import Protocol

from .profiler import ExecutorReport, Profiler
from .tickschedule import ScheduledTask, TickSchedule

TaskFunction = Callable[[int], None]


class Clock(Protocol):
    def now_ns(self) -> int: ...
    def sleep_until_ns(self, deadline_ns: int) -> None: ...
    def cpu_ns(self) -> int: ...


class MonotonicClock:
    """time.monotonic_ns with a hybrid wait: sleep until `spin_ns` before the deadline, then spin."""

    def __init__(self, spin_ns: int = 200_000) -> None:
        self.spin_ns = spin_ns

    def now_ns(self) -> int:
        return time.monotonic_ns()

    def cpu_ns(self) -> int:
        return time.process_time_ns()

    def sleep_until_ns(self, deadline_ns: int) -> None:
        remaining = deadline_ns - time.monotonic_ns()
        if remaining > self.spin_ns:
            time.sleep((remaining - self.spin_ns) / 1e9)
        while time.monotonic_ns() < deadline_ns:
            pass


class FakeClock:
    """Deterministic clock for tests: time moves only by sleep_until_ns and advance()."""

    def __init__(self, start_ns: int = 0) -> None:
        self.t = start_ns

    def now_ns(self) -> int:
        return self.t

    def cpu_ns(self) -> int:
        return self.t

    def sleep_until_ns(self, deadline_ns: int) -> None:
        self.t = max(self.t, deadline_ns)

    def advance(self, ns: int) -> None:
        self.t += ns


def grid_start_ns(now_ns: int, lead_ns: int, period_ns: int, offset_ns: int = 0) -> int:
    """The first instant at least `lead_ns` after `now_ns` that lies `offset_ns` after a multiple of
    `period_ns` on the clock's own time line (t0 for `CyclicExecutive.start`).
    Why: processes whose executives start on one CLOCK_MONOTONIC grid keep a fixed phase to each
    other for their whole life — the simulator samples the IMU on the grid, the core ticks a fixed
    `offset_ns` later — so a sample's age at the tick that reads it is the same every tick and every
    run, instead of a phase drawn at random by each process's start-up time (a sample landing just
    after the tick that wanted it waits a whole tick: IMU→actuator p99 > 1 tick)."""
    if period_ns <= 0 or not 0 <= offset_ns < period_ns:
        raise ValueError(f"grid offset {offset_ns} ns must lie in [0, {period_ns}) ns")
    earliest = now_ns + lead_ns
    return earliest + (offset_ns - earliest) % period_ns


class CyclicExecutive:
    """Runs a TickSchedule's tasks with absolute deadlines and a profiler (see module docstring)."""

    def __init__(
        self,
        schedule: TickSchedule,
        tasks: Mapping[str, TaskFunction],
        clock: Clock | None = None,
        name: str = "executive",
        input_phase: Callable[[int], None] | None = None,
        latch: Callable[[int], None] | None = None,
        output_phase: Callable[[int], None] | None = None,
        report_period_s: float = 1.0,
        on_report: Callable[[ExecutorReport], None] | None = None,
        manage_gc: bool = False,
        catch_up: frozenset[str] | set[str] = frozenset(),
    ) -> None:
        missing = [t.name for t in schedule.tasks if t.name not in tasks]
        if missing:
            raise ValueError(f"no function for scheduled task(s): {', '.join(missing)}")
        unknown = set(catch_up) - {t.name for t in schedule.tasks}
        if unknown:
            raise ValueError(f"catch_up names unknown task(s): {', '.join(sorted(unknown))}")
        self.catch_up = tuple(t for t in schedule.tasks if t.name in catch_up)
        self._pending: set[str] = set()  # catch-up tasks whose release was skipped
        self.schedule = schedule
        self.functions = dict(tasks)
        self.clock = clock or MonotonicClock()
        self.tick_ns = schedule.tick_us * 1000
        self.input_phase, self.latch, self.output_phase = input_phase, latch, output_phase
        self.report_period_ns = int(report_period_s * 1e9)
        self.on_report = on_report
        self.profiler = Profiler(name, self.tick_ns, [(t.name, t.group, t.divider, t.budget_us) for t in schedule.tasks])
        self._plan = self._precompute()
        self.manage_gc = manage_gc
        self.tick = 0
        self.t0_ns: int | None = None
        self._next_report_ns = 0
        self._stop = False

    def _precompute(self) -> list[tuple[ScheduledTask, ...]] | None:
        hyper = math.lcm(*(t.divider for t in self.schedule.tasks))
        if hyper > 100_000:
            return None
        return [tuple(self.schedule.due(k)) for k in range(hyper)]

    def due(self, tick: int) -> tuple[ScheduledTask, ...]:
        if self._plan is not None:
            return self._plan[tick % len(self._plan)]
        return tuple(self.schedule.due(tick))

    def stop(self) -> None:
        """Ask run() to return after the current tick (safe from a task or a signal handler)."""
        self._stop = True

    def start(self, t0_ns: int | None = None) -> None:
        clock = self.clock
        if self.manage_gc:
            # Python's cyclic GC can stop the world for milliseconds: freeze what exists now and
            # collect only in the slack after a tick (see _collect_in_slack).
            gc.collect()
            gc.freeze()
            gc.disable()
        self.t0_ns = t0_ns if t0_ns is not None else clock.now_ns() + self.tick_ns
        self.tick = 0
        self._next_report_ns = self.t0_ns + self.report_period_ns
        self.profiler.start_window(self.t0_ns, clock.cpu_ns())

    def step(self) -> None:
        """Wait for the current tick's deadline and run it (start() first)."""
        if self.t0_ns is None:
            self.start()
        assert self.t0_ns is not None
        clock, k = self.clock, self.tick
        deadline = self.t0_ns + k * self.tick_ns
        clock.sleep_until_ns(deadline)
        start = clock.now_ns()
        if self.input_phase:
            self.input_phase(k)
        if self.latch:
            self.latch(k)
        functions = self.functions
        due = self.due(k)
        if self._pending:
            due_names = {t.name for t in due} | self._pending
            due = tuple(t for t in self.schedule.tasks if t.name in due_names)
            self._pending = set()
        for task in due:
            t_start = clock.now_ns()
            functions[task.name](k)
            self.profiler.task_ran(task.name, t_start, clock.now_ns())
        if self.output_phase:
            self.output_phase(k)
        end = clock.now_ns()
        next_deadline = deadline + self.tick_ns
        overrun = end > next_deadline
        next_tick = k + 1
        if overrun:  # no burst catch-up: resume at the first deadline still ahead
            next_tick = (end - self.t0_ns) // self.tick_ns + 1
            for task in self.catch_up:  # ... but a catch-up task released in between runs once there
                first_release = k + 1 + (task.phase - (k + 1)) % task.divider
                if first_release < next_tick:
                    self._pending.add(task.name)
        self.profiler.tick_done(start - deadline, end - start, overrun, next_tick - k - 1)
        self.tick = next_tick
        if self.manage_gc:
            self._collect_in_slack(self.t0_ns + next_tick * self.tick_ns - clock.now_ns())
        boundary = self.t0_ns + next_tick * self.tick_ns  # windows end on tick deadlines: no drift
        if boundary >= self._next_report_ns:
            report = self.profiler.report(boundary, clock.cpu_ns())
            self._next_report_ns = boundary + self.report_period_ns
            if self.on_report:
                self.on_report(report)

    def _collect_in_slack(self, slack_ns: int) -> None:
        """Young-generation collection when enough garbage piled up and the tick left time."""
        if slack_ns > self.tick_ns // 2 and gc.get_count()[0] > 2000:
            gc.collect(0 if gc.get_count()[1] < 10 else 1)

    def release_gc(self) -> None:
        """Give the garbage collector back to Python (after run(), when manage_gc was set)."""
        if self.manage_gc:
            gc.enable()
            gc.unfreeze()

    def run(self, max_ticks: int | None = None, should_stop: Callable[[], bool] | None = None) -> None:
        """Run ticks until stop(), should_stop() is true, or max_ticks ticks have elapsed."""
        if self.t0_ns is None:
            self.start()
        end_tick = None if max_ticks is None else self.tick + max_ticks
        # A stop() that came before run() (a SIGINT while the node was still starting) is kept, not
        # wiped: clearing the flag here made the core ignore such a signal and run on. The flag is
        # consumed when run() returns, so a later run() starts afresh.
        try:
            while not self._stop and (end_tick is None or self.tick < end_tick):
                if should_stop is not None and should_stop():
                    break
                self.step()
        finally:
            self._stop = False
