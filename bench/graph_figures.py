"""Figures of bench/graph_load.py, ROS-free: /proc accounting, executor-window and stall-probe
arithmetic, nominal rates from the interface manifest's words, and the side-by-side table.

Kept apart from the benchmark's orchestration so test/test_bench_graph_figures.py can check the
arithmetic in milliseconds without a graph.
"""

from __future__ import annotations

import math
import os
import re
import statistics
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

CLOCK_TICKS = os.sysconf("SC_CLK_TCK")
IMU_CHAIN = ("sensors/imu", "perception/imu", "navigation/state")  # one message per IMU sample
_HZ = re.compile(r"(\d+(?:\.\d+)?) Hz(?:,.*| \(.*)?")
_TICK = re.compile(r"every tick \((\d+(?:\.\d+)?) Hz\)")


# ----------------------------------------------------------------------------- nominal rates
def nominal_hz(rate: str) -> float | None:
    """The fixed rate a manifest rate text promises ('500 Hz', '10 Hz, 50 ms latency', 'every tick
    (500 Hz)'), None for conditional or event rates ('on change + 5 Hz', '50 Hz while ...', '1 Hz + on change')."""
    if "while" in rate:
        return None
    m = _HZ.fullmatch(rate) or _TICK.fullmatch(rate)
    return float(m.group(1)) if m else None


def nominal_rates(rates: Mapping[str, str], imu_hz: float, tick_hz: float) -> dict[str, float]:
    """Topic -> nominal Hz for this deployment: the manifest's words, with the IMU chain at the sim's IMU
    rate and 'every tick' topics at the core's tick rate (both 500 Hz unless a variant changes them)."""
    out = {}
    for name, rate in rates.items():
        hz = nominal_hz(rate)
        if hz is None:
            continue
        out[name] = imu_hz if name in IMU_CHAIN else tick_hz if rate.startswith("every tick") else hz
    return out


def delivered_rates(times: Mapping[str, Sequence[float]], start: float, end: float, margin: float = 1.0) -> dict[str, float]:
    """Messages per second of each topic within [start + margin, end - margin] (the margin skips the
    latched values a recording writes at its start)."""
    a, b = start + margin, end - margin
    if b <= a:
        return {}
    return {name: sum(1 for t in ts if a <= t <= b) / (b - a) for name, ts in times.items()}


# ----------------------------------------------------------------------------- processes
@dataclass(frozen=True)
class ProcFigures:
    """One /proc reading of a process: CPU seconds (all threads, user + system), RSS and PSS [kB]."""

    cpu_s: float
    rss_kb: int
    pss_kb: int | None  # None when smaps_rollup was not read (or not readable)


def read_proc(pid: int, memory: bool = True) -> ProcFigures | None:
    """utime + stime of /proc/<pid>/stat, VmRSS of status, Pss of smaps_rollup; None if the process is gone."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        cpu = (int(fields[11]) + int(fields[12])) / CLOCK_TICKS
        if not memory:
            return ProcFigures(cpu, 0, None)
        rss = next(int(line.split()[1]) for line in Path(f"/proc/{pid}/status").read_text().splitlines()
                   if line.startswith("VmRSS:"))
    except (OSError, StopIteration, IndexError, ValueError):
        return None
    pss = None
    try:
        pss = next(int(line.split()[1]) for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines()
                   if line.startswith("Pss:"))
    except (OSError, StopIteration, IndexError, ValueError):
        pass
    return ProcFigures(cpu, rss, pss)


def processes(state: Mapping) -> dict[int, str]:
    """pid -> row label from the supervisor's supervisor.json: the node names sharing a pid (a composed
    process) joined with '+', in the file's order; entries without a pid (stopped) are left out."""
    rows: dict[int, list[str]] = {}
    for name, entry in state.get("nodes", {}).items():
        pid = entry.get("pid") if isinstance(entry, Mapping) else None
        if pid:
            members = entry.get("members") or entry.get("node_names") or [name]
            rows.setdefault(int(pid), []).extend(m for m in members if m not in rows.get(int(pid), []))
    return {pid: "+".join(names) for pid, names in rows.items()}


@dataclass
class ProcessSeries:
    """Readings of one row (label) over time: (wall time, pid, figures)."""

    label: str
    samples: list[tuple[float, int, ProcFigures]] = field(default_factory=list)

    def cpu_percent(self, start: float, end: float) -> float | None:
        """CPU over [start, end] in % of one core: per pid, last minus first reading inside the window
        (a restarted process contributes each of its pids' parts), over the span the readings cover."""
        inside = [s for s in self.samples if start <= s[0] <= end]
        if len(inside) < 2:
            return None
        used = 0.0
        for pid in {p for _, p, _ in inside}:
            mine = [s for s in inside if s[1] == pid]
            used += mine[-1][2].cpu_s - mine[0][2].cpu_s
        return 100.0 * used / (inside[-1][0] - inside[0][0])

    def memory_kb(self, start: float, end: float) -> tuple[int | None, int | None]:
        """Peak RSS and peak PSS [kB] among the memory readings inside the window."""
        inside = [s[2] for s in self.samples if start <= s[0] <= end and s[2].rss_kb]
        rss = max((f.rss_kb for f in inside), default=None)
        pss = max((f.pss_kb for f in inside if f.pss_kb is not None), default=None)
        return rss, pss


# ----------------------------------------------------------------------------- executor windows
@dataclass(frozen=True)
class StatsWindow:
    """One gnc/executor_stats report: the window (end - period, end] in wall seconds."""

    end: float
    period_s: float
    ticks: int
    overruns: int
    load_max_percent: float
    jitter_p50_us: float
    jitter_p99_us: float
    jitter_max_us: float
    tick_hz: float


def stalled(window: StatsWindow, stalls: Sequence[tuple[float, float]], threshold_ms: float) -> bool:
    """True if a probe second (t - 1, t] overlapping the window saw an oversleep above threshold_ms."""
    start = window.end - window.period_s
    return any(ms > threshold_ms and t > start and t - 1.0 < window.end for t, ms in stalls)


@dataclass(frozen=True)
class CoreFigures:
    ticks: int
    overruns: int
    overruns_unexplained: int  # in windows where the stall probe saw no platform stall
    worst_load_percent: float
    worst_load_unstalled_percent: float  # worst tick load over the windows without a platform stall
    jitter_p50_us: float  # median of the windows' medians
    jitter_p99_us: float  # median of the windows' p99
    jitter_p99_worst_us: float  # worst window's p99
    jitter_max_us: float
    stalled_windows: int
    windows: int


def core_figures(windows: Sequence[StatsWindow], stalls: Sequence[tuple[float, float]], threshold_ms: float) -> CoreFigures:
    """Overruns (all / not coinciding with a platform stall), worst tick load and release jitter over the
    executor's report windows. The core publishes percentiles per window, not samples: the whole-run p50
    and p99 printed are the medians of the windows' values (and the worst window's p99)."""
    if not windows:
        nan = math.nan
        return CoreFigures(0, 0, 0, nan, nan, nan, nan, nan, nan, 0, 0)
    calm = [w for w in windows if not stalled(w, stalls, threshold_ms)]
    return CoreFigures(
        ticks=sum(w.ticks for w in windows),
        overruns=sum(w.overruns for w in windows),
        overruns_unexplained=sum(w.overruns for w in calm),
        worst_load_percent=max(w.load_max_percent for w in windows),
        worst_load_unstalled_percent=max((w.load_max_percent for w in calm), default=math.nan),
        jitter_p50_us=statistics.median(w.jitter_p50_us for w in windows),
        jitter_p99_us=statistics.median(w.jitter_p99_us for w in windows),
        jitter_p99_worst_us=max(w.jitter_p99_us for w in windows),
        jitter_max_us=max(w.jitter_max_us for w in windows),
        stalled_windows=len(windows) - len(calm),
        windows=len(windows),
    )


def percentiles(values: Sequence[float], qs: Iterable[float]) -> list[float]:
    """Nearest-rank percentiles (q in 0..100) of values; NaN for an empty sequence."""
    ordered = sorted(values)
    if not ordered:
        return [math.nan for _ in qs]
    return [ordered[min(len(ordered) - 1, max(0, math.ceil(q / 100.0 * len(ordered)) - 1))] for q in qs]


def stall_summary(stalls: Sequence[tuple[float, float]], start: float, end: float,
                  threshold_ms: float) -> tuple[float, float, int]:
    """(median, worst, seconds above threshold) of the probe's per-second worst oversleep inside [start, end]."""
    inside = [ms for t, ms in stalls if start <= t <= end]
    if not inside:
        return math.nan, math.nan, 0
    return statistics.median(inside), max(inside), sum(1 for ms in inside if ms > threshold_ms)


# ----------------------------------------------------------------------------- table
Cell = float | int | str | None


def fmt(value: Cell, digits: int = 1) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    if isinstance(value, str):
        return value
    if isinstance(value, int):
        return str(value)
    return f"{value:.{digits}f}"


Row = tuple[str, Sequence[Cell]] | tuple[str, Sequence[Cell], int] | str


def _digits(row: tuple, default: int) -> int:
    return row[2] if len(row) > 2 else default


def side_by_side(variants: Sequence[str], rows: Sequence[Row], digits: int = 1) -> str:
    """A text table: one column per variant, one line per (label, cells[, digits]); a bare string is a section line."""
    cells = [fmt(c, _digits(r, digits)) for r in rows if not isinstance(r, str) for c in r[1]]
    width = max([12, *(len(v) + 2 for v in variants), *(len(c) + 2 for c in cells)])
    label_w = max([10, *(len(r[0]) for r in rows if not isinstance(r, str))]) + 2
    lines = [" " * label_w + "".join(f"{v:>{width}}" for v in variants)]
    for row in rows:
        if isinstance(row, str):
            lines.append(row)
            continue
        lines.append(f"{row[0]:<{label_w}}" + "".join(f"{fmt(c, _digits(row, digits)):>{width}}" for c in row[1]))
    return "\n".join(lines)


def markdown_table(variants: Sequence[str], rows: Sequence[Row], digits: int = 1) -> str:
    """The same table as GitHub markdown (section lines become bold rows)."""
    lines = ["| figure | " + " | ".join(variants) + " |", "|---|" + "---:|" * len(variants)]
    for row in rows:
        if isinstance(row, str):
            lines.append(f"| **{row.strip()}** |" + " |" * len(variants))
        else:
            lines.append(f"| {row[0]} | " + " | ".join(fmt(c, _digits(row, digits)) for c in row[1]) + " |")
    return "\n".join(lines)
