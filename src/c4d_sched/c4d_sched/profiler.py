"""Cyclic-executive profiler: per-task and per-tick figures over a report window.

Per task (columns of COMP4DRONES D3.3 figures 48–51): executions, period mean/std (start to
start), rate, duty (execution time) mean/std/min/max, budget overruns, CPU %. Per tick:
load (busy time / tick), release jitter (start − deadline) mean/max/p99, overruns (work that
ran past the next deadline), skipped ticks. `report()` closes the window and returns an
ExecutorReport, which nodes turn into c4d_interfaces/ExecutorStats and `format_table` prints.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field


@dataclass
class _TaskWindow:
    count: int = 0
    last_start_ns: int | None = None
    period_n: int = 0
    period_sum: float = 0.0
    period_sq: float = 0.0
    duty_sum: float = 0.0
    duty_sq: float = 0.0
    duty_min: float = math.inf
    duty_max: float = 0.0
    overruns: int = 0


@dataclass(frozen=True)
class TaskReport:
    name: str
    group: str
    divider: int
    count: int
    period_mean_us: float
    period_std_us: float
    rate_hz: float
    duty_mean_us: float
    duty_std_us: float
    duty_min_us: float
    duty_max_us: float
    budget_us: float
    budget_overruns: int
    cpu_percent: float


@dataclass(frozen=True)
class ExecutorReport:
    executor: str
    tick_rate_hz: float
    window_s: float
    ticks_total: int
    overruns_total: int
    skipped_ticks_total: int
    ticks: int
    overruns: int
    skipped_ticks: int
    load_mean_percent: float
    load_max_percent: float
    release_jitter_mean_us: float
    release_jitter_max_us: float
    release_jitter_p99_us: float
    release_jitter_p50_us: float
    cpu_percent: float
    tasks: tuple[TaskReport, ...] = field(default_factory=tuple)


def _std(total: float, squares: float, n: int) -> float:
    if n < 2:
        return 0.0
    mean = total / n
    return math.sqrt(max(0.0, squares / n - mean * mean))


class Profiler:
    """Accumulates one window of figures; all times in nanoseconds from the executive clock."""

    def __init__(self, name: str, tick_ns: int, tasks: list[tuple[str, str, int, int]]) -> None:
        self.name = name
        self.tick_ns = tick_ns
        self.meta = {n: (g, d, b) for n, g, d, b in tasks}
        self.order = [n for n, *_ in tasks]
        self.ticks_total = self.overruns_total = self.skipped_total = 0
        self._last_starts: dict[str, int | None] = {n: None for n in self.order}
        self._reset(None, None)

    def _reset(self, wall_ns: int | None, cpu_ns: int | None) -> None:
        self.window_start_ns, self.window_cpu_ns = wall_ns, cpu_ns
        self.tasks = {n: _TaskWindow(last_start_ns=self._last_starts[n]) for n in self.order}
        self.ticks = self.overruns = self.skipped = 0
        self.busy_sum = 0
        self.busy_max = 0
        self.jitters: list[int] = []

    def start_window(self, wall_ns: int, cpu_ns: int) -> None:
        self.window_start_ns, self.window_cpu_ns = wall_ns, cpu_ns

    def task_ran(self, name: str, start_ns: int, end_ns: int) -> None:
        w = self.tasks[name]
        duty = (end_ns - start_ns) / 1000.0
        w.count += 1
        w.duty_sum += duty
        w.duty_sq += duty * duty
        w.duty_min = min(w.duty_min, duty)
        w.duty_max = max(w.duty_max, duty)
        if duty > self.meta[name][2]:
            w.overruns += 1
        if w.last_start_ns is not None:
            period = (start_ns - w.last_start_ns) / 1000.0
            w.period_n += 1
            w.period_sum += period
            w.period_sq += period * period
        w.last_start_ns = start_ns
        self._last_starts[name] = start_ns

    def tick_done(self, jitter_ns: int, busy_ns: int, overrun: bool, skipped: int) -> None:
        self.ticks += 1
        self.ticks_total += 1
        self.jitters.append(jitter_ns)
        self.busy_sum += busy_ns
        self.busy_max = max(self.busy_max, busy_ns)
        if overrun:
            self.overruns += 1
            self.overruns_total += 1
        self.skipped += skipped
        self.skipped_total += skipped

    def report(self, wall_ns: int, cpu_ns: int) -> ExecutorReport:
        """Close the window at (wall_ns, process cpu_ns) and start the next one."""
        start = self.window_start_ns if self.window_start_ns is not None else wall_ns
        window_ns = max(1, wall_ns - start)
        window_s = window_ns / 1e9
        cpu_start = self.window_cpu_ns if self.window_cpu_ns is not None else cpu_ns
        tasks = []
        for name in self.order:
            w = self.tasks[name]
            group, divider, budget = self.meta[name]
            mean_period = w.period_sum / w.period_n if w.period_n else 0.0
            tasks.append(TaskReport(
                name, group, divider, w.count, mean_period, _std(w.period_sum, w.period_sq, w.period_n),
                w.count / window_s, w.duty_sum / w.count if w.count else 0.0, _std(w.duty_sum, w.duty_sq, w.count),
                w.duty_min if w.count else 0.0, w.duty_max, float(budget), w.overruns,
                100.0 * w.duty_sum * 1000.0 / window_ns,
            ))
        jitters = sorted(self.jitters)
        p99, p50 = (jitters[min(len(jitters) - 1, math.ceil(q * len(jitters)) - 1)] / 1000.0 if jitters else 0.0
                    for q in (0.99, 0.5))
        report = ExecutorReport(
            executor=self.name,
            tick_rate_hz=1e9 / self.tick_ns,
            window_s=window_s,
            ticks_total=self.ticks_total,
            overruns_total=self.overruns_total,
            skipped_ticks_total=self.skipped_total,
            ticks=self.ticks,
            overruns=self.overruns,
            skipped_ticks=self.skipped,
            load_mean_percent=100.0 * self.busy_sum / (self.ticks * self.tick_ns) if self.ticks else 0.0,
            load_max_percent=100.0 * self.busy_max / self.tick_ns,
            release_jitter_mean_us=sum(jitters) / len(jitters) / 1000.0 if jitters else 0.0,
            release_jitter_max_us=jitters[-1] / 1000.0 if jitters else 0.0,
            release_jitter_p99_us=p99,
            release_jitter_p50_us=p50,
            cpu_percent=100.0 * (cpu_ns - cpu_start) / window_ns,
            tasks=tuple(tasks),
        )
        self._reset(wall_ns, cpu_ns)
        return report


def format_table(report: ExecutorReport) -> str:
    """Text table of a report, one line per task (D3.3 figures 48–51 columns) + tick summary."""
    lines = [
        f"{report.executor}: {report.tick_rate_hz:.0f} Hz, window {report.window_s:.2f} s, {report.ticks} ticks, "
        f"load mean {report.load_mean_percent:.1f} % max {report.load_max_percent:.1f} %, jitter mean "
        f"{report.release_jitter_mean_us:.1f} µs p99 {report.release_jitter_p99_us:.1f} µs max "
        f"{report.release_jitter_max_us:.1f} µs, overruns {report.overruns} ({report.overruns_total} total), "
        f"skipped {report.skipped_ticks} ({report.skipped_ticks_total} total), CPU {report.cpu_percent:.1f} %",
        f"{'task':<20}{'group':<12}{'count':>7}{'period µs':>11}{'± std':>9}{'Hz':>8}{'duty µs':>9}"
        f"{'± std':>8}{'min':>8}{'max':>8}{'budget':>8}{'over':>6}{'CPU %':>7}",
    ]
    for t in report.tasks:
        lines.append(
            f"{t.name:<20}{t.group:<12}{t.count:>7}{t.period_mean_us:>11.1f}{t.period_std_us:>9.1f}{t.rate_hz:>8.1f}"
            f"{t.duty_mean_us:>9.1f}{t.duty_std_us:>8.1f}{t.duty_min_us:>8.1f}{t.duty_max_us:>8.1f}"
            f"{t.budget_us:>8.0f}{t.budget_overruns:>6}{t.cpu_percent:>7.2f}"
        )
    return "\n".join(lines)
