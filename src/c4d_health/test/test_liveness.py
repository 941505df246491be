"""Liveness: silent nodes are dead after the timeout; the monitor's own stall is not silence."""

import pytest

from c4d_health.liveness import LivenessMonitor

PERIOD = 0.1


def run(monitor: LivenessMonitor, t0: float, t1: float, alive: set[str]) -> tuple[float, list[str]]:
    """Tick every PERIOD from t0 to t1; nodes in `alive` publish just before each tick."""
    t, verdict = t0, []
    while t < t1 - 1e-9:
        t = round(t + PERIOD, 9)
        for name in alive:
            monitor.heard(name, t - 0.01)
        verdict = monitor.dead(t)
    return t, verdict


def test_a_silent_node_is_dead_after_the_timeout():
    m = LivenessMonitor(["sim", "core"], timeout_s=0.6, period_s=PERIOD, start=0.0)
    t, verdict = run(m, 0.0, 2.0, {"sim", "core"})
    assert verdict == []
    detected = None
    while detected is None:  # sim goes silent at t = 2.0
        t = round(t + PERIOD, 9)
        m.heard("core", t - 0.01)
        if m.dead(t) == ["sim"]:
            detected = t
    assert detected - 2.0 == pytest.approx(0.6)  # first tick with silence > 0.6 s (last heard at 1.99)


def test_a_monitor_stall_is_not_silence_but_real_death_is_still_found():
    m = LivenessMonitor(["sim", "core"], timeout_s=0.6, period_s=PERIOD, start=0.0)
    t, _ = run(m, 0.0, 1.0, {"sim", "core"})
    # the monitor is descheduled for 1.5 s: its next tick comes late, before the queued messages
    t = round(t + 1.5, 9)
    assert m.dead(t) == [] and m.stalled_s == pytest.approx(1.4)
    m.heard("sim", t + 0.001)  # the queued messages arrive right after the late tick
    m.heard("core", t + 0.001)
    t, verdict = run(m, t, t + 1.0, {"sim", "core"})
    assert verdict == []
    # a node that never comes back is reported after timeout_s of running time
    t, verdict = run(m, t, t + 0.8, {"core"})
    assert verdict == ["sim"]


def test_never_heard_counts_from_start_and_bad_arguments():
    m = LivenessMonitor(["mission"], timeout_s=0.6, period_s=PERIOD, start=10.0)
    _, verdict = run(m, 10.0, 10.6, set())
    assert verdict == []
    _, verdict = run(m, 10.6, 10.8, set())
    assert verdict == ["mission"]
    m.heard("unknown", 11.0)  # not watched: ignored
    assert "unknown" not in m.last_seen
    with pytest.raises(ValueError):
        LivenessMonitor(["x"], timeout_s=0.0, period_s=PERIOD, start=0.0)
