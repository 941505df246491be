"""The navigation EKF driven by the sensor streams' timing, without ROS.

Why a class of its own: what the navigation node does with each sample — align first,
predict on every IMU sample but never across a gap, zero-velocity updates while disarmed,
GNSS age against the IMU clock, the terrain distance only while a range reading is fresh —
is logic, and it is unit-tested here without DDS. The node only converts messages.

Issue 19 (docs/navigation.md): every IMU sample's state goes into a `StateHistory`; delayed
measurements (external pose, GNSS, baro, range) are compared with the state at their *sample
time* and the correction is applied to the current state (and to the stored history). Sources
are chosen per axis group by `SourceSelector` (primary / secondary, switch on loss or a SPOOFED
GNSS verdict, offset capture so a switch makes no step). External samples pass
`ExternalValidator` (typed, counted rejections) and `FrameAlignment`. Every GNSS fix is checked
by the `GnssIntegrityMonitor` before it is fused; a SPOOFED verdict undoes the GNSS corrections
fused since the verdict's onset (a journal of them is kept).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from c4d_common.geodesy import GeoOrigin, altitude_at_pressure

from .ekf import N_STATES, NavigationEkf
from .external_pose import ExternalConfig, ExternalSample, ExternalValidator, FrameAlignment, Rejection, wrap
from .gnss_integrity import FixCheck, GnssIntegrityMonitor, IntegrityState, Verdict
from .source_selection import BARO, EXTERNAL, GNSS, NONE, RANGE, SelectionConfig, SourceSelector
from .state_history import PI, VI, P, Q, StateHistory, V

Vec = tuple[float, float, float]

ZUPT_EVERY = 50  # IMU samples between zero-velocity updates (10 Hz at 500 Hz)
MAX_IMU_GAP_S = 0.1  # a longer gap between IMU samples is not integrated
RANGE_TIMEOUT_S = 0.5  # a range reading older than this gives no terrain distance
DEFAULT_SIGMA_H_M, DEFAULT_SIGMA_V_M = 1.0, 2.0  # GNSS accuracy when a fix reports no covariance
TICK_S = 0.2  # integrity monitor tick and source-switch evaluation period (5 Hz, IMU clock)
HORIZONTAL, VERTICAL = np.array([0, 1]), np.array([2])
UNDO_VELOCITY_SIGMA = 0.5  # [m/s] added to the horizontal velocity σ by a SPOOFED undo (_undo_since)
JOURNAL_S = 60.0  # [s] GNSS corrections kept for an undo
HOME_GYRO_BIAS_SIGMA = 0.004  # [rad/s] roll/pitch gyro-bias σ below which home may be set (_settled)
HOME_SETTLE_MAX_S = 10.0  # [s] ... or this long after alignment, converged or not
EXTERNAL_MATCH_S = 0.3  # [s] an external sample this close to a fix is compared with it (integrity monitor)


@dataclass(frozen=True)
class NavigationConfig:
    """The filter's source configuration (navigation node parameters, docs/navigation.md)."""

    horizontal_primary: int = GNSS
    horizontal_secondary: int = EXTERNAL
    height_primary: int = BARO
    height_secondary: int = NONE
    source_timeout_s: float = 1.0  # [s] no fused sample this long: the source is lost
    source_recovery_s: float = 5.0  # [s] the primary healthy this long: back to it
    switch_blend_s: float = 10.0  # [s] time constant of the switch offset's decay
    external: ExternalConfig = field(default_factory=ExternalConfig)
    external_gate: float = 5.0  # [σ] innovation gate of external samples
    external_alignment: str = "estimate"  # estimate | configured
    external_yaw_offset: float = 0.0  # [rad] configured yaw of the external frame in map
    external_origin: Vec = (0.0, 0.0, 0.0)  # [m] configured origin of the external frame in map
    external_alignment_samples: int = 20
    external_fuse_yaw: bool = False  # the external yaw as a heading measurement (indoors)
    origin: Vec | None = None  # configured geodetic origin (lat °, lon °, alt m); None: home from GNSS
    # [s] position kept valid after a SPOOFED cut-off with no other horizontal source: long enough for health's
    # HOLD to brake on it, short enough that the landing then descends level (the core's rule for an invalid
    # position) instead of chasing a drifting dead-reckoned position (12 m in a 7 s descent in SITL at 10 s)
    dead_reckoning_valid_s: float = 3.0
    integrity_cut: bool = True  # a SPOOFED verdict cuts GNSS off (False: the verdict is only reported)
    history_capacity: int = 600  # IMU samples kept (1.2 s at 500 Hz)
    latency_compensation: bool = True  # False: delayed samples compared with the current state (for comparison)

    @property
    def gnss_used(self) -> bool:
        return GNSS in (self.horizontal_primary, self.horizontal_secondary, self.height_primary, self.height_secondary)


class GnssCorrection(NamedTuple):
    """One fused GNSS fix's correction, kept JOURNAL_S for an undo (a SPOOFED verdict)."""

    fix_t: float  # sample time of the fix [s]
    applied_t: float  # filter time it was applied at [s]
    dx: np.ndarray  # the error-state correction (N_STATES)
    wind_before: np.ndarray  # [m/s] the wind estimate before it


@dataclass
class NavStatus:
    """navigation/status' content (c4d_interfaces/EstimatorStatus without header and GNSS verdict)."""

    horizontal_source: int
    height_source: int
    source_switches: int
    last_switch_step_m: float
    last_switch_age_s: float
    external_healthy: bool
    external_aligned: bool
    external_age_s: float
    external_rate_hz: float
    external_latency_s: float
    external_yaw_offset_deg: float
    external_origin: np.ndarray
    external_fused: int
    rejected: dict[Rejection, int]
    gnss: Verdict
    gnss_undone_m: float  # [m] horizontal size of the last SPOOFED undo


class NavigationFilter:
    def __init__(self, ekf: NavigationEkf, config: NavigationConfig | None = None,
                 monitor: GnssIntegrityMonitor | None = None) -> None:
        self.ekf = ekf
        self.cfg = cfg = config or NavigationConfig()
        self._on_ground = False  # disarmed = standing still: zero-velocity updates bound the drift
        # the vehicle's status (armed or not) given at least once (setting on_ground): until then neither a
        # zero-velocity update (the vehicle may be flying: a restart in flight) nor home (_settled: the gyro
        # bias could not converge without those updates)
        self.status_known = False
        # commanded to stay put horizontally (a HOLD or LAND failsafe): without a horizontal source a loose
        # zero-velocity pseudo-measurement then bounds the drift; never while the vehicle may be flying a path
        # (on a 3 m/s circle it would cost 5 m in 6 s)
        self.station_keeping = False
        self.imu_t: float | None = None  # sample time of the last IMU sample [s]
        self.imu_count = 0
        self.mag: Vec | None = None
        self.range_m, self.range_t = math.inf, -math.inf
        self.omega = np.zeros(3)  # bias-corrected body rate [rad/s]
        self.alpha = np.zeros(3)  # low-passed body angular acceleration [rad/s²]
        self.history = StateHistory(cfg.history_capacity)
        self.validator = ExternalValidator(cfg.external)
        self.alignment = (FrameAlignment.configured(cfg.external_yaw_offset, np.asarray(cfg.external_origin))
                          if cfg.external_alignment == "configured" else FrameAlignment(cfg.external_alignment_samples))
        sel = dict(timeout_s=cfg.source_timeout_s, recovery_s=cfg.source_recovery_s, blend_s=cfg.switch_blend_s)
        self.horizontal = SourceSelector(SelectionConfig(cfg.horizontal_primary, cfg.horizontal_secondary, **sel), 2)
        self.height = SourceSelector(SelectionConfig(cfg.height_primary, cfg.height_secondary, **sel), 1)
        self.monitor = monitor or GnssIntegrityMonitor()
        self.verdict = self.monitor.verdict
        self.initialised = False  # a horizontal position was fused (or home set): offsets may be captured
        self.external_fused = 0
        self.gnss_undone_m = 0.0
        self._external_map: tuple[float, np.ndarray] | None = None  # last accepted external sample in map
        self._external_consistent = False
        self._external_arrivals: deque[float] = deque(maxlen=1000)
        self._external_latency = math.nan
        self._journal: deque[GnssCorrection] = deque()  # the GNSS corrections of the last JOURNAL_S
        self._accel_sum, self._accel_n = np.zeros(3), 0  # accelerometer readings since the last drag update
        self._last_dx: np.ndarray | None = None
        self._tick_t = -math.inf
        self._aligned_t = math.nan  # IMU time home collection first found the filter aligned
        self._step_pending: set[int] = set()  # selectors whose switch step is measured on the next fusion
        if cfg.origin is not None:
            ekf.origin = GeoOrigin(*cfg.origin)
        ekf.on_correction = self._on_correction

    # ---------------------------------------------------------------- IMU, magnetometer, range
    def imu(self, t: float, gyro: Vec, accel: Vec) -> bool:
        """One IMU sample at time `t` [s]; True when the estimate advanced (publish it)."""
        ekf, last = self.ekf, self.imu_t
        self.imu_t = t
        if not ekf.aligned:
            ekf.align(accel, self.mag)
            return False
        if last is None or not 0.0 < t - last < MAX_IMU_GAP_S:
            self._push(t)
            if last is not None:
                self.monitor.inertial_gap()  # the shadow misses the gap's displacement
            return False  # first sample after a gap: no integration over an unknown interval
        dt = t - last
        ekf.horizontal_aiding = self.horizontal.fusing(t) != NONE
        ekf.predict(gyro, accel, dt)
        self._push(t)
        self.imu_count += 1
        self._accel_sum += accel
        self._accel_n += 1
        if self.imu_count % ZUPT_EVERY == 0:
            if self.status_known and not self.on_ground:  # in flight: the mean specific force measures the drag
                ekf.update_drag(self._accel_sum / self._accel_n)  # (nothing is fused when drag fusion is off)
            self._accel_sum[:], self._accel_n = 0.0, 0
            if self.on_ground:
                ekf.update_zero_velocity()
            elif self.station_keeping and self.initialised and not ekf.horizontal_aiding:
                ekf.update_unaided_velocity()  # dead reckoning while held still: bound the drift (EKF docstring)
        omega = np.asarray(gyro) - ekf.bg
        self.alpha = 0.8 * self.alpha + 0.2 * (omega - self.omega) / dt
        self.omega = omega
        if t - self._tick_t >= TICK_S:
            self.tick(t)
        return True

    @property
    def on_ground(self) -> bool:
        """Disarmed (from the vehicle's status); False until a status was given (status_known)."""
        return self._on_ground

    @on_ground.setter
    def on_ground(self, value: bool) -> None:
        self._on_ground, self.status_known = bool(value), True

    def __setstate__(self, state: dict) -> None:
        """Snapshots journaled before on_ground became a property, or before drag fusion (resim of older flights)."""
        if "on_ground" in state:
            state["_on_ground"], state["status_known"] = state.pop("on_ground"), True
        state["_journal"] = deque(c if isinstance(c, GnssCorrection) else  # (fix t, applied t, δx (15))
                                  GnssCorrection(c[0], c[1], np.pad(c[2], (0, N_STATES - len(c[2]))), np.zeros(2))
                                  for c in state.get("_journal", ()))
        state.setdefault("_accel_sum", np.zeros(3))
        state.setdefault("_accel_n", 0)
        self.__dict__.update(state)

    def _settled(self) -> bool:
        """Home (and so a valid position, and arming) waits, while disarmed on the ground, until the roll/pitch
        gyro bias has converged (zero-velocity updates: ~3 s after alignment), at most HOME_SETTLE_MAX_S. Why: a
        vehicle that takes off earlier flies its first seconds on a drifting attitude — in SITL under load
        that made the IMU-only shadow disagree with GNSS by 1.6 m (a false SPOOFED verdict at take-off).
        Before the vehicle's status is heard it waits too: no zero-velocity update has run, so the bias σ
        is still its prior (CI: the core's status arrived late, home was set at once, SPOOFED 2 s after take-off)."""
        ekf = self.ekf
        if not ekf.aligned or self.imu_t is None:
            return True  # not yet aligned: as before — waiting would only delay home
        if self.status_known and not self.on_ground:
            return True  # armed: as before
        if math.isnan(self._aligned_t):
            self._aligned_t = self.imu_t
        if self.imu_t - self._aligned_t >= HOME_SETTLE_MAX_S:
            return True
        sigma = math.sqrt(max(ekf.P[9, 9], ekf.P[10, 10]))
        return self.status_known and sigma <= HOME_GYRO_BIAS_SIGMA

    def _push(self, t: float) -> None:
        ekf = self.ekf
        self.history.push(t, ekf.p, ekf.v, ekf.q, ekf.pi, ekf.vi)

    def _on_correction(self, dx: np.ndarray) -> None:
        self.history.shift(dx[0:3], dx[3:6])
        self._last_dx = dx

    def magnetometer(self, field: Vec) -> None:
        self.mag = field
        self.ekf.update_mag(field)

    def range_down(self, distance: float, t: float) -> None:
        """A downward range [m] at `t`; −inf means closer than the minimum range (on the ground)."""
        self.range_m, self.range_t = (0.0 if distance == -math.inf else distance), t
        if RANGE in self.height.configured and math.isfinite(self.range_m):
            self._height(RANGE, t, self.range_m, 0.05**2)

    def terrain_distance(self, t: float) -> float:
        """Distance to the ground [m] at `t`, NaN without a fresh finite range reading."""
        return float(self.range_m) if math.isfinite(self.range_m) and t - self.range_t < RANGE_TIMEOUT_S else math.nan

    # ---------------------------------------------------------------- the state at a sample time
    def _state_at(self, t: float) -> np.ndarray | None:
        """The stored state row at sample time t (the newest for a t slightly ahead of it); the
        current state when latency compensation is off; None outside the history."""
        if not self.cfg.latency_compensation:
            return self._current_row()
        if not self.history.count:
            return None
        return self.history.at(min(t, self.history.newest_t))

    def _fuse(self, selector: SourceSelector, source: int, rows: np.ndarray, z: np.ndarray, row: np.ndarray,
              Rm: np.ndarray, gate: float | None, t: float) -> bool:
        """Fuse the active `source`'s measurement z on `rows` against the state `row` at its sample time."""
        ekf = self.ekf
        predicted = row[P][rows]
        first = not self.initialised and rows is HORIZONTAL
        zz = selector.measurement(z, predicted, t, capture=not first)
        if first:  # the first horizontal position ever (configured origin / alignment): taken as it is
            ekf.p[0:2] += zz - predicted
            self.history.shift(np.array([*(zz - predicted), 0.0]), np.zeros(3))
            self.initialised = True
            ok = True
        else:
            pending = selector in self._step_pending
            p_before = ekf.p.copy()
            ok = ekf.update_position(rows, zz - predicted, Rm, None if pending else gate)
            if ok and pending:
                selector.last_step_m = float(np.linalg.norm(ekf.p - p_before))
                self._step_pending.discard(selector)
        if ok:
            selector.fused(source, t)
            if rows is HORIZONTAL:
                ekf.last_position = ekf.t
        return ok

    # ---------------------------------------------------------------- barometer
    def baro(self, pressure: float, t: float) -> None:
        """A static pressure [Pa] sampled at `t` [s]."""
        ekf = self.ekf
        altitude = altitude_at_pressure(pressure)
        if not math.isfinite(altitude):
            return
        if ekf.origin is None and self.cfg.gnss_used and self.cfg.origin is None:
            ekf.update_baro(pressure)  # home pending: averaged into the offset when it is set
            return
        if ekf.baro_offset is None:
            if ekf.aligned:
                ekf.learn_baro_offset(altitude)
            return
        if BARO in self.height.configured:
            self._height(BARO, t, altitude - ekf.baro_offset, ekf.cfg.baro_noise**2)

    def _height(self, source: int, t: float, z: float, var: float) -> None:
        """A height measurement [m, map z] of `source` at sample time t."""
        row = self._state_at(t)
        if row is None or not self.ekf.aligned:
            return
        zz = np.array([z])
        self.height.sample(source, t)
        if self.height.active == source and source not in self.height.blocked:
            if not self._fuse(self.height, source, VERTICAL, zz, row, np.array([[var]]), 5.0, t) and source == BARO:
                self.ekf.rejected["baro"] += 1

    # ---------------------------------------------------------------- GNSS
    def gnss(self, latitude: float, longitude: float, altitude: float, var_h: float, var_v: float, stamp: float) -> None:
        """A fix taken at `stamp` [s] with variances [m²] (<= 0: unknown); its age is measured on the IMU clock."""
        if not all(map(math.isfinite, (latitude, longitude, altitude, stamp))) or not self.cfg.gnss_used:
            return
        ekf = self.ekf
        sigma_h = math.sqrt(var_h) if var_h > 0 else DEFAULT_SIGMA_H_M
        sigma_v = math.sqrt(var_v) if var_v > 0 else DEFAULT_SIGMA_V_M
        if ekf.origin is None:
            ekf.set_home(latitude, longitude, altitude, ready=self._settled())
            if ekf.origin is not None:
                self.initialised = True
                self._push_home()
            return
        if not ekf.aligned or self.imu_t is None:
            return
        z = np.asarray(ekf.origin.to_enu(latitude, longitude, altitude))
        row = self._state_at(stamp)
        if row is None:  # older than the history: compared with the current state, moved by v·age
            row = self._current_row()
            z = z + ekf.v * max(0.0, self.imu_t - stamp)
        fix = FixCheck(t=stamp, position=z, sigma_h=sigma_h, sigma_v=sigma_v, predicted=row[P].copy(),
                       predicted_cov=ekf.P[0:3, 0:3].copy(), velocity=row[V].copy(), inertial_position=row[PI].copy(),
                       inertial_velocity=row[VI].copy(), external_position=self._external_at(stamp, row),
                       gyro_bias_sigma=math.sqrt(max(ekf.P[9, 9], ekf.P[10, 10])),
                       velocity_sigma=math.sqrt(max(ekf.P[3, 3], ekf.P[4, 4])))
        self._on_verdict(self.monitor.check_fix(fix))
        if not self.verdict.fuse and self.cfg.integrity_cut:
            return
        Rh, gate = np.eye(2) * sigma_h**2, ekf.cfg.gps_gate
        if GNSS in self.horizontal.configured:
            self.horizontal.sample(GNSS, stamp)
        if self.horizontal.active == GNSS:
            self._last_dx = None
            wind_before = ekf.wind.copy()
            if self._fuse(self.horizontal, GNSS, HORIZONTAL, z[0:2], row, Rh, gate, stamp):
                ekf.last_gps = ekf.t
                if self._last_dx is not None:
                    self._journal.append(GnssCorrection(stamp, ekf.t, self._last_dx.copy(), wind_before))
            elif ekf.t - ekf.last_gps > ekf.cfg.gps_reset_after_s and not self._alternative(self.horizontal, stamp):
                # back after an outage, dead reckoning beyond the gate and nothing else to trust: reset
                ekf.reset_position(np.array([z[0], z[1], ekf.p[2]]), np.diag([sigma_h**2, sigma_h**2, ekf.P[2, 2]]))
                ekf.last_gps = ekf.last_position = ekf.t
                self.horizontal.fused(GNSS, stamp)
            else:
                ekf.rejected["gps"] += 1
        if GNSS in self.height.configured:
            self._height(GNSS, stamp, float(z[2]), sigma_v**2)
        while self._journal and self._journal[0][1] < ekf.t - JOURNAL_S:
            self._journal.popleft()

    def _push_home(self) -> None:
        """Home was set: the estimate jumped to 0, the history restarts from it."""
        self.history.clear()
        if self.imu_t is not None:
            self._push(self.imu_t)

    def _current_row(self) -> np.ndarray:
        ekf, row = self.ekf, np.empty(16)
        row[P], row[V], row[Q], row[PI], row[VI] = ekf.p, ekf.v, ekf.q, ekf.pi, ekf.vi
        return row

    def _alternative(self, selector: SourceSelector, t: float) -> bool:
        return any(s != selector.active and selector.fresh(s, t) for s in selector.configured)

    def _external_at(self, t: float, row: np.ndarray) -> np.ndarray | None:
        """The healthy external source's map position at t: its last sample moved by the estimate's
        displacement between the two sample times (from the history); None when older than EXTERNAL_MATCH_S."""
        if self._external_map is None or not self._external_consistent:
            return None
        te, pe = self._external_map
        then = self.history.at(te) if abs(t - te) <= EXTERNAL_MATCH_S else None
        return None if then is None else pe + row[P] - then[P]

    def _on_verdict(self, verdict: Verdict) -> None:
        """A new integrity verdict: block GNSS while SPOOFED and, on the transition, undo what it fused since the onset."""
        was = self.verdict.state
        self.verdict = verdict
        spoofed = verdict.state == IntegrityState.SPOOFED and self.cfg.integrity_cut
        for selector in (self.horizontal, self.height):
            (selector.blocked.add if spoofed else selector.blocked.discard)(GNSS)
        if spoofed and was != IntegrityState.SPOOFED:
            now = self.imu_t if self.imu_t is not None else 0.0
            if self.horizontal.active == GNSS:  # on another source the estimate does not rest on the fixes:
                # undoing what GNSS fused before the switch would only put a step into it
                onset = verdict.onset_t if verdict.onset_t is not None else now
                since_switch = self.horizontal.last_switch_t if math.isfinite(self.horizontal.last_switch_t) else -math.inf
                self._undo_since(max(onset, since_switch))
            if self.horizontal.active == GNSS and not self._alternative(self.horizontal, now):
                self.ekf.valid_until = self.ekf.t + self.cfg.dead_reckoning_valid_s
            self.tick(now, monitor=False)

    def _undo_since(self, onset: float) -> None:
        """Remove the GNSS corrections fused from fixes sampled at or after `onset`: each position
        correction and what its velocity correction integrated to since it was applied; the wind goes back
        to what it was before the first of them (drag fusion moved it along with the pulled velocity)."""
        ekf = self.ekf
        dp, dv, rest = np.zeros(3), np.zeros(3), np.zeros(N_STATES - 6)
        kept: deque[GnssCorrection] = deque()
        wind_before: np.ndarray | None = None
        for c in self._journal:
            if c.fix_t >= onset:
                if wind_before is None:
                    wind_before = c.wind_before
                dp += c.dx[0:3] + c.dx[3:6] * (ekf.t - c.applied_t)
                dv += c.dx[3:6]
                rest += c.dx[6:]
            else:
                kept.append(c)
        self._journal = kept
        if wind_before is None:  # nothing fused since the onset
            self.gnss_undone_m = 0.0
            return
        ekf.p -= dp
        ekf.v -= dv
        # a drift the fixes pulled in is also explained as tilt and accelerometer bias: left in, dead
        # reckoning would keep accelerating the estimate (a 1 m/s drift cost an 11 m excursion in SITL)
        ekf.rotate(-rest[0:3])
        ekf.bg -= rest[3:6]
        ekf.ba -= rest[6:9]
        ekf.wind = wind_before.copy()
        # the undo is linear and leaves some velocity error (0.2-0.35 m/s in the closed-loop runs): say so,
        # so that drag fusion corrects the velocity rather than the biases
        ekf.P[3, 3] += UNDO_VELOCITY_SIGMA**2
        ekf.P[4, 4] += UNDO_VELOCITY_SIGMA**2
        self.history.shift(-dp, -dv)
        self.gnss_undone_m = float(np.hypot(dp[0], dp[1]))

    # ---------------------------------------------------------------- external pose
    def external(self, s: ExternalSample) -> Rejection | None:
        """An external pose sample; returns the rejection reason (counted) or None."""
        ekf, cfg = self.ekf, self.cfg
        if not ekf.aligned or not self.history.count or self.imu_t is None:
            self.validator.counts[Rejection.STALE] += 1  # no state to compare it with yet
            return Rejection.STALE
        checked = self.validator.check(s, self.history.newest_t, self.history.oldest_t)
        if isinstance(checked, Rejection):
            return checked
        row = self._state_at(s.t)
        if row is None:
            self.validator.counts[Rejection.STALE] += 1
            return Rejection.STALE
        map_yaw = _yaw(row[Q])
        if not self.alignment.aligned:
            if self._alignment_ready():
                self.alignment.add(s.position, s.yaw, row[P], map_yaw)
            return None
        z, yaw = self.alignment.to_map(s.position, s.yaw)
        R = self.alignment.covariance_to_map(checked.position_cov)
        gate = cfg.external_gate
        # judged as fused: in use, the source carries its switch offset (captured at the switch, bleeding
        # off) — a raw sample a few decimetres from the estimate right after a switch is not unhealthy
        as_fused = z.copy()
        if self.horizontal.active == EXTERNAL:
            as_fused[0:2] += self.horizontal.offset
        consistent = ekf.gate_passes(HORIZONTAL, as_fused[0:2] - row[P][0:2], R[0:2, 0:2], gate)
        self._external_map, self._external_consistent = (s.t, as_fused), consistent
        self._external_arrivals.append(self.imu_t)
        latency = self.imu_t - s.t
        self._external_latency = latency if math.isnan(self._external_latency) else \
            0.95 * self._external_latency + 0.05 * latency
        fused = rejected = False
        if EXTERNAL in self.horizontal.configured:
            self.horizontal.sample(EXTERNAL, s.t)
            if self.horizontal.active == EXTERNAL:
                ok = self._fuse(self.horizontal, EXTERNAL, HORIZONTAL, z[0:2], row, R[0:2, 0:2], gate, s.t)
                fused, rejected = fused or ok, rejected or not ok
        if EXTERNAL in self.height.configured:
            self._height(EXTERNAL, s.t, float(z[2]), float(R[2, 2]))
            fused = fused or self.height.last_fused.get(EXTERNAL) == s.t
        if cfg.external_fuse_yaw and (fused or not rejected):
            ok = ekf.update_yaw(wrap(yaw - map_yaw), checked.yaw_var, gate)
            fused, rejected = fused or ok, rejected or not ok
        if fused:
            self.external_fused += 1
        elif rejected:
            self.validator.counts[Rejection.GATE] += 1
            return Rejection.GATE
        return None

    def _alignment_ready(self) -> bool:
        """The estimate is worth aligning against: heading known (or given by the source itself)
        and a position (or the external source is the one that defines it)."""
        ekf, cfg = self.ekf, self.cfg
        heading = ekf.heading_valid or cfg.external_fuse_yaw
        position = ekf.position_valid or cfg.horizontal_primary == EXTERNAL or not self.initialised
        return heading and position

    # ---------------------------------------------------------------- 5 Hz: integrity, switching, status
    def tick(self, t: float, monitor: bool = True) -> None:
        """Integrity monitor tick (loss / degradation without fixes) and source switching at IMU time t."""
        self._tick_t = t
        if monitor and self.cfg.gnss_used and self.ekf.origin is not None:
            self._on_verdict(self.monitor.tick(t))
        for selector in (self.horizontal, self.height):
            if selector.update(t):
                self._step_pending.add(selector)

    def status(self) -> NavStatus:
        t = self.imu_t if self.imu_t is not None else 0.0
        h, z = self.horizontal, self.height
        last_switch = max((s.last_switch_t for s in (h, z) if not math.isnan(s.last_switch_t)), default=math.nan)
        step = h.last_step_m if h.last_switch_t == last_switch else z.last_step_m
        arrivals = self._external_arrivals
        while arrivals and arrivals[0] < t - 1.0:
            arrivals.popleft()
        external_age = t - self._external_map[0] if self._external_map is not None else math.nan
        return NavStatus(
            horizontal_source=h.fusing(t), height_source=z.fusing(t), source_switches=h.switches + z.switches,
            last_switch_step_m=step, last_switch_age_s=t - last_switch,
            external_healthy=self.external_healthy(t), external_aligned=self.alignment.aligned,
            external_age_s=external_age, external_rate_hz=float(len(arrivals)),
            external_latency_s=self._external_latency,
            external_yaw_offset_deg=math.degrees(self.alignment.yaw_offset), external_origin=self.alignment.origin,
            external_fused=self.external_fused, rejected=dict(self.validator.counts), gnss=self.verdict,
            gnss_undone_m=self.gnss_undone_m)

    def external_healthy(self, t: float) -> bool:
        return (self.alignment.aligned and self._external_consistent and self._external_map is not None
                and t - self._external_map[0] <= self.cfg.source_timeout_s)

    def status_key(self) -> tuple[object, ...]:
        """What changes navigation/status at once (published on change)."""
        t = self.imu_t or 0.0
        return (self.horizontal.fusing(t), self.height.fusing(t), self.horizontal.switches + self.height.switches,
                self.external_healthy(t), self.alignment.aligned, self.verdict.state)


def _yaw(q: np.ndarray) -> float:
    w, x, y, z = q
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
