from c4d_sim.actuator_link import ActuatorLinkMonitor


def test_steady_stream_has_tick_sized_gaps():
    m = ActuatorLinkMonitor()
    for k in range(5000):
        m.on_command(k * 0.002)
    r = m.report()
    assert r.messages_total == 5000 and r.long_gaps_total == 0
    assert 1.99 < r.max_gap_ms < 2.01 and 2.0 <= r.p999_gap_ms <= 2.1


def test_a_stall_is_counted_and_dominates_the_window_not_the_percentile():
    m = ActuatorLinkMonitor()
    t = 0.0
    for k in range(10000):
        t += 0.332 if k == 5000 else 0.002
        m.on_command(t)
    r = m.report()
    assert r.long_gaps_total == 1 and abs(r.max_gap_ms - 332) < 1e-6 and abs(r.window_max_gap_ms - 332) < 1e-6
    assert r.p999_gap_ms <= 2.1  # one gap in 10 000 is beyond the 99.9th percentile
    assert m.report().window_max_gap_ms == 0.0  # a new window starts after each report


def test_restarted_core_stamps_going_back_do_not_count_as_gaps():
    m = ActuatorLinkMonitor()
    for t in (10.0, 10.002, 1.0, 1.002):
        m.on_command(t)
    r = m.report()
    assert r.max_gap_ms < 2.1 and r.long_gaps_total == 0 and r.messages_total == 4


def test_percentile_beyond_the_binned_range_is_the_worst_gap():
    m = ActuatorLinkMonitor()
    for t in (0.0, 0.5, 1.0):
        m.on_command(t)
    assert m.percentile_s(0.999) == 0.5
    assert m.percentile_s(0.5) == 0.5
