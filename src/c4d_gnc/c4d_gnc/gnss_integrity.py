"""GNSS integrity monitor: is each fix genuine (spoofing) and is the receiver still served (jamming)?

What: `GnssIntegrityMonitor.check_fix(FixCheck)` judges every received fix before the navigation
filter fuses it, `tick(t)` (~5 Hz on the IMU clock) judges the fix rate and accuracy when no fix
comes. The `Verdict` carries the state (UNKNOWN / OK / SUSPECT / SPOOFED / JAMMED, the values of
`GnssIntegrity.STATE_*`), a score (max over the tests of statistic / alarm threshold), the tests
in alarm and in warning (`GnssIntegrity.TEST_*` bits), each test's statistic, how long the alarm
has been raised and `onset_t`: the sample time from which fixes are suspected — the filter undoes
the GNSS corrections it fused since then, so a drift that fooled it for a second does not stay in
the estimate.

The tests (horizontal; thresholds in `IntegrityConfig`, figures in docs/navigation.md § integrity):
- INNOVATION (spoofing): normalized innovation squared of the fix against the estimate, per axis,
  with the estimate's covariance + the reported accuracy; alarm after a few consecutive fixes.
- JUMP (spoofing): the fix-to-fix step minus the displacement the estimate's velocity predicts,
  beyond k·σ of two fixes' noise.
- INERTIAL (spoofing): the GNSS displacement over a sliding window vs the displacement of the
  IMU dead-reckoning shadow (never corrected by any update, so a spoofer cannot drag it), whose
  velocity is re-based to the estimate's velocity at the window start (the shadow's own velocity
  drifts without bound). Both ends are averaged over a few fixes (noise), and a CUSUM of the
  mismatch above a reference catches drifts too slow for the window's threshold.
- EXTERNAL (spoofing): horizontal distance between the fix and the healthy external source.
- LOSS (jamming): fix rate over a window vs the nominal rate (learnt from the first fixes), or
  no fix for a timeout.
- DEGRADED (jamming): reported σ_h vs the nominal σ_h learnt over the first fixes (HDOP-like).
The spoofing thresholds scale with the reported accuracy (a jammed receiver's noisier fixes are
not called spoofed).

Hysteresis: SPOOFED latches; it clears only after `recover_s` of fixes consistent with the
inertial shadow, with their own steps and with the external source (the innovation test cannot
vouch: the estimate drifted without GNSS) — the filter then re-admits GNSS through its source
switching, without a step. JAMMED clears after `jam_recover_s` below the warning levels.

Why ROS-free: every test is unit-tested and studied open-loop (bench/gnss_integrity.py) without DDS.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from enum import IntEnum, IntFlag

import numpy as np

from .ekf import GRAVITY


class IntegrityState(IntEnum):
    """Values == c4d_interfaces GnssIntegrity.STATE_* (test_gnss_integrity checks)."""

    UNKNOWN = 0
    OK = 1
    SUSPECT = 2
    SPOOFED = 3
    JAMMED = 4


class IntegrityTest(IntFlag):
    """Values == c4d_interfaces GnssIntegrity.TEST_*."""

    INNOVATION = 1
    JUMP = 2
    INERTIAL = 4
    EXTERNAL = 8
    LOSS = 16
    DEGRADED = 32


SPOOFING_TESTS = IntegrityTest.INNOVATION | IntegrityTest.JUMP | IntegrityTest.INERTIAL | IntegrityTest.EXTERNAL
JAMMING_TESTS = IntegrityTest.LOSS | IntegrityTest.DEGRADED
# the tests that can vouch for fixes again while SPOOFED (they do not use the estimate's position)
RECOVERY_TESTS = IntegrityTest.JUMP | IntegrityTest.INERTIAL | IntegrityTest.EXTERNAL
NONE = IntegrityTest(0)


@dataclass(frozen=True)
class IntegrityConfig:
    """Thresholds; defaults from the open-loop survey flights (test/support/gnss_flights.py): over 10
    nominal 100 s flights the largest statistics were 0.42 (innovation), 0.78 (inertial mismatch),
    0.58 (CUSUM) and 0.79 (jump) of these alarm levels; figures in docs/navigation.md § integrity
    (bench/gnss_integrity.py). A test warns at `warning_fraction` of its alarm level."""

    warning_fraction: float = 0.5  # a test's statistic / alarm threshold above this: warning
    innovation_alarm_nis: float = 25.0  # normalized innovation squared per axis (25: 5σ)
    innovation_count: int = 3  # consecutive fixes above it: alarm
    jump_sigmas: float = 6.0  # k: step beyond the predicted displacement + k·σ(two fixes): alarm
    inertial_window_s: float = 3.0  # [s] displacement comparison window
    inertial_min_window_s: float = 1.0  # [s] no inertial statistic over a shorter history
    inertial_average_fixes: int = 5  # fixes averaged at each end of the window (noise)
    inertial_alarm_m: float = 1.5  # [m] GNSS vs inertial displacement mismatch (at nominal accuracy)
    cusum_reference_m: float = 0.6  # [m] mismatch below this drains the drift CUSUM
    cusum_alarm_m_s: float = 1.0  # [m·s] CUSUM of the mismatch excess: alarm
    inertial_bias_sigmas: float = 3.0  # k: the inertial thresholds widen by k x the mismatch an unconverged gyro bias explains
    inertial_velocity_sigmas: float = 3.0  # k: the window's threshold widens by k x σ_v·T (the re-basing velocity's error)
    external_alarm_m: float = 2.0  # [m] horizontal distance to the external source (floor)
    external_sigmas: float = 5.0  # ... or this many σ of the difference, whichever is larger
    external_sigma_m: float = 0.1  # [m] 1σ of the external source's position
    external_count: int = 3  # consecutive fixes above it: alarm
    nominal_fixes: int = 20  # fixes that learn the nominal rate and σ_h
    nominal_rate_hz: float = 0.0  # [Hz] the receiver's rate; 0: learnt from the first fixes
    loss_window_s: float = 3.0  # [s] fix-rate window
    loss_alarm_ratio: float = 0.6  # fix rate below this fraction of nominal: alarm
    loss_timeout_s: float = 1.0  # [s] no fix this long: alarm
    degraded_alarm_ratio: float = 3.0  # reported σ_h / nominal σ_h above this: alarm
    degraded_fixes: int = 5  # median over the last fixes' σ_h (one bad report is not jamming)
    recover_s: float = 10.0  # [s] of consistent fixes before SPOOFED clears
    jam_recover_s: float = 2.0  # [s] below the warning levels before JAMMED clears
    innovation_rearm_s: float = 5.0  # [s] after SPOOFED clears, while the filter re-admits GNSS

    def __post_init__(self) -> None:
        for name in ("innovation_alarm_nis", "jump_sigmas", "inertial_window_s", "inertial_alarm_m", "cusum_alarm_m_s",
                     "external_alarm_m", "external_sigmas", "loss_window_s", "loss_timeout_s"):
            if not getattr(self, name) > 0:
                raise ValueError(f"IntegrityConfig.{name} must be > 0")
        if not 0 < self.warning_fraction < 1 or not 0 < self.loss_alarm_ratio < 1 or self.degraded_alarm_ratio <= 1:
            raise ValueError("IntegrityConfig: need 0 < warning_fraction < 1, 0 < loss_alarm_ratio < 1, "
                             "degraded_alarm_ratio > 1")
        if min(self.innovation_count, self.external_count, self.nominal_fixes, self.inertial_average_fixes,
               self.degraded_fixes) < 1:
            raise ValueError("IntegrityConfig: fix counts must be >= 1")


@dataclass(frozen=True)
class FixCheck:
    """What the filter knows when a fix arrives; all vectors numpy (3,), map ENU [m, m/s], at the fix's SAMPLE time."""

    t: float  # fix sample time on the IMU clock [s]
    position: np.ndarray  # the fix converted to map ENU
    sigma_h: float  # reported accuracy [m] (1σ)
    sigma_v: float
    predicted: np.ndarray  # the estimate's position at t, before this fix
    predicted_cov: np.ndarray  # (3, 3) its covariance
    velocity: np.ndarray  # the estimate's velocity at t
    inertial_position: np.ndarray  # dead-reckoning shadow at t: IMU-only integration, never corrected by any update
    inertial_velocity: np.ndarray
    external_position: np.ndarray | None = None  # the healthy external source's map position at t; None without one
    # [rad/s] 1σ of the estimate's roll/pitch gyro bias: unconverged (seconds after alignment: ~0.02), the
    # attitude the shadow integrates with drifts, and so does the shadow (g·σ·T³/6 over a window T)
    gyro_bias_sigma: float = 0.0
    # [m/s] 1σ of the estimate's horizontal velocity at t: the shadow is re-based to that velocity at the window
    # start, so its error σ_v carries into the window's mismatch as σ_v·T (SITL, braking at a geofence barrier:
    # 0.3 m/s, 1.7 m over 3 s — a false SPOOFED before this margin)
    velocity_sigma: float = 0.0


@dataclass(frozen=True)
class Verdict:
    state: IntegrityState = IntegrityState.UNKNOWN
    score: float = 0.0  # max over the tests of statistic / alarm threshold; >= 1: alarm
    alarms: IntegrityTest = NONE
    warnings: IntegrityTest = NONE
    innovation_nis: float = 0.0  # per axis, last fix
    jump_m: float = 0.0  # [m] last step beyond the predicted displacement + k·σ (0: within)
    inertial_mismatch_m: float = 0.0  # [m] GNSS vs inertial displacement over the window
    drift_cusum: float = 0.0  # CUSUM / its alarm level (alarm at 1)
    external_distance_m: float = math.nan  # [m] horizontal; NaN without an external source
    fix_rate_hz: float = math.nan  # [Hz] over the loss window; NaN until it is filled
    accuracy_ratio: float = 1.0  # reported σ_h / nominal σ_h
    alarm_age_s: float = 0.0  # [s] since the current alarm (SPOOFED or JAMMED) was raised
    onset_t: float | None = None  # sample time from which fixes are suspected (None: no spoofing alarm)

    @property
    def fuse(self) -> bool:
        """False while SPOOFED (a JAMMED fix that arrives may still be fused if it passes the gate)."""
        return self.state != IntegrityState.SPOOFED


@dataclass
class _Sample:
    t: float
    fix: np.ndarray  # horizontal (2,)
    inertial: np.ndarray
    inertial_velocity: np.ndarray
    velocity: np.ndarray
    gyro_bias_sigma: float
    velocity_sigma: float = 0.0  # default: windows in snapshots journaled before this field (resim)


class GnssIntegrityMonitor:
    """Spoofing and jamming tests over the fix stream (module docstring); deterministic, no clock of its own."""

    def __init__(self, config: IntegrityConfig | None = None) -> None:
        self.cfg = config or IntegrityConfig()
        self._verdict = Verdict()
        self._window: deque[_Sample] = deque()
        self._fix_times: deque[float] = deque()
        self._sigmas: deque[float] = deque(maxlen=self.cfg.degraded_fixes)
        self._learn_t: list[float] = []
        self._learn_sigma: list[float] = []
        self.nominal_rate_hz = self.cfg.nominal_rate_hz
        self.nominal_sigma_h = 0.0
        self._first_fix_t: float | None = None
        self._last: FixCheck | None = None
        self._innovation_run, self._innovation_onset = 0, math.inf
        self._external_run, self._external_onset = 0, math.inf
        self._mismatch_onset = math.inf  # window start when the mismatch last rose above its warning level
        self._cusum, self._cusum_onset = 0.0, math.inf
        self._scores: dict[IntegrityTest, float] = {}
        self._onsets: dict[IntegrityTest, float] = {}  # per spoofing test: when its statistic started rising
        self._stats: dict[str, float] = {}
        self._spoof_alarms = NONE
        self._spoofed_since: float | None = None
        self._onset: float | None = None
        self._last_inconsistent = -math.inf
        self._jammed_since: float | None = None
        self._last_jam_warning = -math.inf
        self._innovation_armed_at = -math.inf

    @property
    def verdict(self) -> Verdict:
        return self._verdict

    # ------------------------------------------------------------------ fixes
    def check_fix(self, fix: FixCheck) -> Verdict:
        """Judge one received fix (before the filter fuses it) and return the verdict."""
        t = float(fix.t)
        position = np.asarray(fix.position, dtype=float)
        if not (math.isfinite(t) and np.all(np.isfinite(position)) and math.isfinite(fix.sigma_h) and fix.sigma_h > 0):
            return self._verdict  # not a fix (the filter counts it as invalid)
        if self._last is not None and t <= self._last.t:
            return self._verdict  # out of order or repeated: no step, no rate
        self._learn(t, float(fix.sigma_h))
        self._fix_times.append(t)
        self._sigmas.append(float(fix.sigma_h))
        scale = max(1.0, self._accuracy_ratio())  # spoofing thresholds follow the reported accuracy
        self._innovation(fix, t)
        self._jump(fix, t, scale)
        self._inertial(fix, t, scale)
        self._external(fix, t, scale)
        self._last = fix
        return self._decide(t)

    def inertial_gap(self) -> None:
        """The filter skipped an IMU gap (a stall, dropped samples): the dead-reckoning shadow misses
        that interval's displacement, so no inertial window may span it — compare from the next fix on."""
        self._window.clear()

    def tick(self, t: float) -> Verdict:
        """Judge the fix rate and accuracy at IMU time `t` [s] (also when no fix comes)."""
        if self._first_fix_t is None or not math.isfinite(t):
            return self._verdict
        return self._decide(max(t, self._last.t if self._last is not None else t))

    # ------------------------------------------------------------------ spoofing tests
    def _innovation(self, fix: FixCheck, t: float) -> None:
        innovation = (np.asarray(fix.position, dtype=float) - np.asarray(fix.predicted, dtype=float))[:2]
        s = np.asarray(fix.predicted_cov, dtype=float)[:2, :2] + np.eye(2) * fix.sigma_h**2
        try:
            nis = float(innovation @ np.linalg.solve(s, innovation)) / 2.0
        except np.linalg.LinAlgError:
            nis = 0.0
        nis = nis if math.isfinite(nis) else 0.0
        self._stats["innovation_nis"] = nis
        score = nis / self.cfg.innovation_alarm_nis
        if t < self._innovation_armed_at:
            score = 0.0  # the filter is re-admitting GNSS after a spoofing alarm
        if score >= self.cfg.warning_fraction:
            if self._innovation_run == 0:
                self._innovation_onset = t
            self._innovation_run += 1
        else:
            self._innovation_run, self._innovation_onset = 0, math.inf
        self._set(IntegrityTest.INNOVATION, score,
                  score >= 1.0 and self._innovation_run >= self.cfg.innovation_count, self._innovation_onset)

    def _jump(self, fix: FixCheck, t: float, scale: float) -> None:
        last = self._last
        if last is None or t - last.t > self.cfg.loss_timeout_s:
            self._stats["jump_m"] = 0.0
            self._set(IntegrityTest.JUMP, 0.0, False, t)
            return
        dt = t - last.t
        predicted = 0.5 * (np.asarray(last.velocity, dtype=float) + np.asarray(fix.velocity, dtype=float))[:2] * dt
        step = (np.asarray(fix.position, dtype=float) - np.asarray(last.position, dtype=float))[:2]
        error = float(np.linalg.norm(step - predicted))
        limit = self.cfg.jump_sigmas * math.sqrt(fix.sigma_h**2 + last.sigma_h**2)
        self._stats["jump_m"] = max(0.0, error - limit)
        score = error / limit
        self._set(IntegrityTest.JUMP, score, score >= 1.0, last.t)

    def _inertial(self, fix: FixCheck, t: float, scale: float) -> None:
        cfg = self.cfg
        sample = _Sample(t, np.asarray(fix.position, dtype=float)[:2].copy(),
                         np.asarray(fix.inertial_position, dtype=float)[:2].copy(),
                         np.asarray(fix.inertial_velocity, dtype=float)[:2].copy(),
                         np.asarray(fix.velocity, dtype=float)[:2].copy(), fix.gyro_bias_sigma, fix.velocity_sigma)
        window = self._window
        if window and t - window[-1].t > cfg.loss_timeout_s:
            window.clear()  # a gap: the displacement is compared over continuous fixes only
        window.append(sample)
        while t - window[0].t > cfg.inertial_window_s:
            window.popleft()
        start = window[0]
        mismatch = 0.0
        if t - start.t >= cfg.inertial_min_window_s and len(window) >= 2:
            n = min(cfg.inertial_average_fixes, len(window) // 2)
            dv = start.inertial_velocity - start.velocity  # the shadow's velocity, re-based to the estimate's
            residual = np.array([s.fix - (s.inertial - dv * (s.t - start.t)) for s in window])
            mismatch = float(np.linalg.norm(residual[-n:].mean(axis=0) - residual[:n].mean(axis=0)))
        self._stats["inertial_mismatch_m"] = mismatch
        # what an unconverged gyro bias explains over this window (a vehicle armed seconds after power-on:
        # 1.6 m in SITL under load, a false SPOOFED at take-off before this margin)
        span = t - start.t
        margin = cfg.inertial_bias_sigmas * GRAVITY * start.gyro_bias_sigma * span**3 / 6.0
        # ... and what the re-basing velocity's error explains (the window only: the CUSUM's slow drifts outlast it)
        window_margin = margin + cfg.inertial_velocity_sigmas * start.velocity_sigma * span
        score = mismatch / (cfg.inertial_alarm_m * scale + window_margin)
        if score >= cfg.warning_fraction:
            self._mismatch_onset = min(self._mismatch_onset, start.t)
        else:
            self._mismatch_onset = math.inf
        last_t = self._last.t if self._last is not None else t
        reference = cfg.cusum_reference_m * scale + margin
        was = self._cusum
        # bounded at its alarm level: after a spoofing episode it drains in seconds, not minutes
        limit = cfg.cusum_alarm_m_s * scale
        self._cusum = min(limit, max(0.0, self._cusum + (mismatch - reference) * (t - last_t)))
        if self._cusum > 0.0 and was == 0.0:
            self._cusum_onset = start.t  # the drift began at the latest when this window started
        elif self._cusum == 0.0:
            self._cusum_onset = math.inf
        cusum = self._cusum / limit
        self._stats["drift_cusum"] = cusum
        onset = min(self._mismatch_onset, self._cusum_onset)
        self._set(IntegrityTest.INERTIAL, max(score, cusum), score >= 1.0 or cusum >= 1.0, onset)

    def _external(self, fix: FixCheck, t: float, scale: float) -> None:
        cfg = self.cfg
        if fix.external_position is None or not np.all(np.isfinite(fix.external_position)):
            self._stats["external_distance_m"] = math.nan
            self._external_run, self._external_onset = 0, math.inf
            self._set(IntegrityTest.EXTERNAL, 0.0, False, t)
            return
        distance = float(np.linalg.norm((np.asarray(fix.position, dtype=float)
                                         - np.asarray(fix.external_position, dtype=float))[:2]))
        self._stats["external_distance_m"] = distance
        limit = max(cfg.external_alarm_m * scale,
                    cfg.external_sigmas * math.sqrt(2.0 * (fix.sigma_h**2 + cfg.external_sigma_m**2)))
        score = distance / limit
        if score >= cfg.warning_fraction:
            if self._external_run == 0:
                self._external_onset = self._last.t if self._last is not None else t
            self._external_run += 1
        else:
            self._external_run, self._external_onset = 0, math.inf
        self._set(IntegrityTest.EXTERNAL, score, score >= 1.0 and self._external_run >= cfg.external_count,
                  self._external_onset)

    def _set(self, test: IntegrityTest, score: float, alarm: bool, onset: float) -> None:
        self._scores[test] = score
        self._spoof_alarms = (self._spoof_alarms | test) if alarm else (self._spoof_alarms & ~test)
        self._onsets[test] = onset

    # ------------------------------------------------------------------ jamming tests
    def _learn(self, t: float, sigma_h: float) -> None:
        if self._first_fix_t is None:
            self._first_fix_t = t
        if len(self._learn_sigma) >= self.cfg.nominal_fixes:
            return
        self._learn_t.append(t)
        self._learn_sigma.append(sigma_h)
        if len(self._learn_sigma) == self.cfg.nominal_fixes:
            self.nominal_sigma_h = float(np.median(self._learn_sigma))
            if self.nominal_rate_hz <= 0 and len(self._learn_t) >= 2:
                interval = float(np.median(np.diff(self._learn_t)))
                self.nominal_rate_hz = 1.0 / interval if interval > 0 else 0.0

    def _accuracy_ratio(self) -> float:
        if self.nominal_sigma_h <= 0 or not self._sigmas:
            return 1.0
        return float(np.median(self._sigmas)) / self.nominal_sigma_h

    def _jamming(self, t: float) -> tuple[dict[IntegrityTest, float], float]:
        cfg = self.cfg
        times = self._fix_times
        while times and t - times[0] > cfg.loss_window_s:
            times.popleft()
        rate = math.nan
        loss = 0.0
        if self._first_fix_t is not None and t - self._first_fix_t >= cfg.loss_window_s and self.nominal_rate_hz > 0:
            rate = len(times) / cfg.loss_window_s
            loss = max(0.0, 1.0 - rate / self.nominal_rate_hz) / (1.0 - cfg.loss_alarm_ratio)
        last = self._last.t if self._last is not None else t
        if t - last >= cfg.loss_timeout_s:
            loss = max(loss, (t - last) / cfg.loss_timeout_s)
        degraded = max(0.0, self._accuracy_ratio() - 1.0) / (cfg.degraded_alarm_ratio - 1.0)
        return {IntegrityTest.LOSS: loss, IntegrityTest.DEGRADED: degraded}, rate

    # ------------------------------------------------------------------ verdict
    def _decide(self, t: float) -> Verdict:
        cfg = self.cfg
        jam_scores, rate = self._jamming(t)
        scores = {**self._scores, **jam_scores}
        warnings = NONE
        for test, score in scores.items():
            if score >= cfg.warning_fraction:
                warnings |= test
        jam_alarms = NONE
        for test, score in jam_scores.items():
            if score >= 1.0:
                jam_alarms |= test
        alarms = self._spoof_alarms | jam_alarms
        warnings &= ~alarms
        # spoofing: latched until the recovery tests stayed quiet for recover_s
        # consistent = no recovery test in alarm, the drift CUSUM and the external distance below their warning
        # levels (one noisy window mismatch in warning is not evidence; the CUSUM integrates it)
        if (self._spoof_alarms & RECOVERY_TESTS or self._stats.get("drift_cusum", 0.0) >= cfg.warning_fraction
                or warnings & IntegrityTest.EXTERNAL):
            self._last_inconsistent = t
        if self._spoof_alarms and self._spoofed_since is None:
            self._spoofed_since = t
            onsets = [self._onsets.get(test, t) for test in IntegrityTest if test & self._spoof_alarms]
            self._onset = min([t, *onsets])
        elif self._spoofed_since is not None and t - self._last_inconsistent >= cfg.recover_s:
            self._spoofed_since, self._onset = None, None
            self._cusum, self._cusum_onset = 0.0, math.inf
            self._innovation_run, self._innovation_onset = 0, math.inf
            self._innovation_armed_at = t + cfg.innovation_rearm_s
        # jamming: clears after jam_recover_s below the warning levels
        if jam_alarms or (warnings & JAMMING_TESTS):
            self._last_jam_warning = t
        if jam_alarms and self._jammed_since is None:
            self._jammed_since = t
        elif self._jammed_since is not None and t - self._last_jam_warning >= cfg.jam_recover_s:
            self._jammed_since = None
        if self._spoofed_since is not None:
            state, since = IntegrityState.SPOOFED, self._spoofed_since
        elif self._jammed_since is not None:
            state, since = IntegrityState.JAMMED, self._jammed_since
        else:
            state = IntegrityState.SUSPECT if (alarms | warnings) else IntegrityState.OK
            since = None
        s = self._stats
        self._verdict = Verdict(
            state=state, score=max(scores.values(), default=0.0), alarms=alarms, warnings=warnings,
            innovation_nis=s.get("innovation_nis", 0.0), jump_m=s.get("jump_m", 0.0),
            inertial_mismatch_m=s.get("inertial_mismatch_m", 0.0), drift_cusum=s.get("drift_cusum", 0.0),
            external_distance_m=s.get("external_distance_m", math.nan), fix_rate_hz=rate,
            accuracy_ratio=self._accuracy_ratio(), alarm_age_s=0.0 if since is None else t - since,
            onset_t=self._onset)
        return self._verdict


__all__ = ["FixCheck", "GnssIntegrityMonitor", "IntegrityConfig", "IntegrityState", "IntegrityTest", "Verdict"]
