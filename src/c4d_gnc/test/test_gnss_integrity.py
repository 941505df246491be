"""GNSS integrity monitor (c4d_gnc.gnss_integrity) on synthetic fix streams.

A straight 4 m/s leg with 0.3 m white fix noise at 10 Hz; the estimate follows the truth within
a few cm, the inertial shadow's velocity is off by 0.3 m/s (never corrected, as in the filter),
so the re-basing to the estimate's velocity is exercised. Each fault test checks the verdict
before the fault (OK, fused) and after it (the right state, test bit and onset).
"""

from __future__ import annotations

import math
import random

import numpy as np
import pytest

from c4d_gnc.gnss_integrity import FixCheck, GnssIntegrityMonitor, IntegrityConfig, IntegrityState, IntegrityTest, Verdict

RATE_HZ, SIGMA_H = 10.0, 0.3
VELOCITY = np.array([4.0, 0.0, 0.0])
SHADOW_VELOCITY_ERROR = np.array([0.3, -0.2, 0.0])


def fix_at(t: float, rng: random.Random, *, offset: np.ndarray | None = None, sigma_h: float = SIGMA_H,
           external: bool = False) -> FixCheck:
    """The fix at `t` (noise of the reported σ_h) with the estimate, the shadow and the external source."""
    truth = VELOCITY * t
    noise = np.array([rng.gauss(0, sigma_h), rng.gauss(0, sigma_h), 0.0])
    spoof = np.zeros(3) if offset is None else offset
    estimate = truth + np.array([rng.gauss(0, 0.03), rng.gauss(0, 0.03), 0.0])
    return FixCheck(
        t=t, position=truth + noise + spoof, sigma_h=sigma_h, sigma_v=0.5, predicted=estimate,
        predicted_cov=np.eye(3) * 0.1**2, velocity=VELOCITY + np.array([rng.gauss(0, 0.02), rng.gauss(0, 0.02), 0.0]),
        inertial_position=truth + 5.0 + SHADOW_VELOCITY_ERROR * t, inertial_velocity=VELOCITY + SHADOW_VELOCITY_ERROR,
        external_position=truth + np.array([rng.gauss(0, 0.05), rng.gauss(0, 0.05), 0.0]) if external else None)


def fly(monitor: GnssIntegrityMonitor, t0: float, t1: float, rng: random.Random, **kwargs: object) -> list[tuple[float, Verdict]]:
    verdicts = []
    n0, n1 = round(t0 * RATE_HZ), round(t1 * RATE_HZ)
    for k in range(n0, n1):
        t = k / RATE_HZ
        drift, jump = kwargs.get("drift"), kwargs.get("jump")
        off = None
        if drift is not None:
            off = np.asarray(drift, dtype=float) * (t - t0)
        elif jump is not None:
            off = np.asarray(jump, dtype=float)
        sigma_h = kwargs.get("sigma_h", SIGMA_H)
        assert isinstance(sigma_h, float)
        verdicts.append((t, monitor.check_fix(fix_at(t, rng, offset=off, sigma_h=sigma_h,
                                                     external=bool(kwargs.get("external", False))))))
    return verdicts


def test_state_and_test_values_equal_the_message_constants() -> None:
    from c4d_interfaces.msg import GnssIntegrity

    for state in IntegrityState:
        assert getattr(GnssIntegrity, f"STATE_{state.name}") == state.value
    for test in IntegrityTest:
        assert getattr(GnssIntegrity, f"TEST_{test.name}") == test.value
    states = {n for n in dir(GnssIntegrity) if n.startswith("STATE_")}
    tests = {n for n in dir(GnssIntegrity) if n.startswith("TEST_")}
    assert states == {f"STATE_{s.name}" for s in IntegrityState}
    assert tests == {f"TEST_{t.name}" for t in IntegrityTest}


def test_unknown_until_the_first_fix_then_ok_over_a_nominal_stream() -> None:
    monitor = GnssIntegrityMonitor()
    assert monitor.verdict.state == IntegrityState.UNKNOWN and monitor.tick(1.0).state == IntegrityState.UNKNOWN
    verdicts = fly(monitor, 0.0, 120.0, random.Random(1))
    assert all(v.state in (IntegrityState.OK, IntegrityState.SUSPECT) and v.fuse for _, v in verdicts)
    assert all(v.alarms == 0 for _, v in verdicts)
    assert verdicts[-1][1].fix_rate_hz == pytest.approx(RATE_HZ, abs=0.5)
    assert monitor.nominal_sigma_h == pytest.approx(SIGMA_H)


def first_alarm(verdicts: list[tuple[float, Verdict]], state: IntegrityState) -> tuple[float, Verdict]:
    for t, v in verdicts:
        if v.state == state:
            return t, v
    raise AssertionError(f"never {state.name}")


def test_a_1_m_s_drift_is_spoofing_within_2_s_with_its_onset() -> None:
    monitor, rng = GnssIntegrityMonitor(), random.Random(2)
    fly(monitor, 0.0, 30.0, rng)
    assert monitor.verdict.state != IntegrityState.SPOOFED
    verdicts = fly(monitor, 30.0, 40.0, rng, drift=(1.0, 0.0, 0.0))
    t, v = first_alarm(verdicts, IntegrityState.SPOOFED)
    assert t - 30.0 < 2.0
    assert v.alarms & IntegrityTest.INERTIAL and not v.fuse
    assert v.onset_t is not None and 30.0 - 3.5 <= v.onset_t <= 30.0  # fixes since the drift began are undone
    assert verdicts[-1][1].alarm_age_s == pytest.approx(verdicts[-1][0] - t)


def test_the_window_allows_for_the_estimate_s_velocity_error_and_still_catches_a_drift() -> None:
    """The shadow is re-based to the estimate's velocity at the window start: an estimate 0.6 m/s off there (braking
    hard, SITL) carries 1.8 m into a 3 s window. Given the estimate's σ_v (0.15 m/s) the window allows for it —
    without it, a false SPOOFED; a 1 m/s drift is still caught within 3 s at a nominal σ_v of 0.07 m/s."""

    def stream(velocity_sigma: float, velocity_error: float, drift: float) -> list[Verdict]:
        monitor, rng, out = GnssIntegrityMonitor(), random.Random(5), []
        for k in range(round(10.0 * RATE_HZ)):
            t = k / RATE_HZ
            base = fix_at(t, rng)
            bump = velocity_error if 3.0 <= t < 3.5 else 0.0  # a wrong estimate velocity at some window starts
            spoof = np.array([drift * max(0.0, t - 5.0), 0.0, 0.0])
            out.append(monitor.check_fix(FixCheck(
                t=t, position=base.position + spoof, sigma_h=SIGMA_H, sigma_v=0.5, predicted=base.predicted,
                predicted_cov=base.predicted_cov, velocity=base.velocity + np.array([bump, 0.0, 0.0]),
                inertial_position=base.inertial_position, inertial_velocity=base.inertial_velocity,
                velocity_sigma=velocity_sigma)))
        return out

    assert any(v.state == IntegrityState.SPOOFED for v in stream(0.0, 0.6, 0.0))
    assert not any(v.state == IntegrityState.SPOOFED for v in stream(0.15, 0.6, 0.0))
    caught = [k / RATE_HZ for k, v in enumerate(stream(0.07, 0.0, 1.0)) if v.state == IntegrityState.SPOOFED]
    assert caught and caught[0] - 5.0 < 3.0, caught[:1]


def test_a_20_m_jump_is_spoofing_at_once() -> None:
    monitor, rng = GnssIntegrityMonitor(), random.Random(3)
    fly(monitor, 0.0, 20.0, rng)
    verdicts = fly(monitor, 20.0, 22.0, rng, jump=(0.0, 20.0, 0.0))
    t, v = first_alarm(verdicts, IntegrityState.SPOOFED)
    assert t == pytest.approx(20.0)
    assert v.alarms & IntegrityTest.JUMP and v.jump_m > 15.0
    assert v.onset_t is not None and v.onset_t <= 20.0


def test_a_drift_against_an_external_source_alarms_the_external_test() -> None:
    monitor, rng = GnssIntegrityMonitor(IntegrityConfig(inertial_alarm_m=100.0, cusum_alarm_m_s=100.0)), random.Random(4)
    fly(monitor, 0.0, 20.0, rng, external=True)
    assert monitor.verdict.external_distance_m < 1.5
    verdicts = fly(monitor, 20.0, 30.0, rng, drift=(0.0, 1.0, 0.0), external=True)
    t, v = first_alarm(verdicts, IntegrityState.SPOOFED)
    assert v.alarms == IntegrityTest.EXTERNAL and t - 20.0 < 4.0


def test_spoofed_clears_only_after_recover_s_of_consistent_fixes() -> None:
    cfg = IntegrityConfig()
    monitor, rng = GnssIntegrityMonitor(cfg), random.Random(5)
    fly(monitor, 0.0, 20.0, rng)
    spoofed = fly(monitor, 20.0, 25.0, rng, jump=(0.0, 20.0, 0.0))
    assert spoofed[-1][1].state == IntegrityState.SPOOFED
    # the spoofer holds its 20 m offset: steps and inertial displacement are consistent again
    held = fly(monitor, 25.0, 25.0 + cfg.recover_s + 1.0, rng, jump=(0.0, 20.0, 0.0))
    cleared = [t for t, v in held if v.state != IntegrityState.SPOOFED]
    assert cleared, "never cleared"
    assert cleared[0] >= 20.0 + cfg.recover_s  # not before recover_s after the last inconsistency


def test_loss_of_fixes_is_jamming_and_clears_when_they_return() -> None:
    monitor, rng = GnssIntegrityMonitor(), random.Random(6)
    fly(monitor, 0.0, 20.0, rng)
    assert monitor.nominal_rate_hz == pytest.approx(RATE_HZ)
    v = monitor.tick(20.5)
    assert v.state != IntegrityState.JAMMED
    v = monitor.tick(21.2)
    assert v.state == IntegrityState.JAMMED and v.alarms & IntegrityTest.LOSS and v.fuse
    fly(monitor, 21.3, 30.0, rng)
    assert monitor.verdict.state == IntegrityState.OK


def test_half_the_fixes_lost_is_jamming() -> None:
    monitor, rng = GnssIntegrityMonitor(), random.Random(7)
    fly(monitor, 0.0, 20.0, rng)
    for k in range(200, 300, 2):  # every other fix: 5 Hz of 10
        monitor.check_fix(fix_at(k / RATE_HZ, rng))
    assert monitor.verdict.state == IntegrityState.JAMMED and monitor.verdict.alarms & IntegrityTest.LOSS
    assert monitor.verdict.fix_rate_hz == pytest.approx(5.0, abs=0.5)


def test_degraded_accuracy_is_jamming_not_spoofing() -> None:
    monitor, rng = GnssIntegrityMonitor(), random.Random(8)
    fly(monitor, 0.0, 20.0, rng)
    verdicts = fly(monitor, 20.0, 40.0, rng, sigma_h=5 * SIGMA_H)
    t, v = first_alarm(verdicts, IntegrityState.JAMMED)
    assert t - 20.0 < 1.0 and v.alarms & IntegrityTest.DEGRADED and v.accuracy_ratio == pytest.approx(5.0)
    assert all(v.state != IntegrityState.SPOOFED for _, v in verdicts)


def test_invalid_or_out_of_order_fixes_change_nothing() -> None:
    monitor, rng = GnssIntegrityMonitor(), random.Random(9)
    fly(monitor, 0.0, 10.0, rng)
    before = monitor.verdict
    bad = fix_at(10.0, rng)
    assert monitor.check_fix(FixCheck(**{**bad.__dict__, "position": np.array([math.nan, 0.0, 0.0])})) is before
    assert monitor.check_fix(FixCheck(**{**bad.__dict__, "t": 5.0})) is before
    assert monitor.check_fix(FixCheck(**{**bad.__dict__, "sigma_h": 0.0})) is before


def test_config_rejects_nonsense() -> None:
    with pytest.raises(ValueError, match="inertial_window_s"):
        IntegrityConfig(inertial_window_s=0.0)
    with pytest.raises(ValueError, match="warning_fraction"):
        IntegrityConfig(warning_fraction=1.5)
