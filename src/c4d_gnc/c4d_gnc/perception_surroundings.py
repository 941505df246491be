"""The perception node's surroundings part: sensors/scan + navigation/state → perception/surroundings
and perception/markers (the logic is c4d_gnc.surroundings; this is the ROS glue).

- Per scan (10–20 Hz): the newest navigation/state gives the pose (taken from a side node nobody
  spins, c4d_ros.drain.LatestSampler: no 500 Hz callback in this process besides the IMU path),
  the scan becomes detections, the tracker updates, Surroundings and the markers go out stamped
  with the scan's time. Without a valid horizontal position and heading the scan cannot be placed
  in `map`: no obstacles (tracks cleared), said once in the log.
- A timer at `wind_rate_hz` samples navigation/state for the wind estimate; when no scan came for
  `scan_timeout_s` (no lidar on this vehicle, or it stopped) the same timer publishes Surroundings
  with no obstacles, so the wind reaches its consumers on any vehicle.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from geometry_msgs.msg import Point
from sensor_msgs.msg import LaserScan
from visualization_msgs.msg import Marker, MarkerArray

from c4d_common.airframe import Airframe, AirframeError, default_airframe_path, load_airframe
from c4d_interfaces.msg import Obstacle, Surroundings, VehicleState
from c4d_ros.drain import LatestSampler
from c4d_ros.manifest import MARKERS, NAV_STATE, SCAN, SURROUNDINGS
from c4d_ros.params import ParameterError, Spec
from c4d_ros.stamps import stamp_to_s

from .surroundings import ClusterConfig, NavSample, Tracker, TrackerConfig, WindConfig, WindEstimator, detections

PARAMS = {
    "airframe": Spec("quad_x", "airframe whose mass and linear drag the wind estimate uses [name in c4d_common "
                     "config/airframes or YAML file path]", read_only=True),
    "cluster_gap_m": Spec(0.5, "scan points farther apart start a new obstacle [m]", 0.05, 10.0, read_only=True),
    "cluster_gap_beams": Spec(3.0, "... unless closer than this many beam spacings at their range [beams]", 1.0, 50.0,
                              read_only=True),
    "cluster_min_points": Spec(3, "smaller clusters are noise [points]", 1, 100, read_only=True),
    "max_post_radius_m": Spec(2.0, "a larger fitted circle is no post: the cluster is cut into map cells [m]",
                              0.1, 50.0, read_only=True),
    "wall_cell_m": Spec(1.0, "map grid a wall or box is cut into, one obstacle per cell [m]", 0.1, 20.0, read_only=True),
    "fit_tolerance_m": Spec(0.08, "RMS distance of a post's points to its fitted circle [m]", 0.001, 2.0,
                            read_only=True),
    "track_gate_m": Spec(1.0, "a detection farther than this from a track's prediction starts another track [m]",
                         0.05, 20.0, read_only=True),
    "track_max_misses": Spec(5, "a track is dropped after this many scans without a detection [scans]", 0, 1000,
                             read_only=True),
    "track_min_hits": Spec(2, "a track is published once detected in this many scans [scans]", 1, 100,
                           read_only=True),
    "track_accel_noise": Spec(2.0, "obstacle motion model: white acceleration, square root of its spectral "
                              "density [m/s^1.5]", 0.01, 100.0, read_only=True),
    "track_position_noise_m": Spec(0.1, "1-sigma of a detected centre [m]", 0.001, 10.0, read_only=True),
    "wind_time_constant_s": Spec(2.0, "low-pass of the instantaneous wind estimate [s]", 0.05, 600.0, read_only=True),
    "wind_converge_s": Spec(5.0, "airborne this long before the wind estimate is valid [s]", 0.0, 3600.0,
                            read_only=True),
    "wind_min_height_m": Spec(1.0, "below this height above home the vehicle counts as on the ground [m]",
                              0.0, 1000.0, read_only=True),
    "wind_rate_hz": Spec(10.0, "navigation/state sampling for the wind estimate; also the rate of Surroundings "
                         "without scans [Hz]", 1.0, 100.0, read_only=True),
    "scan_timeout_s": Spec(0.5, "no scan for this long: Surroundings go out from the wind timer, with no "
                           "obstacles [s]", 0.05, 60.0, read_only=True),
    "markers": Spec(True, "publish perception/markers (RViz / Foxglove) while someone subscribes [bool]",
                    read_only=True),
}

POSE_BITS = VehicleState.VALID_POSITION_XY | VehicleState.VALID_HEADING
WIND_BITS = (VehicleState.VALID_ATTITUDE | VehicleState.VALID_VELOCITY_XY | VehicleState.VALID_VELOCITY_Z
             | VehicleState.VALID_ACCELERATION | VehicleState.VALID_POSITION_Z)
MARKER_HEIGHT_M = 2.0  # drawn height of a 2-D obstacle's cylinder


def airframe_of(ref: str) -> Airframe:
    """The airframe named (bundled) or given as a YAML path; ParameterError (one line) otherwise."""
    try:
        return load_airframe(Path(ref) if ref.endswith((".yaml", ".yml")) else default_airframe_path(ref))
    except AirframeError as exc:
        raise ParameterError(f"parameter 'airframe': {exc}") from None


def configs(values: dict[str, Any]) -> tuple[ClusterConfig, TrackerConfig, WindConfig]:
    """The logic's configurations from the declared parameter values."""
    cluster = ClusterConfig(values["cluster_gap_m"], values["cluster_gap_beams"], values["cluster_min_points"],
                            values["max_post_radius_m"], values["wall_cell_m"], values["fit_tolerance_m"])
    tracker = TrackerConfig(gate_m=values["track_gate_m"], max_misses=values["track_max_misses"],
                            min_hits=values["track_min_hits"], accel_noise=values["track_accel_noise"],
                            position_noise_m=values["track_position_noise_m"])
    wind = WindConfig(values["wind_time_constant_s"], values["wind_converge_s"], values["wind_min_height_m"])
    return cluster, tracker, wind


def nav_sample(msg: VehicleState) -> NavSample:
    """The wind estimate's view of one navigation/state sample."""
    o = msg.orientation
    cov = msg.attitude_covariance
    tilt_var = max(cov[0], cov[4], 0.0)
    return NavSample(stamp_to_s(msg.header.stamp), msg.position.z,
                     (msg.velocity.x, msg.velocity.y, msg.velocity.z),
                     (msg.acceleration.x, msg.acceleration.y, msg.acceleration.z),
                     (o.w, o.x, o.y, o.z), msg.valid & WIND_BITS == WIND_BITS, math.sqrt(tilt_var))


def yaw_of(msg: VehicleState) -> float:
    o = msg.orientation
    return math.atan2(2.0 * (o.w * o.z + o.x * o.y), 1.0 - 2.0 * (o.y * o.y + o.z * o.z))


class SurroundingsNode:
    """Runs the scan pipeline and the wind estimate on `node`; navigation/state is sampled from
    `side_node` (never spun)."""

    def __init__(self, node: Any, side_node: Any, values: dict[str, Any], airframe: Airframe) -> None:
        self.node, self.clock, self.log = node, node.get_clock(), node.get_logger()
        self.cluster, tracker_cfg, wind_cfg = configs(values)
        self.tracker = Tracker(tracker_cfg)
        try:
            self.wind = WindEstimator.for_airframe(airframe, wind_cfg)
        except ValueError as exc:
            raise ParameterError(f"parameter 'airframe': {exc}") from None
        self.scan_timeout_s = float(values["scan_timeout_s"])
        self.markers = bool(values["markers"])
        self.state = LatestSampler(side_node, VehicleState, NAV_STATE.name, NAV_STATE.qos)
        self.pub = node.create_publisher(Surroundings, SURROUNDINGS.name, SURROUNDINGS.qos)
        self.pub_markers = node.create_publisher(MarkerArray, MARKERS.name, MARKERS.qos)
        node.create_subscription(LaserScan, SCAN.name, self.on_scan, SCAN.qos)
        node.create_timer(1.0 / float(values["wind_rate_hz"]), self.on_timer)
        self.last_scan_wall = -math.inf
        self.pose_warned = False
        self.scans = 0

    def now(self) -> float:
        return self.clock.now().nanoseconds * 1e-9

    def sample_wind(self) -> VehicleState | None:
        msg = self.state.latest()
        if msg is not None:
            self.wind.update(nav_sample(msg))
        return msg

    def on_timer(self) -> None:
        self.sample_wind()
        if self.now() - self.last_scan_wall > self.scan_timeout_s:
            if self.tracker.tracks:
                self.tracker.clear()
            self.publish(self.clock.now().to_msg(), [], 0.0)

    def on_scan(self, scan: LaserScan) -> None:
        """One scan: place it with the newest estimated pose, track, publish."""
        self.last_scan_wall = self.now()
        self.scans += 1
        state = self.sample_wind()
        t = stamp_to_s(scan.header.stamp)
        if state is None or state.valid & POSE_BITS != POSE_BITS:
            if not self.pose_warned:
                self.log.warning("scan ignored: no valid horizontal position and heading in navigation/state yet")
                self.pose_warned = True
            self.tracker.clear()
            self.publish(scan.header.stamp, [], math.nan)
            return
        self.pose_warned = False
        p = state.position
        found = detections(np.asarray(scan.ranges, dtype=np.float64), scan.angle_min, scan.angle_increment,
                           scan.range_min, scan.range_max, p.x, p.y, yaw_of(state), self.cluster)
        tracks = self.tracker.update(t, found)
        self.publish(scan.header.stamp, tracks, p.z, t)

    def publish(self, stamp: Any, tracks: list, z: float, t: float = 0.0) -> None:
        msg = Surroundings()
        msg.header.stamp = stamp
        msg.header.frame_id = "map"
        for tr in tracks:
            o = Obstacle(id=tr.id, radius=float(tr.radius), height=math.nan, confidence=float(tr.confidence),
                         age=float(t - tr.first_t))
            o.position.x, o.position.y, o.position.z = float(tr.x), float(tr.y), float(z)
            o.velocity.x, o.velocity.y = float(tr.vx), float(tr.vy)
            msg.obstacles.append(o)
        w = self.wind
        msg.wind.x, msg.wind.y = float(w.wind[0]), float(w.wind[1])
        msg.wind_valid = w.valid
        msg.wind_std = float(w.std)
        self.pub.publish(msg)
        if self.markers and self.pub_markers.get_subscription_count() > 0:
            self.pub_markers.publish(markers(msg))


def markers(s: Surroundings) -> MarkerArray:
    """One cylinder per obstacle (colour: confidence), an arrow for its velocity and a label; a
    DELETEALL first, so tracks gone since the last array vanish."""
    out = MarkerArray()
    out.markers.append(Marker(action=Marker.DELETEALL))
    for o in s.obstacles:
        cyl = Marker(ns="obstacles", id=o.id, type=Marker.CYLINDER, action=Marker.ADD)
        cyl.header = s.header
        cyl.pose.position.x, cyl.pose.position.y = o.position.x, o.position.y
        cyl.pose.position.z = o.position.z
        cyl.pose.orientation.w = 1.0
        cyl.scale.x = cyl.scale.y = 2.0 * o.radius
        cyl.scale.z = MARKER_HEIGHT_M
        cyl.color.r, cyl.color.g, cyl.color.b, cyl.color.a = 1.0 - o.confidence, 0.3, o.confidence, 0.6
        speed = math.hypot(o.velocity.x, o.velocity.y)
        label = Marker(ns="labels", id=o.id, type=Marker.TEXT_VIEW_FACING, action=Marker.ADD, text=f"{o.id}: {speed:.1f} m/s")
        label.header = s.header
        label.pose.position.x, label.pose.position.y = o.position.x, o.position.y
        label.pose.position.z = o.position.z + 0.5 * MARKER_HEIGHT_M + 0.3
        label.pose.orientation.w = 1.0
        label.scale.z = 0.4
        label.color.r = label.color.g = label.color.b = label.color.a = 1.0
        out.markers += [cyl, label]
        if speed > 0.2:
            out.markers.append(arrow(s, "velocity", o.id, o.position, o.velocity.x, o.velocity.y, (1.0, 0.5, 0.0)))
    return out


def arrow(s: Surroundings, ns: str, id_: int, at: Point, dx: float, dy: float, rgb: tuple[float, float, float]) -> Marker:
    """An arrow from `at` along (dx, dy) (one metre per m/s)."""
    m = Marker(ns=ns, id=id_, type=Marker.ARROW, action=Marker.ADD)
    m.header = s.header
    m.pose.orientation.w = 1.0
    m.points = [Point(x=at.x, y=at.y, z=at.z), Point(x=at.x + dx, y=at.y + dy, z=at.z)]
    m.scale.x, m.scale.y, m.scale.z = 0.1, 0.2, 0.2
    m.color.r, m.color.g, m.color.b = rgb
    m.color.a = 1.0
    return m
