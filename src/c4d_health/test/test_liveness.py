"""Liveness: silent nodes after the timeout, dead or stalled by their graph presence; the monitor's own stall is not silence."""

import pytest

from c4d_health.liveness import GraphPresence, LivenessMonitor, Silence, classify

PERIOD = 0.1


def run(monitor: LivenessMonitor, t0: float, t1: float, alive: set[str]) -> tuple[float, list[str]]:
    """Tick every PERIOD from t0 to t1; nodes in `alive` publish just before each tick."""
    t, verdict = t0, []
    while t < t1 - 1e-9:
        t = round(t + PERIOD, 9)
        for name in alive:
            monitor.heard(name, t - 0.01)
        verdict = monitor.silent(t)
    return t, verdict


def test_a_silent_node_is_dead_after_the_timeout():
    m = LivenessMonitor(["sim", "core"], timeout_s=0.6, period_s=PERIOD, start=0.0)
    t, verdict = run(m, 0.0, 2.0, {"sim", "core"})
    assert verdict == []
    detected = None
    while detected is None:  # sim goes silent at t = 2.0
        t = round(t + PERIOD, 9)
        m.heard("core", t - 0.01)
        if m.silent(t) == ["sim"]:
            detected = t
    assert detected - 2.0 == pytest.approx(0.6)  # first tick with silence > 0.6 s (last heard at 1.99)


def test_a_monitor_stall_is_not_silence_but_real_death_is_still_found():
    m = LivenessMonitor(["sim", "core"], timeout_s=0.6, period_s=PERIOD, start=0.0)
    t, _ = run(m, 0.0, 1.0, {"sim", "core"})
    # the monitor is descheduled for 1.5 s: its next tick comes late, before the queued messages
    t = round(t + 1.5, 9)
    assert m.silent(t) == [] and m.stalled_s == pytest.approx(1.4)
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


def test_an_optional_node_is_judged_only_once_heard():
    """The offboard gateway is not in every graph: never heard is not dead; heard, then silent, is."""
    m = LivenessMonitor(["offboard"], timeout_s=2.5, period_s=PERIOD, start=0.0, optional=["offboard"])
    _, verdict = run(m, 0.0, 30.0, set())
    assert verdict == []
    t, verdict = run(m, 30.0, 32.0, {"offboard"})
    assert verdict == []
    _, verdict = run(m, t, t + 2.6, set())
    assert verdict == ["offboard"]


def test_silent_and_gone_from_the_graph_is_dead_silent_but_present_is_stalled():
    assert classify(["sim", "mission", "core"], {"core", "sim", "health"}) == Silence(dead=("mission",), stalled=("core", "sim"))
    assert classify([], {"core"}) == Silence()
    assert classify(["mission"], None) == Silence(dead=("mission",))  # graph not sampled yet: the old rule (dead)


def test_a_killed_node_is_stalled_until_it_leaves_the_graph_and_a_restart_clears_it():
    """The whole story on a fake clock: mission silent from t = 1.9 s, DDS drops it from the graph at 6 s (lease),
    the restarted mission publishes again from 9 s."""
    m = LivenessMonitor(["mission", "core"], timeout_s=0.6, period_s=PERIOD, start=0.0)
    graph = GraphPresence(period_s=1.0)
    samples, verdicts = [], {}
    t = 0.0
    while t < 12.0 - 1e-9:
        t = round(t + PERIOD, 9)
        m.heard("core", t - 0.01)
        if t < 2.0 or t >= 9.0:
            m.heard("mission", t - 0.01)
        if graph.due(t):
            samples.append(t)
            graph.update(t, {"core", "health"} | ({"mission"} if t < 6.0 or t >= 8.5 else set()))
        verdicts[t] = classify(m.silent(t), graph.names)
    assert all(b - a >= 1.0 - 1e-9 for a, b in zip(samples, samples[1:], strict=False)) and len(samples) <= 12  # <= 1 Hz
    assert verdicts[2.4] == Silence() and verdicts[2.5] == Silence(stalled=("mission",))  # last heard at 1.89 s
    assert verdicts[5.9] == Silence(stalled=("mission",))
    first_dead = min(t for t, v in verdicts.items() if v.dead)
    assert 6.0 <= first_dead <= 7.0 + 1e-9 and verdicts[first_dead] == Silence(dead=("mission",))  # within a graph period
    assert verdicts[9.0] == Silence() and verdicts[12.0] == Silence()  # back: nothing silent
    assert graph.present("mission") and GraphPresence(1.0).present("x") is None
    with pytest.raises(ValueError):
        GraphPresence(0.0)
