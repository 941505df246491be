"""Flight summary arithmetic (ROS-free): distance without noise build-up, tracking error only in the
air, overruns as a delta of the core's counters, failsafes deduplicated, progress lines."""

from __future__ import annotations

import math
import random

import pytest

from c4d_bringup.summary import FlightSummary, progress_line


def test_distance_duration_and_tracking():
    s = FlightSummary()
    rng = random.Random(1)
    for _ in range(500):  # on the ground, disarmed: nothing counts
        s.on_position(rng.gauss(0, 0.05), rng.gauss(0, 0.05), 0.0)
    s.on_status(10.0, armed=True, in_air=False)
    s.on_setpoint(5.0, 5.0, 5.0)  # armed but not in the air yet: not a tracking sample
    for k in range(101):  # climb 10 m, with 2 cm noise
        s.on_position(rng.gauss(0, 0.02), rng.gauss(0, 0.02), 0.1 * k)
    s.on_status(20.0, armed=True, in_air=True)
    for k in range(201):  # 20 m north at 10 m, setpoint 0.3 m ahead
        s.on_position(0.0, 0.1 * k, 10.0)
        s.on_setpoint(0.0, 0.1 * k + 0.3, 10.0)
    s.on_status(40.0, armed=False, in_air=False)
    s.on_position(0.0, 50.0, 0.0)  # disarmed again: ignored
    assert s.duration_s == pytest.approx(30.0)
    assert 29.5 <= s.distance_m <= 31.0  # 10 m up + 20 m along, noise not accumulated
    assert s.max_tracking_error_m == pytest.approx(0.3) and s.rms_tracking_error_m == pytest.approx(0.3)
    assert s.tracking_samples == 201 and s.max_altitude_m == pytest.approx(10.0)


def test_overruns_and_failsafes():
    s = FlightSummary()
    s.on_executor_stats(1000, 4, 30.0)
    s.on_executor_stats(6000, 5, 130.0)
    s.on_executor_stats(11000, 6, 40.0)
    assert (s.ticks, s.overruns, s.load_max_percent) == (10000, 2, 130.0)
    for action, reason in [("NONE", ""), ("WARN", "executor_overrun: 1 new overrun(s)"), ("WARN", "executor_overrun: 2 new"),
                           ("NONE", ""), ("WARN", "executor_overrun: 1 new overrun(s)"), ("RTL", "battery_low: 18 %"),
                           ("RTL", "battery_low: 17 %")]:
        s.on_failsafe(action, reason)
    lines = "\n".join(s.lines("completed", {"mcap": "/x.mcap"}))
    assert "failsafes  RTL battery_low: 18 %\n" in lines
    assert "warnings   WARN executor_overrun: 1 new overrun(s) (x2)" in lines
    assert "overruns   2 (0.020 % of 10000 ticks, worst tick load 130 %)" in lines and "mcap       /x.mcap" in lines


def test_progress_line():
    line = progress_line(12.34, (4, 3, 3, 1.0), (1.0, -2.0, 3.5), 0.97, "disarmed AUTO/-")
    assert line == "[  12.3 s]  COMPLETED item  3/3  100.0 %  E    1.0 N   -2.0 U   3.5 m  batt  97 %  disarmed AUTO/-"
    assert "batt" not in progress_line(0.0, None, None, math.nan, "-")


def test_status_waits_for_every_node_and_what_it_shows():
    from c4d_bringup.status import complete

    expected = ["sim", "core", "payload"]
    full = {"status": 1, "stats": 1, "battery": 1}
    assert complete(expected, {"sim", "core", "payload", "c4d_status_1"}, full)
    assert not complete(expected, {"sim", "core"}, full)  # payload not discovered yet
    assert not complete(expected, {"sim", "core", "payload"}, {"status": 1, "battery": 1})  # no executor stats yet
    assert complete(["payload", "bridge"], {"payload", "bridge"}, {})  # nodes with nothing on the screen
