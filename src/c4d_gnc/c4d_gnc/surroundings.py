"""What is around the vehicle (D3.3 §2.2.5, "UAV surrounding"): obstacles from a planar lidar scan
and the wind from the vehicle's own dynamics. ROS-free; the perception node feeds it.

Obstacles, per scan:
1. `scan_points`: the valid beams (finite, range_min <= r < range_max) of a scan in the levelled
   base_link frame (FLU rotated by the yaw only: the scan is level at the vehicle's height) become
   points in `map` with the estimated position and yaw.
2. `segment`: consecutive beams whose points lie closer than the gap (the larger of `gap_m` and
   `gap_beams` beam spacings at that range, so a far object is not cut by the beam spacing) form a
   cluster; the first and last cluster of a full 360° scan are joined when they touch.
3. `detect`: a cluster becomes one obstacle when a circle fits it (algebraic fit refined by a few
   Gauss-Newton steps on the geometric distance): a post seen from one side shows only its front
   arc, whose centroid lies ~r/2 in front of the true centre and whose spread underestimates the
   radius; the fitted circle has both right. A cluster that is no post (a wall, a box: fitted
   radius above `max_radius_m`, residual above `fit_tolerance_m`, or the centre on the sensor's
   side) is cut by a fixed `cell_m` grid in `map` along its longer axis (x or y) into pieces, each
   its bounding circle: a wall becomes a chain of circles that stay put while the vehicle moves.
4. `Tracker`: detections are associated to tracks by global nearest neighbour (greedy on the
   distance to each track's predicted position, within `gate_m`); each track runs a constant-
   velocity Kalman filter (white acceleration noise), so a mover's velocity comes out of the
   positions; confidence rises with hits and decays with misses, a track is dropped after
   `max_misses` scans without a detection, ids are stable while tracked.

Wind (`WindEstimator`): the plant's horizontal force balance is m·a = T·z_b − C·(v − w) (thrust
T along the body z axis, linear drag C per world axis against the air-relative velocity). With
the estimated acceleration a, velocity v and attitude z_b, and T from the vertical balance
(vertical wind taken as zero), the drag force and so the air-relative velocity follow, and
w = v + drag / C. This holds in any flight, not only in hover (the acceleration is in the
balance), but needs the vehicle airborne; a first-order low-pass smooths the IMU-rate noise,
and the estimate is valid after `converge_s` airborne with a valid attitude.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from c4d_common.airframe import GRAVITY, Airframe

# ----------------------------------------------------------------------------- obstacles


@dataclass(frozen=True)
class ClusterConfig:
    """Segmentation and fitting parameters (the perception node's parameters of the same names)."""

    gap_m: float = 0.5  # [m] points farther apart start a new cluster
    gap_beams: float = 3.0  # [1] ... unless closer than this many beam spacings at their range
    min_points: int = 3  # [1] smaller clusters are noise
    max_radius_m: float = 2.0  # [m] a larger fitted circle is no post: the cluster is cut into cells
    cell_m: float = 1.0  # [m] map grid a wall or box is cut into
    fit_tolerance_m: float = 0.08  # [m] RMS distance of the points to the fitted circle


@dataclass(frozen=True)
class Detection:
    """One obstacle seen in one scan: centre in map [m], radius [m], number of points."""

    x: float
    y: float
    radius: float
    points: int


MIN_RADIUS_M = 0.05  # [m] a piece of one or two points still has an extent


def scan_points(ranges: np.ndarray, angle_min: float, angle_increment: float, range_min: float,
                range_max: float, x: float, y: float, yaw: float) -> np.ndarray:
    """The valid returns of a scan as map points (N×2, in beam order). Invalid beams (NaN, ±inf,
    below range_min, at or beyond range_max: REP 117 "no return") are left out."""
    r = np.asarray(ranges, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(r) & (r >= range_min) & (r < range_max)
    idx = np.flatnonzero(valid)
    a = yaw + angle_min + angle_increment * idx
    rv = r[idx]
    return np.column_stack((x + rv * np.cos(a), y + rv * np.sin(a)))


def segment(points: np.ndarray, sensor: tuple[float, float], angle_increment: float, full_circle: bool,
            cfg: ClusterConfig) -> list[np.ndarray]:
    """Split beam-ordered map points into clusters of neighbours (see the module doc)."""
    n = len(points)
    if n == 0:
        return []
    step = np.hypot(*np.diff(points, axis=0).T)
    rng = np.hypot(points[:, 0] - sensor[0], points[:, 1] - sensor[1])
    allowed = np.maximum(cfg.gap_m, cfg.gap_beams * abs(angle_increment) * np.maximum(rng[:-1], rng[1:]))
    cuts = np.flatnonzero(step > allowed) + 1
    clusters = np.split(points, cuts)
    if full_circle and len(clusters) > 1:
        wrap = float(np.hypot(*(points[0] - points[-1])))
        if wrap <= max(cfg.gap_m, cfg.gap_beams * abs(angle_increment) * max(rng[0], rng[-1])):
            clusters[0] = np.vstack((clusters.pop(), clusters[0]))
    return clusters


def fit_circle(points: np.ndarray, iterations: int = 4) -> tuple[float, float, float, float] | None:
    """Least-squares circle through 2-D points: (cx, cy, r, rms residual), None if degenerate.
    The algebraic (Kåsa) fit starts a few Gauss-Newton steps on the geometric distance, which
    remove the algebraic fit's bias towards small circles on a short noisy arc."""
    if len(points) < 3:
        return None
    mean = points.mean(axis=0)
    p = points - mean
    a = np.column_stack((p, np.ones(len(p))))
    b = (p * p).sum(axis=1)
    try:
        sol, *_ = np.linalg.lstsq(a, b, rcond=None)
    except np.linalg.LinAlgError:
        return None
    c = sol[:2] / 2.0
    r2 = sol[2] + c @ c
    if not np.isfinite(r2) or r2 <= 0.0:
        return None
    radius = math.sqrt(r2)
    for _ in range(iterations):
        d = p - c
        dist = np.hypot(d[:, 0], d[:, 1])
        if np.any(dist < 1e-9):
            return None
        jac = np.column_stack((-d / dist[:, None], -np.ones(len(p))))
        step, *_ = np.linalg.lstsq(jac, -(dist - radius), rcond=None)
        c = c + step[:2]
        radius += float(step[2])
        if not np.all(np.isfinite(c)) or radius <= 0.0:
            return None
    d = p - c
    rms = float(np.sqrt(np.mean((np.hypot(d[:, 0], d[:, 1]) - radius) ** 2)))
    return float(c[0] + mean[0]), float(c[1] + mean[1]), radius, rms


def bounding(points: np.ndarray) -> Detection:
    """Bounding circle about the centroid (a piece of a wall or box)."""
    c = points.mean(axis=0)
    r = float(np.max(np.hypot(points[:, 0] - c[0], points[:, 1] - c[1])))
    return Detection(float(c[0]), float(c[1]), max(r, MIN_RADIUS_M), len(points))


def detect(cluster: np.ndarray, sensor: tuple[float, float], cfg: ClusterConfig) -> list[Detection]:
    """The obstacles of one cluster: its fitted circle when it is a post, else its grid pieces."""
    if len(cluster) < cfg.min_points:
        return []
    fit = fit_circle(cluster)
    if fit is not None:
        cx, cy, r, rms = fit
        near = float(np.min(np.hypot(cluster[:, 0] - sensor[0], cluster[:, 1] - sensor[1])))
        beyond = math.hypot(cx - sensor[0], cy - sensor[1]) > near  # convex towards the sensor
        if r <= cfg.max_radius_m and rms <= cfg.fit_tolerance_m and beyond:
            return [Detection(cx, cy, max(r, MIN_RADIUS_M), len(cluster))]
    spread = np.ptp(cluster, axis=0)
    axis = 0 if spread[0] >= spread[1] else 1  # cut across the long axis only: a wall on a grid line stays one row
    cells = np.floor(cluster[:, axis] / cfg.cell_m).astype(np.int64)
    return [bounding(cluster[cells == k]) for k in np.unique(cells)]


def detections(ranges: np.ndarray, angle_min: float, angle_increment: float, range_min: float, range_max: float,
               x: float, y: float, yaw: float, cfg: ClusterConfig) -> list[Detection]:
    """All obstacles seen in one scan taken at (x, y, yaw) in map."""
    points = scan_points(ranges, angle_min, angle_increment, range_min, range_max, x, y, yaw)
    full = abs(angle_increment) * len(ranges) >= 2.0 * math.pi - 1.5 * abs(angle_increment)
    out: list[Detection] = []
    for cluster in segment(points, (x, y), angle_increment, full, cfg):
        out.extend(detect(cluster, (x, y), cfg))
    return out


@dataclass(frozen=True)
class TrackerConfig:
    """Association and filter parameters (the perception node's parameters of the same names)."""

    gate_m: float = 1.0  # [m] a detection farther than this from a track's prediction is not it
    max_misses: int = 5  # [scans] a track is dropped after this many scans without a detection
    min_hits: int = 2  # [scans] a track is reported once detected this often
    accel_noise: float = 2.0  # [m/s²] white-acceleration spectral density of the motion model (√q)
    position_noise_m: float = 0.1  # [m] 1-σ of a detection's centre
    initial_speed_m_s: float = 3.0  # [m/s] 1-σ of a new track's unknown velocity
    confidence_gain: float = 0.3  # [1] fraction of the way to 1 (hit) or to 0 (miss) per scan
    radius_gain: float = 0.3  # [1] low-pass weight of a new radius


@dataclass
class Track:
    """One tracked obstacle. x/y axes share one 2×2 covariance (same model and noise on both)."""

    id: int
    x: float
    y: float
    vx: float
    vy: float
    radius: float
    first_t: float
    t: float  # time of the last prediction / update
    p11: float  # position variance [m²]
    p12: float  # position-velocity covariance [m²/s]
    p22: float  # velocity variance [m²/s²]
    hits: int = 1
    misses: int = 0
    confidence: float = 0.0

    def predict(self, t: float, q: float) -> None:
        """Constant-velocity prediction to time t (white acceleration noise q [m²/s³])."""
        dt = t - self.t
        if dt <= 0.0:
            return
        self.x += self.vx * dt
        self.y += self.vy * dt
        p11, p12, p22 = self.p11, self.p12, self.p22
        self.p11 = p11 + 2.0 * dt * p12 + dt * dt * p22 + q * dt ** 3 / 3.0
        self.p12 = p12 + dt * p22 + q * dt * dt / 2.0
        self.p22 = p22 + q * dt
        self.t = t

    def correct(self, d: Detection, r: float, cfg: TrackerConfig) -> None:
        """Kalman update with a detected centre (variance r [m²]); radius and confidence follow."""
        s = self.p11 + r
        k1, k2 = self.p11 / s, self.p12 / s
        ex, ey = d.x - self.x, d.y - self.y
        self.x += k1 * ex
        self.y += k1 * ey
        self.vx += k2 * ex
        self.vy += k2 * ey
        p11, p12, p22 = self.p11, self.p12, self.p22
        self.p11, self.p12, self.p22 = (1.0 - k1) * p11, (1.0 - k1) * p12, p22 - k2 * p12
        self.radius += cfg.radius_gain * (d.radius - self.radius)
        self.hits += 1
        self.misses = 0
        self.confidence += cfg.confidence_gain * (1.0 - self.confidence)

    def miss(self, cfg: TrackerConfig) -> None:
        self.misses += 1
        self.confidence *= 1.0 - cfg.confidence_gain

    @property
    def speed_std(self) -> float:
        return math.sqrt(max(self.p22, 0.0))


@dataclass
class Tracker:
    """Tracks across scans: predict, associate (greedy nearest neighbour in a gate), correct,
    start tracks from unmatched detections, drop tracks after `max_misses` misses."""

    cfg: TrackerConfig = field(default_factory=TrackerConfig)
    tracks: list[Track] = field(default_factory=list)
    next_id: int = 1

    def update(self, t: float, found: list[Detection]) -> list[Track]:
        """Take the detections of the scan at time t; return the reported (confirmed) tracks."""
        cfg = self.cfg
        q = cfg.accel_noise ** 2
        r = cfg.position_noise_m ** 2
        for tr in self.tracks:
            tr.predict(t, q)
        matched_tracks: set[int] = set()
        matched_dets: set[int] = set()
        if self.tracks and found:
            tp = np.array([(tr.x, tr.y) for tr in self.tracks])
            dp = np.array([(d.x, d.y) for d in found])
            dist = np.hypot(tp[:, None, 0] - dp[None, :, 0], tp[:, None, 1] - dp[None, :, 1])
            order = np.argsort(dist, axis=None)
            for flat in order[: int(np.count_nonzero(dist <= cfg.gate_m))]:
                i, j = divmod(int(flat), len(found))
                if i in matched_tracks or j in matched_dets:
                    continue
                self.tracks[i].correct(found[j], r, cfg)
                matched_tracks.add(i)
                matched_dets.add(j)
        for i, tr in enumerate(self.tracks):
            if i not in matched_tracks:
                tr.miss(cfg)
        self.tracks = [tr for tr in self.tracks if tr.misses <= cfg.max_misses]
        for j, d in enumerate(found):
            if j not in matched_dets:
                self.tracks.append(Track(self.next_id, d.x, d.y, 0.0, 0.0, d.radius, t, t, r, 0.0,
                                         cfg.initial_speed_m_s ** 2, confidence=cfg.confidence_gain))
                self.next_id += 1
        return self.confirmed()

    def confirmed(self) -> list[Track]:
        return [tr for tr in self.tracks if tr.hits >= self.cfg.min_hits]

    def clear(self) -> None:
        """Forget every track (the scan stopped: nothing is known any more); ids keep counting."""
        self.tracks = []


# ----------------------------------------------------------------------------- wind


@dataclass(frozen=True)
class NavSample:
    """What the wind estimate needs of one navigation/state sample (world ENU, body FLU)."""

    t: float  # [s] sample time
    z: float  # [m] height above the origin (home)
    velocity: tuple[float, float, float]  # [m/s]
    acceleration: tuple[float, float, float]  # [m/s²] kinematic, gravity removed
    q: tuple[float, float, float, float]  # (w, x, y, z) body → world
    valid: bool  # attitude, velocity and acceleration all valid
    tilt_std: float = 0.0  # [rad] 1-σ of roll/pitch (attitude covariance); 0 = unknown


@dataclass(frozen=True)
class WindConfig:
    """The wind filter's parameters (the perception node's parameters of the same names)."""

    time_constant_s: float = 2.0  # [s] low-pass of the instantaneous estimate
    converge_s: float = 5.0  # [s] airborne this long before the estimate is valid
    min_height_m: float = 1.0  # [m] above home: lower counts as on the ground (ground effect, contact)
    max_gap_s: float = 1.0  # [s] a longer gap between samples restarts the convergence


@dataclass
class WindEstimator:
    """Air-mass velocity (world ENU, horizontal) from the drag the vehicle's dynamics reveal.

    `mass` [kg] and `drag` [N/(m/s)] per world axis are the airframe's (c4d_common.airframe: the
    simulator's plant uses the same linear drag model)."""

    mass: float
    drag: tuple[float, float, float]
    cfg: WindConfig = field(default_factory=WindConfig)
    wind: tuple[float, float] = (0.0, 0.0)
    var: tuple[float, float] = (0.0, 0.0)  # low-passed squared deviation of the raw estimate
    airborne_s: float = 0.0
    tilt_std: float = 0.0
    last_t: float | None = None
    samples: int = 0

    def __post_init__(self) -> None:
        if not (self.mass > 0.0 and self.drag[0] > 0.0 and self.drag[1] > 0.0):
            raise ValueError("wind estimate: the airframe needs mass > 0 and horizontal drag > 0 "
                             f"(mass {self.mass}, drag {self.drag[:2]}): without drag the wind is unobservable")

    @classmethod
    def for_airframe(cls, af: Airframe, cfg: WindConfig | None = None) -> WindEstimator:
        return cls(af.mass, af.drag_linear, cfg or WindConfig())

    def raw(self, s: NavSample) -> tuple[float, float] | None:
        """The instantaneous wind of one sample, None when the balance cannot be solved."""
        w, qx, qy, qz = s.q
        zb = (2.0 * (qx * qz + w * qy), 2.0 * (qy * qz - w * qx), 1.0 - 2.0 * (qx * qx + qy * qy))
        if zb[2] < 0.5:  # tilted beyond 60°: no hover-like balance
            return None
        vx, vy, vz = s.velocity
        ax, ay, az = s.acceleration
        cx, cy, cz = self.drag
        m = self.mass
        thrust = (m * (az + GRAVITY) + cz * vz) / zb[2]  # vertical balance, no vertical wind
        if thrust <= 0.0:
            return None
        drag_x = m * ax - thrust * zb[0]  # = −C·(v − w)
        drag_y = m * ay - thrust * zb[1]
        return vx + drag_x / cx, vy + drag_y / cy

    def update(self, s: NavSample) -> None:
        """Fold in one sample (ignored when not newer than the last, invalid or on the ground)."""
        if self.last_t is not None and s.t <= self.last_t:
            return
        dt = 0.0 if self.last_t is None else s.t - self.last_t
        self.last_t = s.t
        finite = all(math.isfinite(v) for v in (*s.velocity, *s.acceleration, *s.q, s.z))
        sample = self.raw(s) if finite and s.valid and s.z >= self.cfg.min_height_m else None
        if sample is None or dt > self.cfg.max_gap_s:
            self.airborne_s = 0.0
            self.samples = 0
            return
        if self.samples == 0:
            self.wind, self.var = sample, (0.0, 0.0)
        else:
            alpha = 1.0 - math.exp(-dt / self.cfg.time_constant_s)
            ex, ey = sample[0] - self.wind[0], sample[1] - self.wind[1]
            self.wind = (self.wind[0] + alpha * ex, self.wind[1] + alpha * ey)
            self.var = (self.var[0] + alpha * (ex * ex - self.var[0]), self.var[1] + alpha * (ey * ey - self.var[1]))
            self.airborne_s += dt
        self.samples += 1
        self.tilt_std = s.tilt_std if math.isfinite(s.tilt_std) else 0.0

    @property
    def valid(self) -> bool:
        return self.airborne_s >= self.cfg.converge_s

    @property
    def std(self) -> float:
        """1-σ of each horizontal component: the raw samples' scatter reduced by the low-pass
        (as if independent at the mean sample spacing), with the attitude uncertainty's share
        (a tilt error δ reads as a drag of m·g·δ)."""
        if self.samples < 2 or self.airborne_s <= 0.0:
            return math.inf
        spacing = self.airborne_s / (self.samples - 1)
        reduce = min(1.0, spacing / (2.0 * self.cfg.time_constant_s))
        scatter = max(self.var) * reduce
        tilt = self.mass * GRAVITY * self.tilt_std / min(self.drag[0], self.drag[1])
        return math.sqrt(scatter + tilt * tilt)
