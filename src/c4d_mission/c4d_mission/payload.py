"""Payload coordination: when to trigger the (simulated) camera, and the capture log files.

The camera state follows the plan: the camera items before the mission's current item decide
the mode — off, on (capture at every waypoint reached), or distance (capture every N metres of
horizontal travel). `CameraTrigger.update()` is fed the vehicle position and the mission
progress and returns the captures to take; `CaptureLog` writes one GeoJSON and one CSV file per
flight. ROS-free; the payload node publishes the captures as c4d_interfaces/CaptureEvent.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass
from pathlib import Path

from c4d_common.plan import Plan

Vec = tuple[float, float, float]
EARLY_M = 0.25  # a distance capture may fire this far before its spot: a vehicle easing into a waypoint
# ends a hair short of the leg's end, and the last spot of a leg is often exactly there


@dataclass(frozen=True)
class Capture:
    index: int
    trigger: str  # "waypoint" | "distance" | "command"
    position: Vec  # local ENU
    mission_item: int


def camera_mode(plan: Plan, current_item: int) -> tuple[str, float]:
    """(mode, distance) in force while item `current_item` runs."""
    mode, distance = "off", 0.0
    for item in plan.items[: max(0, current_item)]:
        if item.type == "camera_distance":
            distance = item.camera_distance
            mode = "distance" if distance > 0 else "off"
        elif item.type == "camera_start":
            mode = "distance" if distance > 0 else "on"
        elif item.type == "camera_stop":
            mode = "off"
    return mode, distance


class CameraTrigger:
    """Decides captures. Distance mode measures progress along the *planned* path (the
    vehicle's position projected on the active leg), so capture spacing is exact and does not
    inflate with position noise; waypoint mode captures when a waypoint is reported reached."""

    def __init__(self) -> None:
        self.count = 0
        self._plan_key: object = None
        self._legs: dict[int, tuple[float, Vec, Vec]] = {}  # item -> (arc length at leg start, a, b)
        self._next_s: float | None = None
        self._last: tuple[float, Vec] | None = None  # (arc length, position) of the previous sample
        self._seen_reached = -1
        self._seen_capture_items: set[int] = set()

    def _path(self, plan: Plan, home) -> None:
        from c4d_common.plan_validation import local_point

        self._legs.clear()
        position, arc = (0.0, 0.0, 0.0), 0.0
        for k, item in enumerate(plan.items):
            if item.type in ("waypoint", "loiter") and all(math.isfinite(v) for v in (item.x, item.y, item.z)):
                target = local_point(item, home)
                self._legs[k] = (arc, position, target)
                arc += math.hypot(target[0] - position[0], target[1] - position[1])
                position = target
            elif item.type == "takeoff":
                position = (position[0], position[1], item.z)

    def update(self, plan: Plan | None, current_item: int, last_reached: int, position: Vec, home=None) -> list[Capture]:
        captures: list[Capture] = []
        if plan is None:
            return captures
        if self._plan_key != (id(plan), id(home)):
            self._plan_key = (id(plan), id(home))
            self._path(plan, home)
            self._next_s = None
        for k in range(max(0, self._seen_reached + 1), last_reached + 1):  # items completed since last time
            kind = plan.items[k].type if k < len(plan.items) else ""
            if kind == "camera_capture" and k not in self._seen_capture_items:
                self._seen_capture_items.add(k)
                captures.append(self._take("command", position, k))
            elif kind in ("waypoint", "loiter") and camera_mode(plan, k)[0] == "on":
                captures.append(self._take("waypoint", position, k))
            elif kind in ("waypoint", "loiter") and camera_mode(plan, k)[0] == "distance" and k in self._legs \
                    and self._next_s is not None:
                # the leg is complete (the vehicle is at its waypoint): fire what is due up to its end
                arc0, a, b = self._legs[k]
                end = arc0 + math.hypot(b[0] - a[0], b[1] - a[1])
                while self._next_s <= end + 1e-6:
                    captures.append(self._take("distance", position, k))
                    self._next_s += camera_mode(plan, k)[1]
        self._seen_reached = max(self._seen_reached, last_reached)
        mode, distance = camera_mode(plan, current_item)
        leg = self._legs.get(current_item)
        if mode != "distance" or leg is None:
            if mode != "distance":
                self._next_s = None
            self._last = None
            return captures
        arc0, a, b = leg
        length = math.hypot(b[0] - a[0], b[1] - a[1])
        along = 0.0
        if length > 1e-9:
            along = ((position[0] - a[0]) * (b[0] - a[0]) + (position[1] - a[1]) * (b[1] - a[1])) / length
        s = arc0 + min(max(along, 0.0), length)
        if self._next_s is None:  # mode just became active: first capture one spacing ahead
            self._next_s = arc0 + distance if along <= 0.0 else s + distance
        last_s, last_pos = self._last if self._last is not None else (s, position)
        while s >= self._next_s - EARLY_M:
            # geotag where the threshold was crossed (interpolated between the two samples), so a
            # late or sparse state sample does not move the capture along the track
            f = (min(self._next_s, s) - last_s) / (s - last_s) if s > last_s else 1.0
            at = tuple(a + min(max(f, 0.0), 1.0) * (b - a) for a, b in zip(last_pos, position, strict=True))
            captures.append(self._take("distance", at, current_item))  # type: ignore[arg-type]
            self._next_s += distance
        self._last = (s, position)
        return captures

    def _take(self, trigger: str, position: Vec, item: int) -> Capture:
        capture = Capture(self.count, trigger, position, item)
        self.count += 1
        return capture


class CaptureLog:
    """Geotagged captures of one flight as GeoJSON (FeatureCollection of points) and CSV."""

    def __init__(self, directory: Path, stem: str) -> None:
        directory.mkdir(parents=True, exist_ok=True)
        self.geojson = directory / f"{stem}.geojson"
        self.csv = directory / f"{stem}.csv"
        self.features: list[dict] = []
        with open(self.csv, "w", newline="") as f:
            csv.writer(f).writerow(["index", "time", "trigger", "latitude", "longitude", "altitude_amsl", "east", "north",
                                    "up", "mission_item", "file_name"])
        self._write_geojson()

    def add(self, capture: Capture, time_s: float, lat: float, lon: float, alt: float, file_name: str) -> None:
        e, n, u = capture.position
        with open(self.csv, "a", newline="") as f:
            csv.writer(f).writerow([capture.index, f"{time_s:.3f}", capture.trigger, f"{lat:.8f}", f"{lon:.8f}",
                                    f"{alt:.2f}", f"{e:.3f}", f"{n:.3f}", f"{u:.3f}", capture.mission_item, file_name])
        self.features.append({"type": "Feature", "geometry": {"type": "Point", "coordinates": [lon, lat, alt]},
                              "properties": {"index": capture.index, "time": time_s, "trigger": capture.trigger,
                                             "mission_item": capture.mission_item, "file_name": file_name}})
        self._write_geojson()

    def _write_geojson(self) -> None:
        tmp = self.geojson.with_suffix(".geojson.tmp")
        tmp.write_text(json.dumps({"type": "FeatureCollection", "features": self.features}, indent=1))
        tmp.replace(self.geojson)  # atomic: a reader never sees half a file
