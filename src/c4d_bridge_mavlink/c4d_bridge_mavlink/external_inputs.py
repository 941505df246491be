"""MAVLink position inputs (VIO, motion capture, another GNSS receiver) → c4d's frames, ROS-free.

What: `ExternalInputs.handle(msg, now)` turns VISION_POSITION_ESTIMATE (#102) and ATT_POS_MOCAP
(#138) into a `PoseSample` (→ navigation/external/pose), ODOMETRY (#331) into an `OdometrySample`
(→ navigation/external/odometry) and GPS_INPUT (#232) into a `GnssSample` (→ navigation/external/gnss),
or None when the frame is dropped. Every drop is counted per reason (`rejected`), every forwarded
sample per message (`accepted`); `take_warnings(now)` yields at most one line per reason per
WARN_PERIOD_S (the node logs them).

Conversions (frames.py for the fixed rotations):
- positions / velocities in a local NED frame → ENU: (x, y, z) → (y, x, −z); ODOMETRY's LOCAL_FRD
  (a local frame whose x is not north) takes the same swap: an FRD frame that happens to face north
  gives ENU exactly, any other heading is a yaw offset the navigation aligns (external frame yaw);
- attitudes body FRD → local NED (Euler roll / pitch / yaw of VISION_POSITION_ESTIMATE, quaternions
  of ATT_POS_MOCAP / ODOMETRY) → body FLU → ENU quaternions (frames.attitude_to_enu);
- body rates and body velocities FRD → FLU: (x, y, z) → (x, −y, −z);
- covariances: MAVLink sends the upper triangle of a 6×6 row-major matrix (21 floats; NaN in the
  first element = unknown). Unknown → all zeros (the navigation then takes its parameter). Known →
  the full symmetric matrix, transformed C' = T C Tᵀ: pose (x, y, z, roll, pitch, yaw) in NED with
  Euler-angle errors → ROS (x, y, z, rotation about X, Y, Z of the ENU frame): position by the NED→ENU
  swap; the Euler errors become a small rotation about the world axes with the level-attitude
  approximation [δφ cosψ − δθ sinψ, δφ sinψ + δθ cosψ, δψ] (exact in yaw; at 10° of tilt the roll /
  pitch mixing is off by < 2 %), then swapped to ENU. Twist covariances (ODOMETRY, body FRD) take
  the FRD→FLU signs. A covariance that is not finite, has a non-positive position variance or is
  not positive semi-definite is refused ("covariance").

Sample time (`SampleClock`): MAVLink stamps are µs on the *sender's* clock. What the navigation needs
is the sample's time on the ROS clock; the bridge computes the sample's *age at arrival* and stamps
`ros_now − age`. Per sender (sysid, compid) and message:
- usec ≥ 10¹⁵ (after 2001-09-09): UNIX epoch µs, age = wall clock − usec. Exact when the sender's
  clock is synchronised with this host's (NTP / chrony / the same machine); a future stamp beyond
  FUTURE_TOLERANCE_S is refused ("future");
- smaller: time since the sender's boot. If the sender answers the bridge's TIMESYNC requests, the
  offset comes from the round trip (error ≤ RTT/2, the asymmetry); otherwise it is estimated as the
  minimum of (arrival − usec) over the last OFFSET_WINDOW_S: the fastest sample defines age 0, so the
  age is underestimated by the minimum one-way delay (loopback / LAN < 1 ms; serial: a frame's
  transmission time, 2.6 ms for VISION_POSITION_ESTIMATE at 57600 baud) — a *constant* latency of the
  source itself (a VIO pipeline's processing time) is invisible without a shared clock;
- in a simulated graph (the ROS clock is sim time, far from the epoch) a stamp within
  SIM_CLOCK_TOLERANCE_S of the ROS clock is taken as the ROS clock itself (the simulator stamps with
  it), exact;
- usec 0: no stamp, the arrival time.
A stamp older than `max_age_s` is refused ("stale"); a sender clock jumping back (reboot) restarts
that sender's estimate. Why: the navigation fuses at the sample time (state history) — a wrong
stamp is a wrong latency compensation, so the error of each time base is documented
(docs/mavlink.md § external inputs).

Rate: one token bucket per (message, sender), `max_rate_hz` with a burst of RATE_BURST; the excess is
dropped before any conversion ("rate") — a 1 kHz flood costs the parse and a dict lookup per frame.
Sources: frames from our own system id (companions: a VIO computer is component 197, any component
but the autopilot's own) and from systems heard sending a GCS HEARTBEAT (`note_gcs`) are taken;
anyone else's (another vehicle's companion on a shared link) is refused ("source").
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from c4d_common import quat

from .frames import Vec, attitude_to_enu, frd_to_flu, ned_to_enu
from .offboard import Rejected
from .signing import mavlink

M = mavlink
NAN = math.nan
MESSAGES = ("VISION_POSITION_ESTIMATE", "ATT_POS_MOCAP", "ODOMETRY", "GPS_INPUT")
EPOCH_MIN_US = 10**15  # [µs] stamps above are UNIX time (2001-09-09 on)
FUTURE_TOLERANCE_S = 0.05  # [s] a UNIX-time stamp this far ahead of our clock is accepted as age 0
SIM_CLOCK_TOLERANCE_S = 2.0  # [s] a small stamp this close to a sim-time ROS clock is that clock
OFFSET_WINDOW_S = 10.0  # [s] min-filter window of the boot-time offset (sender clock drift ≤ 1 ms in it)
CLOCK_RESET_S = 1.0  # [s] a sender stamp this far behind its last one: the sender restarted
RATE_BURST = 5.0  # samples a source may send back to back above its rate
TIMESYNC_MAX_RTT_S = 0.05  # [s] round trips longer than this say too little about the offset
TIMESYNC_GAIN = 0.2  # low-pass of successive TIMESYNC offsets (jitter of each round trip)
WARN_PERIOD_S = 10.0  # [s] one warning line per reason at most this often
MAX_POSITION_M = 100_000.0  # [m] a local position beyond is nonsense
GPS_UERE_M = 1.0  # [m] user equivalent range error: σ = DOP × UERE when no accuracy is sent
ODOMETRY_POSE_FRAMES = {M.MAV_FRAME_LOCAL_NED: "LOCAL_NED", M.MAV_FRAME_LOCAL_FRD: "LOCAL_FRD"}
ODOMETRY_TWIST_FRAMES = {M.MAV_FRAME_BODY_FRD: "BODY_FRD", **ODOMETRY_POSE_FRAMES}  # PX4 accepts these
# GPS_FIX_TYPE → sensor_msgs/NavSatStatus.status (−1 NO_FIX, 0 FIX, 1 SBAS_FIX, 2 GBAS_FIX)
NAVSAT_STATUS = {2: 0, 3: 0, 4: 1, 5: 2, 6: 2, 7: 0, 8: 0}
NO_FIX = -1
COV_UNKNOWN, COV_APPROXIMATED, COV_DIAGONAL_KNOWN = 0, 1, 2  # NavSatFix.position_covariance_type
# level-attitude Euler error → rotation error about the world axes, then NED → ENU (see docstring)
_SWAP = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
_FRD_FLU = np.diag([1.0, -1.0, -1.0])


@dataclass(frozen=True)
class PoseSample:
    """geometry_msgs/PoseWithCovarianceStamped content: base_link in the external frame (ENU axes)."""

    stamp: float  # sample time on the ROS clock [s]
    position: Vec  # [m] ENU
    orientation: quat.Quat  # body FLU → ENU (w, x, y, z)
    covariance: tuple[float, ...]  # 36, row-major (x, y, z, rot X, rot Y, rot Z); zeros = unknown
    source: str  # MAVLink message name


@dataclass(frozen=True)
class OdometrySample:
    """nav_msgs/Odometry content: pose as PoseSample, twist in base_link (FLU)."""

    pose: PoseSample
    velocity: Vec  # [m/s] body FLU; NaN = not sent
    angular_velocity: Vec  # [rad/s] body FLU; NaN = not sent
    twist_covariance: tuple[float, ...]  # 36; zeros = unknown


@dataclass(frozen=True)
class GnssSample:
    """sensor_msgs/NavSatFix content."""

    stamp: float
    status: int  # NavSatStatus.status
    latitude: float  # [deg]; NaN without a fix
    longitude: float
    altitude: float  # [m] AMSL; NaN when ignored or 2D
    covariance: tuple[float, ...]  # 9, ENU row-major [m²]
    covariance_type: int  # NavSatFix.COVARIANCE_TYPE_*
    satellites: int


def upper_to_full(upper: Sequence[float], n: int = 6) -> np.ndarray:
    """The symmetric n×n matrix of a row-major upper triangle (MAVLink's 21-float covariances)."""
    full = np.zeros((n, n))
    full[np.triu_indices(n)] = np.asarray(upper, dtype=float)[: n * (n + 1) // 2]
    return full + np.triu(full, 1).T


def _checked(cov: np.ndarray, position_block: bool) -> tuple[float, ...]:
    """A transformed covariance as a 36-tuple, refused when not finite / not PSD / zero position variance."""
    if not np.all(np.isfinite(cov)):
        raise Rejected("covariance", "covariance not finite (NaN only in the first element means unknown)")
    if position_block and not np.all(np.diag(cov)[:3] > 0.0):
        raise Rejected("covariance", "covariance: position variances must be > 0")
    scale = max(1e-12, float(np.max(np.abs(np.diag(cov)))))
    if float(np.linalg.eigvalsh(cov)[0]) < -1e-9 * scale:
        raise Rejected("covariance", "covariance not positive semi-definite")
    return tuple(float(v) for v in cov.reshape(-1))


def pose_covariance_to_enu(upper: Sequence[float], yaw_ned: float) -> tuple[float, ...]:
    """MAVLink pose covariance (NED position, FRD Euler errors; 21 upper-triangle floats, NaN first =
    unknown) → ROS PoseWithCovariance.covariance in ENU (36 floats; all zeros = unknown)."""
    if not upper or math.isnan(upper[0]):
        return (0.0,) * 36
    c, s = math.cos(yaw_ned), math.sin(yaw_ned)
    euler_to_world = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])  # level attitude
    t = np.zeros((6, 6))
    t[:3, :3] = _SWAP
    t[3:, 3:] = _SWAP @ euler_to_world
    full = upper_to_full(upper)
    return _checked(t @ full @ t.T, position_block=True)


def twist_covariance_to_flu(upper: Sequence[float], to_body_flu: np.ndarray) -> tuple[float, ...]:
    """MAVLink velocity covariance (vx, vy, vz, rates; 21 floats) → ROS twist covariance in base_link
    (FLU); `to_body_flu` maps the sent velocity axes to body FLU (3×3)."""
    if not upper or math.isnan(upper[0]):
        return (0.0,) * 36
    t = np.zeros((6, 6))
    t[:3, :3] = to_body_flu
    t[3:, 3:] = _FRD_FLU
    full = upper_to_full(upper)
    return _checked(t @ full @ t.T, position_block=False)


def euler_frd_ned_to_enu(roll: float, pitch: float, yaw: float) -> quat.Quat:
    """MAVLink Euler angles (body FRD → NED, yaw clockwise from north) → body FLU → ENU quaternion."""
    return attitude_to_enu(quat.from_euler(roll, pitch, yaw))


def _finite(values: Sequence[float], what: str) -> None:
    if not all(math.isfinite(v) for v in values):
        raise Rejected("invalid", f"{what} not finite")


def _local_position(x: float, y: float, z: float) -> Vec:
    _finite((x, y, z), "position")
    if max(abs(x), abs(y), abs(z)) > MAX_POSITION_M:
        raise Rejected("range", f"position beyond {MAX_POSITION_M:.0f} m")
    return ned_to_enu((float(x), float(y), float(z)))


def _unit_quaternion(q: Sequence[float]) -> quat.Quat:
    values = tuple(float(v) for v in q)
    _finite(values, "quaternion")
    if not abs(math.sqrt(sum(v * v for v in values)) - 1.0) < 0.01:
        raise Rejected("quaternion", "quaternion not a unit quaternion")
    return quat.normalize(values)  # type: ignore[arg-type]


@dataclass
class _SourceClock:
    base: str = ""  # "epoch", "ros", "boot", "none"
    last_us: int = 0
    buckets: list[float] = field(default_factory=lambda: [math.inf, math.inf])  # min(arrival − stamp) per half window
    bucket_start: float = -math.inf
    timesync_offset: float | None = None  # [s] sender clock − our monotonic clock, from TIMESYNC


class SampleClock:
    """Sender µs stamps → age at arrival [s] (module docstring: time bases and their errors)."""

    def __init__(self, max_age_s: float) -> None:
        self.max_age_s = max_age_s
        self.sources: dict[tuple[int, int], _SourceClock] = {}
        self.resets = 0

    def timesync(self, source: tuple[int, int], offset_s: float) -> None:
        """The sender's clock minus our monotonic clock, measured by a TIMESYNC round trip (low-passed)."""
        clock = self.sources.setdefault(source, _SourceClock())
        old = clock.timesync_offset
        clock.timesync_offset = offset_s if old is None else old + TIMESYNC_GAIN * (offset_s - old)

    def boot_sources(self) -> bool:
        """Whether a sender stamps with its boot time (worth TIMESYNC requests)."""
        return any(c.base == "boot" for c in self.sources.values())

    def age(self, source: tuple[int, int], usec: int, mono: float, wall: float, ros: float) -> float:
        """Age [s] at arrival of a sample stamped `usec` by `source`; `mono`, `wall`, `ros` = now on the
        monotonic, UNIX and ROS clocks. Rejected ("future", "stale") when unusable."""
        clock = self.sources.setdefault(source, _SourceClock())
        if usec <= 0:
            return 0.0
        stamp = usec * 1e-6
        if usec >= EPOCH_MIN_US:
            clock.base = "epoch"
            age = wall - stamp
            if age < -FUTURE_TOLERANCE_S:
                raise Rejected("future", f"UNIX-time stamp {-age:.2f} s ahead of this host's clock (sync the clocks)")
            age = max(age, 0.0)
        elif ros < EPOCH_MIN_US * 1e-6 / 10 and (clock.base == "ros" or
                                                 (clock.base == "" and abs(ros - stamp) < SIM_CLOCK_TOLERANCE_S)):
            clock.base = "ros"  # a simulated graph: the sender stamps with the ROS (sim) clock
            age = ros - stamp
            if age < -FUTURE_TOLERANCE_S:
                raise Rejected("future", f"stamp {-age:.2f} s ahead of the ROS clock")
            age = max(age, 0.0)
        else:
            age = self._boot_age(clock, usec, mono)
        if age > self.max_age_s:
            raise Rejected("stale", f"sample {age:.2f} s old (max_age_s {self.max_age_s:g})")
        return age

    def _boot_age(self, clock: _SourceClock, usec: int, mono: float) -> float:
        stamp = usec * 1e-6
        if clock.base == "boot" and usec < clock.last_us - CLOCK_RESET_S * 1e6:
            clock.buckets, clock.bucket_start, clock.timesync_offset = [math.inf, math.inf], -math.inf, None
            self.resets += 1  # the sender restarted: its clock is a new one
        clock.base, clock.last_us = "boot", max(usec, clock.last_us) if clock.base == "boot" else usec
        if clock.timesync_offset is not None:
            return max(0.0, mono - (stamp - clock.timesync_offset))
        if mono - clock.bucket_start > OFFSET_WINDOW_S / 2:  # the older half leaves the window
            clock.buckets, clock.bucket_start = [clock.buckets[1], math.inf], mono
        clock.buckets[1] = min(clock.buckets[1], mono - stamp)
        offset = min(clock.buckets)
        return max(0.0, (mono - stamp) - offset)

    def describe(self) -> dict[str, str]:
        """Time base per sender for the link statistics."""
        return {f"clock_{s}_{c}": (k.base + ("+timesync" if k.timesync_offset is not None else ""))
                for (s, c), k in sorted(self.sources.items())}


class RateLimit:
    """Token buckets per key: at most `rate_hz` on average, RATE_BURST back to back."""

    def __init__(self, rate_hz: float) -> None:
        self.rate_hz = rate_hz
        self.buckets: dict[object, tuple[float, float]] = {}  # key → (tokens, time)

    def allow(self, key: object, now: float) -> bool:
        tokens, last = self.buckets.get(key, (RATE_BURST, now))
        tokens = min(RATE_BURST, tokens + max(0.0, now - last) * self.rate_hz)
        if tokens < 1.0:
            self.buckets[key] = (tokens, now)
            return False
        self.buckets[key] = (tokens - 1.0, now)
        return True


@dataclass(frozen=True)
class Clocks:
    """Now on the three clocks a conversion needs [s]."""

    mono: float  # time.monotonic()
    wall: float  # time.time()
    ros: float  # the node's clock (sim time in a simulated graph)


Sample = PoseSample | OdometrySample | GnssSample


class ExternalInputs:
    """The four MAVLink position inputs → samples in c4d's frames, with per-reason rejection counters."""

    def __init__(self, sysid: int, compid: int = M.MAV_COMP_ID_AUTOPILOT1, max_rate_hz: float = 250.0,
                 max_age_s: float = 0.5) -> None:
        self.sysid, self.compid = sysid, compid
        self.rate = RateLimit(max_rate_hz)
        self.clock = SampleClock(max_age_s)
        self.gcs_systems: set[int] = set()
        self.accepted: Counter[str] = Counter()
        self.rejected: Counter[str] = Counter()
        self._warned_at: dict[str, float] = {}
        self._pending: dict[str, str] = {}  # reason → newest text not yet warned

    def note_gcs(self, sysid: int) -> None:
        """A HEARTBEAT of type GCS came from `sysid`: its position inputs are taken."""
        self.gcs_systems.add(sysid)

    def allowed_source(self, sysid: int, compid: int) -> bool:
        """Our companions (our sysid, not our own component) and systems that announced themselves as a GCS."""
        return (sysid == self.sysid and compid != self.compid) or sysid in self.gcs_systems

    def handle(self, msg, now: Clocks) -> Sample | None:
        """One input frame → its sample, or None (dropped: counted per reason, warned per reason)."""
        kind = msg.get_type()
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        try:
            if not self.allowed_source(*source):
                raise Rejected("source", f"from system {source[0]} component {source[1]}: neither this vehicle's "
                                         "companion nor a GCS (send a GCS HEARTBEAT or use the vehicle's system id)")
            if not self.rate.allow((kind, source), now.mono):
                raise Rejected("rate", f"above {self.rate.rate_hz:g} Hz (max_rate_hz)")
            sample = self._convert(kind, msg, source, now)
        except Rejected as exc:
            self.rejected[exc.reason] += 1
            self._pending[exc.reason] = f"{kind}: {exc.text}"
            return None
        self.accepted[kind] += 1
        return sample

    def on_timesync(self, msg, mono: float):
        """TIMESYNC: a request (tc1 = 0) is answered with our monotonic clock [ns] (returned, to send);
        an answer to one of our requests (ts1 = its send time) gives the sender's clock offset."""
        if msg.tc1 == 0:
            return M.MAVLink_timesync_message(int(mono * 1e9), msg.ts1)
        rtt = mono - msg.ts1 * 1e-9
        if 0.0 <= rtt < TIMESYNC_MAX_RTT_S:
            self.clock.timesync((msg.get_srcSystem(), msg.get_srcComponent()), msg.tc1 * 1e-9 - (mono - rtt / 2))
        return None

    def timesync_request(self, mono: float):
        """A TIMESYNC request to send (about 1 Hz) while some sender stamps with its boot time; else None."""
        return M.MAVLink_timesync_message(0, int(mono * 1e9)) if self.clock.boot_sources() else None

    def take_warnings(self, now: float) -> list[str]:
        """One line per reason with new drops, each reason at most every WARN_PERIOD_S."""
        out = []
        for reason, text in list(self._pending.items()):
            if now - self._warned_at.get(reason, -math.inf) >= WARN_PERIOD_S:
                self._warned_at[reason] = now
                del self._pending[reason]
                out.append(f"external input dropped ({reason}, {self.rejected[reason]} so far): {text}")
        return out

    # ----------------------------------------------------------------------------- messages
    def _stamp(self, source: tuple[int, int], usec: int, now: Clocks) -> float:
        return now.ros - self.clock.age(source, int(usec), now.mono, now.wall, now.ros)

    def _convert(self, kind: str, msg, source: tuple[int, int], now: Clocks) -> Sample:
        if kind == "VISION_POSITION_ESTIMATE":
            position = _local_position(msg.x, msg.y, msg.z)
            _finite((msg.roll, msg.pitch, msg.yaw), "attitude")
            covariance = pose_covariance_to_enu(list(msg.covariance), msg.yaw)
            return PoseSample(self._stamp(source, msg.usec, now), position,
                              euler_frd_ned_to_enu(msg.roll, msg.pitch, msg.yaw), covariance, kind)
        if kind == "ATT_POS_MOCAP":
            position = _local_position(msg.x, msg.y, msg.z)
            q = _unit_quaternion(msg.q)
            covariance = pose_covariance_to_enu(list(msg.covariance), quat.to_euler(q)[2])
            return PoseSample(self._stamp(source, msg.time_usec, now), position, attitude_to_enu(q), covariance, kind)
        if kind == "ODOMETRY":
            return self._odometry(msg, source, now)
        if kind == "GPS_INPUT":
            return self._gps_input(msg, source, now)
        raise Rejected("message", f"{kind} is not a position input")

    def _odometry(self, msg, source: tuple[int, int], now: Clocks) -> OdometrySample:
        if msg.frame_id not in ODOMETRY_POSE_FRAMES:
            raise Rejected("frame", f"frame_id {msg.frame_id} not supported (LOCAL_NED, LOCAL_FRD)")
        if msg.child_frame_id not in ODOMETRY_TWIST_FRAMES:
            raise Rejected("frame", f"child_frame_id {msg.child_frame_id} not supported (BODY_FRD, LOCAL_NED, LOCAL_FRD)")
        position = _local_position(msg.x, msg.y, msg.z)
        q_ned = _unit_quaternion(msg.q)
        orientation = attitude_to_enu(q_ned)
        pose = PoseSample(self._stamp(source, msg.time_usec, now), position, orientation,
                          pose_covariance_to_enu(list(msg.pose_covariance), quat.to_euler(q_ned)[2]), "ODOMETRY")
        v = (float(msg.vx), float(msg.vy), float(msg.vz))
        rates = (float(msg.rollspeed), float(msg.pitchspeed), float(msg.yawspeed))
        for values, what in ((v, "velocity"), (rates, "body rates")):
            if any(math.isinf(x) for x in values) or 0 < sum(math.isnan(x) for x in values) < 3:
                raise Rejected("invalid", f"{what}: all three finite, or all NaN (unknown)")
        if msg.child_frame_id == M.MAV_FRAME_BODY_FRD:
            to_body = _FRD_FLU
        else:  # velocity in the local frame: rotate into base_link
            world_to_body = np.array([quat.rotate(orientation, axis) for axis in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0),
                                                                                  (0.0, 0.0, 1.0))])  # rows: body axes = Rᵀ
            to_body = world_to_body @ _SWAP
        velocity = tuple(float(x) for x in to_body @ np.array(v)) if math.isfinite(v[0]) else (NAN, NAN, NAN)
        twist_cov = twist_covariance_to_flu(list(msg.velocity_covariance), to_body)
        return OdometrySample(pose, velocity, frd_to_flu(rates), twist_cov)  # type: ignore[arg-type]

    def _gps_input(self, msg, source: tuple[int, int], now: Clocks) -> GnssSample:
        flags = msg.ignore_flags
        stamp = self._stamp(source, msg.time_usec, now)
        status = NAVSAT_STATUS.get(msg.fix_type, NO_FIX)
        if status == NO_FIX:  # no fix is news too (jamming): published without a position
            return GnssSample(stamp, NO_FIX, NAN, NAN, NAN, (0.0,) * 9, COV_UNKNOWN, msg.satellites_visible)
        lat, lon = msg.lat * 1e-7, msg.lon * 1e-7
        if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
            raise Rejected("range", "latitude / longitude out of range")
        alt = NAN if flags & M.GPS_INPUT_IGNORE_FLAG_ALT or msg.fix_type < 3 else float(msg.alt)
        if not math.isnan(alt) and not (math.isfinite(alt) and -1000.0 <= alt <= 50_000.0):
            raise Rejected("range", "altitude not finite or outside [-1000, 50000] m")
        sigma_h, cov_type = NAN, COV_UNKNOWN
        if not flags & M.GPS_INPUT_IGNORE_FLAG_HORIZONTAL_ACCURACY:
            sigma_h, cov_type = float(msg.horiz_accuracy), COV_DIAGONAL_KNOWN
        elif not flags & M.GPS_INPUT_IGNORE_FLAG_HDOP:
            sigma_h, cov_type = float(msg.hdop) * GPS_UERE_M, COV_APPROXIMATED
        sigma_v = NAN
        if not flags & M.GPS_INPUT_IGNORE_FLAG_VERTICAL_ACCURACY:
            sigma_v = float(msg.vert_accuracy)
        elif not flags & M.GPS_INPUT_IGNORE_FLAG_VDOP:
            sigma_v = float(msg.vdop) * GPS_UERE_M
        for sigma, what in ((sigma_h, "horizontal"), (sigma_v, "vertical")):
            if not math.isnan(sigma) and not (math.isfinite(sigma) and sigma > 0.0):
                raise Rejected("range", f"{what} accuracy / DOP must be > 0 (or its ignore flag set)")
        if math.isnan(sigma_h):
            covariance: tuple[float, ...] = (0.0,) * 9
        else:
            v = sigma_v if not math.isnan(sigma_v) else 1.5 * sigma_h  # the usual vertical/horizontal ratio
            covariance = (sigma_h**2, 0.0, 0.0, 0.0, sigma_h**2, 0.0, 0.0, 0.0, v**2)
        return GnssSample(stamp, status, lat, lon, alt, covariance, cov_type, msg.satellites_visible)

    def stats(self) -> dict[str, str]:
        """Counters for bridge/link_stats: accepted per message, rejected per reason, time bases."""
        out = {f"accepted_{k}": str(v) for k, v in sorted(self.accepted.items())}
        out.update({f"rejected_{k}": str(v) for k, v in sorted(self.rejected.items())})
        out["clock_resets"] = str(self.clock.resets)
        out.update(self.clock.describe())
        return out
