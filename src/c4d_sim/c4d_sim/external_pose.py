"""External-pose emulator (VIO / motion capture / UWB stand-in) from the sim's ground truth, ROS-free.

What: at `rate_hz` the emulator samples the plant's true pose, drops the sample with
`dropout_probability`, adds seeded Gaussian noise (position `noise_m` per axis, heading
`yaw_noise_deg`, body velocity `velocity_noise_m_s`), expresses it in the emulated source's own
frame (yawed by `frame_yaw_deg` and offset by `frame_offset_m` from the sim's ENU world) and
holds it for `latency_s`: a sample is released once the plant's time has passed its sample time
+ latency, stamped with the sample time (what a real source does: measured at t, delivered later).
`mavlink_vision_position()` turns a sample into the fields of MAVLink VISION_POSITION_ESTIMATE
(NED position, FRD→NED Euler angles, the covariance's upper triangle, the reset counter).

Why here: the navigation filter's external-source path (latency compensation, frame alignment,
gating, switching on loss) needs a source whose error, delay and frame are known exactly, so
whole-graph tests can compare the estimate with the truth; a ROS-free class makes rate, latency,
noise, dropout and frame testable without DDS. Its random stream is its own (seed + 1), so turning
it on does not change the other sensors' noise (lockstep runs stay comparable bit for bit).

Frame convention: the source frame S has its origin at `frame_offset_m` in the world W (ENU, m)
and its x axis `frame_yaw_deg` counter-clockwise from east, z up: p_W = R_z(yaw)·p_S + offset,
so p_S = R_z(−yaw)·(p_W − offset), q_S←body = q_z(−yaw) ⊗ q_W←body.
"""

from __future__ import annotations

import math
import random
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field

from c4d_common import quat

from .plant import PlantState

Vec = tuple[float, float, float]
SIGMA_FLOOR_M = 1e-3  # [m] reported position σ never below this: a noise-free source still has a positive-definite covariance
SIGMA_FLOOR_RAD = math.radians(0.1)  # [rad] the same for the orientation
SIGMA_FLOOR_M_S = 1e-3  # [m/s] the same for the velocity
OUTPUTS = ("ros", "mavlink", "both")


def parse_udpout(url: str) -> tuple[str, int]:
    """(host, port) of `udpout:HOST:PORT` (the MAVLink output's destination); ValueError with one line otherwise."""
    kind, _, rest = url.partition(":")
    host, _, port = rest.rpartition(":")
    if kind != "udpout" or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"bad MAVLink URL {url!r}: expected udpout:HOST:PORT (e.g. udpout:127.0.0.1:14550)")
    return host, int(port)


@dataclass
class ExternalPoseSettings:
    """The emulator's settings; `enabled`, noises, dropout and frame may change at run time."""

    enabled: bool = False
    rate_hz: float = 100.0
    latency_s: float = 0.03
    noise_m: float = 0.01  # [m] 1σ per position axis
    yaw_noise_deg: float = 0.2  # [deg] 1σ heading
    velocity_noise_m_s: float = 0.02  # [m/s] 1σ per body velocity axis
    dropout_probability: float = 0.0  # per sample
    frame_yaw_deg: float = 0.0  # source frame's x axis, ccw from east [deg]
    frame_offset_m: Vec = (0.0, 0.0, 0.0)  # source frame's origin in the world ENU [m]


@dataclass(frozen=True)
class ExternalPoseSample:
    """One emulated measurement in the source frame (ENU-like axes of S, body FLU)."""

    stamp: float  # sample time [s, simulated]
    position: Vec  # [m] in S
    orientation: quat.Quat  # body FLU → S
    velocity_body: Vec  # [m/s] body FLU
    angular_velocity: Vec  # [rad/s] body FLU
    sigma_position: float  # [m] reported 1σ (per axis)
    sigma_orientation: float  # [rad] reported 1σ (per axis)
    sigma_velocity: float  # [m/s]
    reset_counter: int  # incremented when the source frame changes (a reset in the source's estimate)


def world_to_source(p: Sequence[float], yaw: float, offset: Sequence[float]) -> Vec:
    """A world ENU point in the source frame (yaw [rad], offset [m], see the module docstring)."""
    dx, dy, dz = p[0] - offset[0], p[1] - offset[1], p[2] - offset[2]
    c, s = math.cos(yaw), math.sin(yaw)
    return (c * dx + s * dy, -s * dx + c * dy, dz)


def source_to_world(p: Sequence[float], yaw: float, offset: Sequence[float]) -> Vec:
    """The inverse of `world_to_source`."""
    c, s = math.cos(yaw), math.sin(yaw)
    return (c * p[0] - s * p[1] + offset[0], s * p[0] + c * p[1] + offset[1], p[2] + offset[2])


def _yaw_quat(yaw: float) -> quat.Quat:
    return (math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2))


class ExternalPoseEmulator:
    """Samples, degrades, delays and frames the true pose; `sample()` at the rate, `due()` to release.

    Counters: `sampled` (taken while enabled), `dropped` (lost to `dropout_probability`),
    `released` (handed to the publishers)."""

    def __init__(self, settings: ExternalPoseSettings, seed: int = 0) -> None:
        self.settings = settings
        self.rng = random.Random(seed + 1)  # its own stream: the other sensors' noise is unchanged by it
        self.pending: deque[ExternalPoseSample] = deque()
        self.reset_counter = 0
        self.sampled = self.dropped = self.released = 0

    def set(self, name: str, value: object) -> str | None:
        """Apply a run-time setting (name without the 'external_pose.' prefix); the reason when refused.
        Disabling drops the samples in flight (the source is lost now); a frame change counts a reset."""
        s = self.settings
        if name == "enabled":
            s.enabled = bool(value)
            if not s.enabled:
                self.pending.clear()
        elif name in ("noise_m", "yaw_noise_deg", "velocity_noise_m_s", "dropout_probability", "frame_yaw_deg"):
            number = float(value)  # type: ignore[arg-type]
            if not math.isfinite(number):
                return f"{name} must be finite"
            setattr(s, name, number)
            self.reset_counter += name == "frame_yaw_deg"
        elif name == "frame_offset_m":
            values = [float(v) for v in value]  # type: ignore[attr-defined]
            if len(values) != 3 or not all(math.isfinite(v) for v in values):
                return "frame_offset_m needs 3 finite values [x, y, z]"
            s.frame_offset_m = (values[0], values[1], values[2])
            self.reset_counter += 1
        else:
            return f"'{name}' cannot change at run time"
        return None

    def sample(self, state: PlantState) -> None:
        """Take one sample of the true state now (called at `rate_hz`); queued for `latency_s`."""
        s = self.settings
        if not s.enabled:
            return
        self.sampled += 1
        g = self.rng.gauss
        if s.dropout_probability > 0.0 and self.rng.random() < s.dropout_probability:
            self.dropped += 1
            return
        yaw = math.radians(s.frame_yaw_deg)
        noisy = (state.position[0] + g(0.0, s.noise_m), state.position[1] + g(0.0, s.noise_m),
                 state.position[2] + g(0.0, s.noise_m))
        yaw_error = g(0.0, math.radians(s.yaw_noise_deg))
        orientation = quat.normalize(quat.mul(_yaw_quat(yaw_error - yaw), state.orientation))
        v = quat.rotate_inverse(state.orientation, state.velocity)
        sv = s.velocity_noise_m_s
        self.pending.append(ExternalPoseSample(
            stamp=state.t, position=world_to_source(noisy, yaw, s.frame_offset_m), orientation=orientation,
            velocity_body=(v[0] + g(0.0, sv), v[1] + g(0.0, sv), v[2] + g(0.0, sv)),
            angular_velocity=tuple(state.angular_velocity),  # type: ignore[arg-type]
            sigma_position=max(s.noise_m, SIGMA_FLOOR_M),
            sigma_orientation=max(math.radians(s.yaw_noise_deg), SIGMA_FLOOR_RAD),
            sigma_velocity=max(sv, SIGMA_FLOOR_M_S), reset_counter=self.reset_counter))

    def due(self, t: float) -> list[ExternalPoseSample]:
        """The samples whose latency has passed at simulated time `t`, oldest first."""
        out, pending, latency = [], self.pending, self.settings.latency_s
        while pending and pending[0].stamp + latency <= t + 1e-9:
            out.append(pending.popleft())
        self.released += len(out)
        return out


@dataclass(frozen=True)
class VisionPositionFields:
    """The fields of MAVLink VISION_POSITION_ESTIMATE (local NED frame of the source, body FRD)."""

    usec: int
    x: float  # [m] north (the source frame's y)
    y: float  # [m] east (its x)
    z: float  # [m] down
    roll: float  # [rad] FRD
    pitch: float
    yaw: float  # [rad] from north, clockwise
    covariance: list[float] = field(default_factory=list)  # upper triangle of the 6x6 (x, y, z, roll, pitch, yaw), row-major
    reset_counter: int = 0


def upper_triangle(diagonal: Sequence[float]) -> list[float]:
    """Row-major upper triangle of the 6x6 matrix with this diagonal (21 values, MAVLink's layout)."""
    out: list[float] = []
    for row in range(6):
        out += [diagonal[row] if col == row else 0.0 for col in range(row, 6)]
    return out


def mavlink_vision_position(sample: ExternalPoseSample, epoch: float) -> VisionPositionFields:
    """ENU/FLU → NED/FRD: x_N = y, y_E = x, z_D = −z; roll_FRD = roll_FLU, pitch_FRD = −pitch_FLU,
    yaw_NED = π/2 − yaw_ENU (wrapped to ±π). `usec` = (epoch + stamp) in µs: the sample's UNIX time in
    real time, simulated time since the sim's start in lockstep (epoch 0, like every sim stamp)."""
    roll, pitch, yaw = quat.to_euler(sample.orientation)
    yaw_ned = math.atan2(math.cos(yaw), math.sin(yaw))  # π/2 − yaw, wrapped
    p, sp, so = sample.position, sample.sigma_position ** 2, sample.sigma_orientation ** 2
    return VisionPositionFields(
        usec=round((epoch + sample.stamp) * 1e6), x=p[1], y=p[0], z=-p[2], roll=roll, pitch=-pitch, yaw=yaw_ned,
        covariance=upper_triangle((sp, sp, sp, so, so, so)), reset_counter=sample.reset_counter % 256)
