"""Freedom from interference over the whole graph (issue 13): while `c4d fly` flies a 10 m square
loop, every restartable node is SIGKILLed three times in turn (the supervisor restarts it), then 20
DDS participants subscribing to every topic join and leave, then a never-taking subscriber and a
slow `echo`-like consumer attach. Per disturbance: the GNC core's worst tick < 10 ms plus what the
SCHED_FIFO-90 stall probe saw the platform itself stall in that window (at most 20 ms), the true altitude within
±1 m of the plan; over the flight, no gap > 20 ms in the commands the simulated vehicle received
(same platform allowance), and the mission completes."""

from __future__ import annotations

from interference import CRUISE_ALT, InterferenceFlight

RESTARTABLE = ("recorder", "bridge", "payload", "mission", "health")
ROUNDS = 3
CHURN_S, SLOW_S = 12.0, 8.0


def bound(window_stall_ms: float, nominal_ms: float) -> float:
    """The nominal bound plus what the platform itself stalled in the same window (a stall lengthens the tick
    it hits by as much), at most twice the nominal bound (issue 13: 10 ms, 20 ms if the probe saw longer)."""
    return nominal_ms + min(window_stall_ms, nominal_ms)


def test_no_node_restart_or_foreign_participant_disturbs_the_flight(ros_env, tmp_path):
    # cruise planned with ample margin (restarts back off 1, 2, 4 s and start slower under load); the
    # land item is made current once the disturbances are over, so the margin costs no test time
    flight = InterferenceFlight(tmp_path, dict(ros_env), cruise_s=2 * (ROUNDS * len(RESTARTABLE) * 8 + CHURN_S + SLOW_S))
    windows = []
    try:
        assert flight.wait_cruise(), flight.fly_log()[-3000:]
        for _ in range(ROUNDS):
            for name in RESTARTABLE:
                w = flight.open_window(f"kill -9 {name}")
                assert flight.kill_and_wait_restart(name), f"{name} was not restarted\n{flight.fly_log()[-2000:]}"
                windows.append(flight.close_window(w, settle_s=1.5))
        for label, args, seconds in ((f"churn of 20 participants, {CHURN_S:g} s", ("churn", str(CHURN_S), "20"), CHURN_S),
                                     (f"slow consumers, {SLOW_S:g} s", ("slow", str(SLOW_S)), SLOW_S)):
            w = flight.open_window(label)
            proc = flight.disturber(*args)
            flight.spin(seconds + 0.5)
            out, _ = proc.communicate(timeout=60)
            assert proc.returncode == 0, out
            windows.append(flight.close_window(w))
        assert flight.obs.mission is not None and flight.obs.mission[1] < flight.land_item, \
            f"the cruise ended before the disturbances did: {flight.obs.mission}"
        refused = flight.land_now()
        assert not refused, refused
        code = flight.finish()
        link = dict(flight.obs.link)
        log = flight.fly_log()
    finally:
        flight.close()
    table = "\n".join(f"{w.label:32s} worst tick {w.worst_tick_ms:6.1f} ms, skipped {w.skipped_ticks:4d}, "
                      f"alt {w.min_alt:5.2f}..{w.max_alt:5.2f} m, platform stall {w.platform_stall_ms:5.1f} ms" for w in windows)
    print(f"\n{table}\nvehicle command link: {link}")
    mission_log = flight.run_dir / "run" / "logs" / "mission.log"
    mission_lines = mission_log.read_text(errors="replace").splitlines()
    restores = [ln for ln in mission_lines if any(w in ln for w in ("WARN", "restor", "resum"))]
    assert code == 0 and "flight     completed" in log, log[-3000:] + "\nmission node:\n" + "\n".join(restores[-20:])
    for w in windows:
        assert w.worst_tick_ms < bound(w.platform_stall_ms, 10.0), f"{w.label}: core tick\n{table}"
        assert CRUISE_ALT - 1.0 <= w.min_alt and w.max_alt <= CRUISE_ALT + 1.0, f"{w.label}: altitude\n{table}"
    worst_stall = max(g for _, g in flight.stalls) if flight.stalls else 0.0
    assert link, "no sim/actuator_link report"
    assert link["max_gap_ms"] <= bound(worst_stall, 20.0), f"command gap {link} (platform stall {worst_stall:.1f} ms)\n{table}"
