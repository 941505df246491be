"""Core stalls from executor statistics on a fake clock: long ticks, skipped ticks, silent statistics
while the core is in the graph (stalled, not dead), repetition, and the monitor's own stall."""

import math

import pytest

from c4d_health.core_stall import CoreStallMonitor, CoreStallReport, StatsWindow
from c4d_health.policy import CoreStallLimits

PERIOD = 0.1
RATE = 500.0  # Hz: a 2 ms tick
CLEAN = StatsWindow(RATE, 130.0, 2)  # 2.6 ms worst tick, 2 skipped: a normal flight window


def window(worst_ms: float, skipped: int = 0) -> StatsWindow:
    return StatsWindow(RATE, worst_ms / (1000.0 / RATE) * 100.0, skipped)


def fly(m: CoreStallMonitor, t0: float, t1: float, stats: dict[float, StatsWindow] | None = None,
        present: bool | None = True) -> dict[float, CoreStallReport]:
    """Tick every PERIOD from t0 to t1; statistics arrive at whole seconds (`stats` overrides, None entries: none)."""
    reports, t = {}, t0
    while t < t1 - 1e-9:
        t = round(t + PERIOD, 9)
        if abs(t - round(t)) < 1e-9:
            w = (stats or {}).get(round(t), CLEAN)
            if w is not None:
                m.on_stats(t - 0.01, w)
        reports[t] = m.check(t, present)
    return reports


def monitor(**limits) -> CoreStallMonitor:
    return CoreStallMonitor(CoreStallLimits(**limits), PERIOD, start=0.0)


def test_worst_tick_from_the_load():
    assert window(332.0).worst_tick_ms == pytest.approx(332.0)
    assert CLEAN.worst_tick_ms == pytest.approx(2.6)
    assert math.isnan(StatsWindow(0.0, 100.0, 0).worst_tick_ms)


def test_clean_flight_has_no_stall():
    reports = fly(monitor(), 0.0, 30.0)
    assert all(r == CoreStallReport() for r in reports.values())


def test_one_long_tick_is_one_stall_with_the_numbers_and_clears_with_the_next_window():
    reports = fly(monitor(), 0.0, 8.0, {3: window(332.0, 165)})
    assert reports[3.0] == CoreStallReport("worst tick 332 ms, 165 skipped ticks")
    assert reports[3.9].stall and reports[4.0] == CoreStallReport()  # the next clean window clears it
    assert fly(monitor(), 0.0, 4.0, {3: window(25.0, 3)})[3.0].stall == "worst tick 25 ms, 3 skipped ticks"
    assert fly(monitor(), 0.0, 4.0, {3: window(20.0, 25)})[3.0] == CoreStallReport()  # at the limits: no stall


def test_many_skipped_ticks_alone_are_a_stall():
    assert fly(monitor(), 0.0, 4.0, {3: window(6.0, 26)})[3.0].stall == "worst tick 6 ms, 26 skipped ticks"


def test_repeated_stalls_within_the_window():
    stalls = {2: window(30.0), 5: window(40.0), 9: window(50.0, 30)}
    reports = fly(monitor(), 0.0, 25.0, stalls)
    assert not reports[8.9].repeated  # two so far
    assert reports[9.0].repeated == "3 stalls within 10 s; worst tick 50 ms, 30 skipped ticks"
    assert reports[10.0].repeated and not reports[10.0].stall  # still 3 within 10 s, none right now
    assert not reports[12.1].repeated  # the first (t = 1.99) left the window
    spread = fly(monitor(), 0.0, 30.0, {2: window(30.0), 13: window(30.0), 24: window(30.0)})
    assert not any(r.repeated for r in spread.values())


def test_silent_statistics_while_the_core_is_in_the_graph_is_a_stall():
    silent_from_5 = dict.fromkeys(range(5, 30))
    reports = fly(monitor(), 0.0, 12.0, silent_from_5)  # last statistics at 3.99 s
    assert reports[5.4] == CoreStallReport()
    assert reports[5.6].stall == "no executor statistics for 1.6 s (core still in the ROS graph)"
    assert not reports[6.5].repeated
    assert reports[7.6].repeated.startswith("3 stalls within 10 s; no executor statistics for 3.6 s")
    gone = fly(monitor(), 0.0, 12.0, silent_from_5, present=False)  # a dead core is node_dead's, not ours
    assert all(r == CoreStallReport() for r in gone.values())
    unknown = fly(monitor(), 0.0, 12.0, silent_from_5, present=None)
    assert all(r == CoreStallReport() for r in unknown.values())
    back = fly(monitor(), 0.0, 20.0, dict.fromkeys(range(5, 8)))  # statistics again from 8 s
    assert back[7.0].stall and back[8.0] == CoreStallReport(repeated="3 stalls within 10 s")  # 3 s silent: 3 stalls
    assert back[17.6] == CoreStallReport()  # they age out of the window


def test_no_statistics_yet_is_not_a_stall_and_the_monitor_stall_is_discounted():
    assert all(r == CoreStallReport() for r in fly(monitor(), 0.0, 10.0, dict.fromkeys(range(0, 11))).values())
    m = monitor()
    fly(m, 0.0, 3.0)
    # health itself is descheduled for 2 s: its late tick comes before the queued statistics
    assert m.check(5.0, True) == CoreStallReport()
    m.on_stats(5.001, CLEAN)
    assert fly(m, 5.0, 8.0)[8.0] == CoreStallReport()
