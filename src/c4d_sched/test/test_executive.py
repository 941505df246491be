"""Cyclic executive with a fake clock: order, dividers, phases, accounting, overrun/skip."""

import pytest

from c4d_sched.executive import CyclicExecutive, FakeClock, grid_start_ns
from c4d_sched.profiler import Profiler, format_table
from c4d_sched.tickschedule import ScheduleConfigError, parse_config, schedule_from_config

CONFIG = {
    "tick_hz": 500,
    "phase_method": "gcdplus",
    "tasks": [
        {"name": "mixer", "group": "actuators", "rate_hz": 500, "budget_us": 50},
        {"name": "rate", "group": "control", "rate_hz": 500, "budget_us": 100},
        {"name": "state", "group": "estimation", "rate_hz": 500, "budget_us": 80},
        {"name": "position", "group": "control", "rate_hz": 100, "budget_us": 200},
        {"name": "telemetry", "group": "telemetry", "rate_hz": 50, "budget_us": 400},
        {"name": "logger", "group": "default", "rate_hz": 10, "budget_us": 900},
        {"name": "fixed", "group": "guidance", "divider": 4, "budget_us": 100, "phase": 3},
    ],
}


def run(schedule, ticks, work_ns=None, clock=None, latch=None):
    clock = clock or FakeClock()
    log = []

    def make(name):
        def fn(k):
            log.append((k, name))
            clock.advance((work_ns or {}).get(name, 10_000))
        return fn

    ex = CyclicExecutive(schedule, {t.name: make(t.name) for t in schedule.tasks}, clock, latch=latch,
                         report_period_s=0.1)
    ex.start(t0_ns=0)
    ex.run(max_ticks=ticks)
    return ex, log


def test_group_order_dividers_and_phases():
    schedule = schedule_from_config(CONFIG)
    ex, log = run(schedule, 100)
    by = {t.name: t for t in schedule.tasks}
    assert by["fixed"].phase == 3 and by["fixed"].divider == 4
    for name, t in by.items():
        ticks = [k for k, n in log if n == name]
        assert ticks == [k for k in range(100) if k % t.divider == t.phase], name
    groups = ["input", "estimation", "guidance", "control", "actuators", "telemetry", "default"]
    for k in range(100):
        names = [n for kk, n in log if kk == k]
        assert [by[n].group for n in names] == sorted((by[n].group for n in names), key=groups.index)
        assert names.index("state") < names.index("rate") < names.index("mixer")


def test_gcdplus_phases_lower_the_max_tick_load_than_zero_phases():
    gcd = schedule_from_config(CONFIG)
    zero = schedule_from_config(CONFIG, method_override="zero")
    assert gcd.max_tick_load_us < zero.max_tick_load_us
    # zero phasing releases position, telemetry, logger and fixed-free tasks in tick 0 together
    assert zero.max_tick_load_us == 50 + 100 + 80 + 200 + 400 + 900
    assert gcd.max_tick_load_us <= 2000


def test_stats_arithmetic():
    schedule = schedule_from_config({"tick_hz": 1000, "tasks": [
        {"name": "a", "group": "control", "rate_hz": 1000, "budget_us": 100},
        {"name": "b", "group": "default", "rate_hz": 250, "budget_us": 100}]})
    reports = []
    clock = FakeClock()
    durations = iter([50_000, 150_000] * 1000)

    def a(k):
        clock.advance(next(durations))

    def b(k):
        clock.advance(20_000)

    ex = CyclicExecutive(schedule, {"a": a, "b": b}, clock, report_period_s=0.1, on_report=reports.append)
    ex.start(t0_ns=0)
    ex.run(max_ticks=200)
    r = reports[0]
    assert r.ticks == 100 and r.overruns == 0 and r.skipped_ticks == 0
    ta = next(t for t in r.tasks if t.name == "a")
    assert ta.count == 100 and ta.duty_mean_us == pytest.approx(100.0) and ta.duty_std_us == pytest.approx(50.0)
    assert ta.duty_min_us == 50.0 and ta.duty_max_us == 150.0 and ta.budget_overruns == 50
    assert ta.period_mean_us == pytest.approx(1000.0) and ta.rate_hz == pytest.approx(1000.0, rel=0.02)
    tb = next(t for t in r.tasks if t.name == "b")
    assert tb.count == 25 and tb.period_mean_us == pytest.approx(4000.0) and tb.budget_overruns == 0
    assert r.release_jitter_max_us == 0.0
    assert "a" in format_table(r) and "D3.3" not in format_table(r)


def test_overrun_is_counted_and_ticks_are_skipped_not_bursted():
    schedule = schedule_from_config({"tick_hz": 1000, "tasks": [
        {"name": "a", "group": "control", "rate_hz": 1000, "budget_us": 100}]})
    clock = FakeClock()
    starts = []

    def a(k):
        starts.append((k, clock.now_ns()))
        clock.advance(2_500_000 if k == 3 else 100_000)  # tick 3 runs 2.5 ms

    ex = CyclicExecutive(schedule, {"a": a}, clock, report_period_s=100)
    ex.start(t0_ns=0)
    ex.run(max_ticks=10)
    ticks = [k for k, _ in starts]
    assert ticks == [0, 1, 2, 3, 6, 7, 8, 9]  # ticks 4 and 5 skipped, no burst
    assert all(t == k * 1_000_000 for k, t in starts)  # every start on its own deadline: no drift
    assert ex.profiler.overruns_total == 1 and ex.profiler.skipped_total == 2


def test_latch_runs_before_tasks_every_tick():
    schedule = schedule_from_config({"tick_hz": 500, "tasks": [
        {"name": "a", "group": "control", "rate_hz": 500, "budget_us": 100}]})
    seen = []
    ex, log = run(schedule, 5, latch=lambda k: seen.append(k))
    assert seen == [0, 1, 2, 3, 4]


@pytest.mark.parametrize("change,message", [
    ({"group": "magic"}, "unknown group 'magic'"),
    ({"rate_hz": 300}, "rate_hz 300 does not divide the tick rate 500 Hz"),
    ({"budget_us": 2500}, "budget_us 2500 must be in 1..2000"),
    ({"phase": 7}, "phase must be 'auto' or an integer in 0..4"),
    ({"colour": 1}, "unknown field(s) colour"),
])
def test_bad_task_config_names_the_field(change, message):
    task = {"name": "x", "group": "control", "rate_hz": 100, "budget_us": 100, **change}
    with pytest.raises(ScheduleConfigError, match=message.replace("(", r"\(").replace(")", r"\)")):
        parse_config({"tick_hz": 500, "tasks": [task]})


def test_bad_executive_config():
    with pytest.raises(ScheduleConfigError, match="tick_hz"):
        parse_config({"tick_hz": 3, "tasks": [{"name": "a", "divider": 1, "budget_us": 1}]})
    with pytest.raises(ScheduleConfigError, match="missing field 'budget_us'"):
        parse_config({"tasks": [{"name": "a", "divider": 1}]})
    with pytest.raises(ScheduleConfigError, match="phase_method"):
        parse_config({"phase_method": "best", "tasks": [{"name": "a", "divider": 1, "budget_us": 1}]})


@pytest.mark.parametrize("catch_up", [frozenset(), frozenset({"slow", "beat"})])
def test_catch_up_tasks_released_on_skipped_ticks_run_once_at_the_next_tick(catch_up):
    schedule = schedule_from_config({"tick_hz": 1000, "tasks": [
        {"name": "a", "group": "control", "rate_hz": 1000, "budget_us": 100},
        {"name": "slow", "group": "default", "divider": 4, "phase": 1, "budget_us": 100},    # ticks 1, 5, 9
        {"name": "beat", "group": "default", "divider": 5, "phase": 4, "budget_us": 100},    # ticks 4, 9
        {"name": "other", "group": "default", "divider": 10, "phase": 5, "budget_us": 100}]})  # tick 5
    clock = FakeClock()
    runs = []

    def make(name):
        def fn(k):
            runs.append((k, name))
            clock.advance(2_500_000 if (k, name) == (3, "a") else 10_000)  # tick 3 overruns: 4, 5 skipped
        return fn

    ex = CyclicExecutive(schedule, {t.name: make(t.name) for t in schedule.tasks}, clock, report_period_s=100,
                         catch_up=catch_up)
    ex.start(t0_ns=0)
    ex.run(max_ticks=10)
    at_6 = sorted(name for k, name in runs if k == 6)
    assert at_6 == (["a", "beat", "slow"] if catch_up else ["a"])  # 'other' is not a catch-up task: lost
    assert [k for k, name in runs if name == "slow"] == ([1, 6, 9] if catch_up else [1, 9])
    assert ex.profiler.skipped_total == 2
    with pytest.raises(ValueError, match="unknown task"):
        CyclicExecutive(schedule, {t.name: make(t.name) for t in schedule.tasks}, clock, catch_up={"nope"})


def test_release_jitter_percentiles_of_a_window():
    p = Profiler("x", 1_000_000, [])
    p.start_window(0, 0)
    for j in [*range(1, 100), 5_000]:  # µs: 1..99 and one 5 ms outlier
        p.tick_done(j * 1000, 100_000, False, 0)
    r = p.report(1_000_000_000, 0)
    assert (r.release_jitter_p50_us, r.release_jitter_p99_us, r.release_jitter_max_us) == (50.0, 99.0, 5000.0)


def test_grid_start_keeps_two_processes_at_a_fixed_phase_whenever_they_start():
    """A sampler starting on the grid and a consumer starting `offset` later keep the same phase
    whatever their start-up times: the consumer's tick always falls offset after a sample."""
    period, offset = 2_000_000, 1_000_000
    for sampler_now, consumer_now in ((0, 0), (123_457, 9_876_543), (1_999_999, 2_000_001), (5_000_000_017, 17)):
        sampler = grid_start_ns(sampler_now, period, period)
        consumer = grid_start_ns(consumer_now, period, period, offset)
        assert sampler >= sampler_now + period and sampler - sampler_now < 2 * period
        assert consumer >= consumer_now + period and consumer - consumer_now < 2 * period
        assert sampler % period == 0 and (consumer - sampler) % period == offset
    assert grid_start_ns(0, 0, period) == 0  # already on the grid: no extra period
    for bad in (-1, period):
        with pytest.raises(ValueError, match="grid offset"):
            grid_start_ns(0, period, period, bad)


def test_stop_before_run_is_kept_and_consumed():
    """A SIGINT while a node is still starting calls stop() before run(): run() must return at once
    (it used to clear the request and run on), and a later run() runs again."""
    schedule = schedule_from_config(CONFIG)
    ex, _ = run(schedule, 0)
    ex.stop()
    ex.run(max_ticks=5)
    assert ex.tick == 0
    ex.run(max_ticks=5)
    assert ex.tick == 5
