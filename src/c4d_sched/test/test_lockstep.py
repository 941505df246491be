"""Lockstep gates and clock (c4d_sched.lockstep): what is awaited, what matches, when waiting stops."""

from __future__ import annotations

from c4d_sched.executive import CyclicExecutive
from c4d_sched.lockstep import CLOCK, InputGate, LockstepClock, StepGate, pause_ns, step_time_ns
from c4d_sched.tickschedule import TaskSpec, build_schedule

MS = 1_000_000


def test_input_gate_waits_for_clock_then_running_streams_only():
    gate = InputGate(2 * MS, ("gyro", "state"))
    assert gate.missing(0) == (CLOCK,)  # no simulated time yet
    gate.on_clock(0)
    assert gate.missing(0) == ()  # no stream has started: nothing to wait for
    gate.on_sample("gyro", 0)
    gate.on_clock(2 * MS)
    assert gate.missing(2 * MS) == ("gyro",)  # gyro delivered step 0: it runs, its step-2 ms sample is awaited
    gate.on_sample("gyro", 2 * MS - 300)  # float stamps round to the ns: equal within the tolerance
    assert gate.missing(2 * MS) == ()
    gate.on_sample("state", 2 * MS)  # navigation starts publishing (after alignment)
    gate.on_clock(4 * MS)
    assert gate.missing(4 * MS) == ("gyro", "state")
    gate.on_sample("state", 4 * MS)
    gate.on_sample("gyro", 4 * MS)
    assert gate.missing(4 * MS) == ()


def test_input_gate_stops_waiting_for_a_stream_that_went_away():
    gate = InputGate(2 * MS, ("gyro",))
    gate.on_clock(2 * MS)
    gate.on_sample("gyro", 2 * MS)
    gate.on_clock(4 * MS)
    assert gate.missing(4 * MS) == ("gyro",)  # (the clock gives up on it after its timeout)
    gate.on_clock(6 * MS)
    assert gate.missing(6 * MS) == ()  # its newest sample is older than the previous tick: not running
    assert gate.missing(8 * MS) == (CLOCK,)


def test_step_gate_awaits_the_declared_step_and_matches_by_stamp():
    gate = StepGate()
    assert gate.missing() == ()
    assert gate.declare(2 * MS)
    assert gate.missing() == ("command",)
    assert not gate.on_command(0)  # an older command (the core's start-up one) answers nothing
    assert gate.missing() == ("command",)
    assert gate.on_command(2 * MS + 10)
    assert gate.missing() == ()
    assert not gate.declare(2 * MS)  # the same step again is not a new step
    assert gate.missing() == ()
    assert (gate.steps, gate.matched) == (1, 1)


def test_step_gate_holds_after_the_step_at_pause_time_is_answered():
    gate = StepGate(pause_ns(0.004))
    gate.declare(2 * MS)
    gate.on_command(2 * MS)
    assert gate.missing() == ()
    gate.declare(4 * MS)
    assert gate.missing() == ("command",)  # the step at the pause time is still answered
    gate.on_command(4 * MS)
    assert gate.missing() == ("paused",)
    gate.pause_at_ns = pause_ns(-1.0)  # released
    assert gate.missing() == ()


def test_step_time_is_the_imu_grid():
    assert step_time_ns(0.0, 0.002) == 0
    assert step_time_ns(0.0029999999999, 0.002) == 2 * MS
    assert step_time_ns(0.0039999999999, 0.002) == 4 * MS  # float sums of 1 ms steps land a hair early
    assert step_time_ns(1.003, 0.002) == 1002 * MS


class ScriptedGate:
    """Misses whatever the script says for the next polls."""

    def __init__(self, answers):
        self.answers = list(answers)

    def missing(self, deadline_ns):
        return self.answers.pop(0) if self.answers else ()


def test_clock_polls_until_the_gate_is_satisfied_and_jumps_to_the_deadline():
    polls, wall = [], [0.0]
    gate = ScriptedGate([("gyro",), ("gyro",), ()])
    clock = LockstepClock(gate, lambda: polls.append(1), lambda *a: True, report_s=1.0,
                          sleep=lambda s: wall.__setitem__(0, wall[0] + s), wall=lambda: wall[0])
    clock.sleep_until_ns(6 * MS)
    assert len(polls) == 3 and clock.now_ns() == 6 * MS and clock.stalls == 0


def test_clock_reports_a_stall_and_gives_up_only_when_told():
    wall, stalls = [0.0], []

    def on_stall(deadline, missing, waited):
        stalls.append((deadline, missing, round(waited, 3)))
        return len(stalls) == 3  # keep waiting twice, then give up

    clock = LockstepClock(ScriptedGate([("command",)] * 100_000), lambda: None, on_stall, report_s=0.5,
                          sleep=lambda s: wall.__setitem__(0, wall[0] + s), wall=lambda: wall[0])
    clock.sleep_until_ns(2 * MS)
    assert [s[1] for s in stalls] == [("command",)] * 3
    assert [s[2] for s in stalls] == [0.5, 1.0, 1.5]
    assert (clock.stalls, clock.given_up, clock.now_ns()) == (3, 1, 2 * MS)


def test_executive_on_the_lockstep_clock_never_overruns_or_skips():
    """However long a tick takes in wall time, simulated time does not move during it."""
    gate = InputGate(2 * MS, ())
    ran: list[int] = []
    clock = LockstepClock(gate, lambda: gate.on_clock(clock.now_ns() + 2 * MS), lambda *a: False)
    schedule = build_schedule(2000, "zero", [TaskSpec("work", "control", 1, 100, 0)])

    def work(k):
        ran.append(k)
        for _ in range(20_000):  # a few ms of wall time: 'late' in real time
            pass

    ex = CyclicExecutive(schedule, {"work": work}, clock)
    ex.start(t0_ns=0)
    ex.run(max_ticks=20)
    assert ran == list(range(20))
    assert ex.profiler.overruns_total == 0 and ex.profiler.skipped_total == 0 and ex.profiler.ticks_total == 20


def test_an_interrupted_clock_stops_waiting():
    clock = LockstepClock(ScriptedGate([("command",)] * 10), lambda: None, lambda *a: False)
    clock.interrupt()
    clock.sleep_until_ns(2 * MS)
    assert clock.now_ns() == 2 * MS
