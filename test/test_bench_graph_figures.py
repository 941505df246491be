"""bench/graph_figures.py, the arithmetic behind bench/graph_load.py (issue 16): ROS-free, no graph, milliseconds.

A wrong figure in a benchmark table is worse than none: these pin the parsing of the manifest's rate
words, the stall attribution of overruns, CPU over a window with a restarted process, the grouping of a
composed process and the table layout."""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
from graph_figures import (
    ProcessSeries,
    ProcFigures,
    StatsWindow,
    core_figures,
    delivered_rates,
    markdown_table,
    nominal_hz,
    nominal_rates,
    percentiles,
    processes,
    read_proc,
    side_by_side,
    stall_summary,
)


@pytest.mark.parametrize("words,hz", [
    ("500 Hz", 500.0), ("10 Hz, 50 ms latency", 10.0), ("500 Hz (per IMU sample)", 500.0),
    ("50 Hz (parameter)", 50.0), ("every tick (500 Hz)", 500.0), ("1 Hz", 1.0),
    ("1 Hz + on change", None), ("on change + 5 Hz", None), ("50 Hz while a mission runs", None),
    ("per capture", None), ("once", None), ("lockstep only: per step (500 Hz simulated)", None),
])
def test_nominal_rate_words(words, hz):
    assert nominal_hz(words) == hz


def test_nominal_rates_follow_the_imu_and_tick_rate_of_the_variant():
    rates = {"sensors/imu": "500 Hz, every sample", "navigation/state": "500 Hz (per IMU sample)",
             "control/actuators": "every tick (500 Hz)", "sensors/gps": "10 Hz", "mission/state": "on change + 5 Hz"}
    assert nominal_rates(rates, 500.0, 500.0) == {"sensors/imu": 500.0, "navigation/state": 500.0,
                                                  "control/actuators": 500.0, "sensors/gps": 10.0}
    fast = nominal_rates(rates, 1000.0, 1000.0)
    assert fast["sensors/imu"] == fast["navigation/state"] == fast["control/actuators"] == 1000.0
    assert fast["sensors/gps"] == 10.0


def test_delivered_rate_skips_the_latched_start_and_counts_inside_the_window():
    ts = [100.0] * 5 + [100.0 + k / 10 for k in range(10, 190)]  # 5 latched at the start, then 10 Hz
    assert delivered_rates({"x": ts}, 100.0, 120.0) == {"x": pytest.approx(10.0, rel=0.01)}


def window(end, overruns, load, p50=5.0, p99=50.0, mx=80.0):
    return StatsWindow(end, 1.0, 500, overruns, load, p50, p99, mx, 500.0)


def test_overruns_in_a_window_with_a_platform_stall_are_explained_the_others_not():
    windows = [window(10.0, 0, 60.0), window(11.0, 3, 400.0, mx=9000.0), window(12.0, 2, 150.0, p99=70.0)]
    stalls = [(10.0, 0.2), (11.0, 8.5), (12.0, 0.3)]  # the probe's second (10, 11] stalled 8.5 ms
    f = core_figures(windows, stalls, threshold_ms=1.0)
    assert (f.ticks, f.overruns, f.overruns_unexplained) == (1500, 5, 2)
    assert (f.worst_load_percent, f.worst_load_unstalled_percent) == (400.0, 150.0)
    assert (f.jitter_p50_us, f.jitter_p99_us, f.jitter_p99_worst_us, f.jitter_max_us) == (5.0, 50.0, 70.0, 9000.0)
    assert (f.stalled_windows, f.windows) == (1, 3)
    assert core_figures(windows, [], 1.0).overruns_unexplained == 5  # no stall seen: nothing explained


def test_cpu_over_the_window_adds_the_parts_of_a_restarted_process():
    s = ProcessSeries("mission")
    s.samples = [(0.0, 1, ProcFigures(10.0, 0, None)), (1.0, 1, ProcFigures(10.5, 0, None)),
                 (2.0, 1, ProcFigures(11.0, 0, None)), (3.0, 2, ProcFigures(0.2, 0, None)),
                 (4.0, 2, ProcFigures(0.4, 0, None)), (9.0, 2, ProcFigures(5.0, 0, None))]
    assert s.cpu_percent(1.0, 4.0) == pytest.approx(100.0 * (0.5 + 0.2) / 3.0)
    assert s.cpu_percent(8.0, 8.5) is None


def test_memory_is_the_peak_of_the_readings_in_the_window():
    s = ProcessSeries("core", [(0.0, 1, ProcFigures(1.0, 900, 500)), (5.0, 1, ProcFigures(2.0, 800, 450)),
                               (10.0, 1, ProcFigures(3.0, 0, None)), (15.0, 1, ProcFigures(4.0, 850, 470))])
    assert s.memory_kb(4.0, 16.0) == (850, 470)


def test_a_composed_process_is_one_row_naming_its_nodes_and_stopped_ones_are_left_out():
    state = {"nodes": {"sim": {"pid": 11}, "ground": {"pid": 12, "members": ["mission", "health"]},
                       "core": {"pid": None}, "a": {"pid": 13}, "b": {"pid": 13}}}
    assert processes(state) == {11: "sim", 12: "mission+health", 13: "a+b"}


def test_read_proc_of_this_process_and_of_a_gone_one():
    me = read_proc(os.getpid())
    assert me is not None and me.cpu_s > 0 and me.rss_kb > 1000 and (me.pss_kb is None or me.pss_kb > 0)
    assert read_proc(2 ** 22 + 12345) is None


def test_percentiles_and_stall_summary():
    assert percentiles([3.0, 1.0, 2.0, 4.0], [50, 100]) == [2.0, 4.0]
    assert all(math.isnan(v) for v in percentiles([], [50]))
    assert stall_summary([(1.0, 0.1), (2.0, 5.0), (3.0, 0.2), (9.0, 30.0)], 0.0, 4.0, 1.0) == (0.2, 5.0, 1)


def test_tables_put_variants_side_by_side():
    rows = [("CPU total", [150.0, None]), "section", ("flight", ["completed", "aborted"]), ("overruns %", [0.0123, 2], 3)]
    text = side_by_side(["today", "board"], rows).splitlines()
    assert text[0].split() == ["today", "board"]
    assert text[1].split() == ["CPU", "total", "150.0", "-"] and text[2] == "section"
    md = markdown_table(["today", "board"], rows).splitlines()
    assert md[2] == "| CPU total | 150.0 | - |" and md[3].startswith("| **section** |")
    assert text[4].split() == ["overruns", "%", "0.012", "2"] and md[5] == "| overruns % | 0.012 | 2 |"
