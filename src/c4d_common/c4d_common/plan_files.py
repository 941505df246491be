"""Plan files on disk: c4d YAML plans, QGroundControl `.plan` JSON (chosen by suffix) and QGC WPL
110 waypoint files (MAVProxy, Mission Planner, QGroundControl export; chosen by their first line).

Separate from `plan` (the model) because the QGroundControl reader needs the MAVLink item
mapping of `mavlink_items`, which itself builds on the model: plan <- mavlink_items <- plan_files.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from .mavlink_items import FRAME_GLOBAL, FRAME_GLOBAL_INT, item_from_mavlink
from .plan import NAN, Geofence, Item, Plan, PlanError, plan_from_yaml_text


def plan_from_qgc_text(text: str) -> Plan:
    """QGroundControl `.plan` (JSON): simple mission items, the geofence (geofence_from_qgc)."""
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise PlanError(f"malformed .plan JSON at line {exc.lineno}") from None
    if not isinstance(doc, dict) or doc.get("fileType") != "Plan" or not isinstance(doc.get("mission"), dict):
        raise PlanError("not a QGroundControl .plan file (fileType 'Plan' with a 'mission')")
    mission = doc["mission"]
    items = []
    for k, raw in enumerate(mission.get("items") or []):
        where = f"item {k + 1}"
        if not isinstance(raw, dict) or raw.get("type") != "SimpleItem":
            raise PlanError(f"{where}: only SimpleItem is supported (got {raw.get('type') if isinstance(raw, dict) else raw!r})")
        params = raw.get("params")
        if not isinstance(params, list) or len(params) != 7:
            raise PlanError(f"{where}: 'params' must hold 7 values")
        try:
            values = [NAN if v is None else float(v) for v in params]
        except (TypeError, ValueError):
            raise PlanError(f"{where}: 'params' must be numbers or null") from None
        command, frame = raw.get("command"), raw.get("frame")
        if not isinstance(command, int) or not isinstance(frame, int):
            raise PlanError(f"{where}: 'command' and 'frame' must be integers")
        items.append(item_from_mavlink(command, frame, values, where=where))
    return Plan(tuple(items), geofence_from_qgc(doc.get("geoFence") or {}), "qgc-plan",
                float(mission.get("cruiseSpeed") or 0.0))


def _qgc_vertices(raw: object, where: str) -> tuple[tuple[float, float], ...]:
    if not isinstance(raw, list) or len(raw) < 3:
        raise PlanError(f"{where}: 'polygon' needs at least 3 [lat, lon] vertices")
    try:
        vertices = tuple((float(v[0]), float(v[1])) for v in raw)
    except (TypeError, ValueError, IndexError):
        raise PlanError(f"{where}: vertices must be [lat, lon] numbers") from None
    if not all(math.isfinite(c) for v in vertices for c in v):
        raise PlanError(f"{where}: non-finite vertex")
    return vertices


def geofence_from_qgc(fence: object) -> Geofence:
    """A QGroundControl `geoFence` section: one inclusion polygon (`"inclusion": true`, the
    default), any number of exclusion polygons (`"inclusion": false`) and exclusion circles
    (`{"circle": {"center": [lat, lon], "radius": r}, "inclusion": false}`). Inclusion circles and
    a second inclusion polygon have no c4d equivalent (a fence has one allowed area): PlanError."""
    if not isinstance(fence, dict):
        raise PlanError("geoFence must be an object")
    inclusion: tuple[tuple[float, float], ...] = ()
    exclusions = []
    for k, poly in enumerate(fence.get("polygons") or []):
        where = f"geoFence polygon {k + 1}"
        if not isinstance(poly, dict):
            raise PlanError(f"{where}: must be an object")
        vertices = _qgc_vertices(poly.get("polygon"), where)
        if not poly.get("inclusion", True):
            exclusions.append(vertices)
        elif inclusion:
            raise PlanError(f"{where}: a second inclusion polygon (c4d keeps one allowed area)")
        else:
            inclusion = vertices
    circles = []
    for k, raw in enumerate(fence.get("circles") or []):
        where = f"geoFence circle {k + 1}"
        circle = raw.get("circle") if isinstance(raw, dict) else None
        if not isinstance(circle, dict):
            raise PlanError(f"{where}: needs a 'circle' with 'center' and 'radius'")
        if raw.get("inclusion", True):
            raise PlanError(f"{where}: inclusion circles are not supported (use the max distance from home)")
        try:
            lat, lon, radius = float(circle["center"][0]), float(circle["center"][1]), float(circle["radius"])
        except (KeyError, TypeError, ValueError, IndexError):
            raise PlanError(f"{where}: 'center' must be [lat, lon] and 'radius' a number") from None
        if not (math.isfinite(lat) and math.isfinite(lon) and math.isfinite(radius) and radius > 0):
            raise PlanError(f"{where}: needs a finite centre and a radius > 0")
        circles.append((lat, lon, radius))
    return Geofence(inclusion, exclusion_polygons=tuple(exclusions), exclusion_circles=tuple(circles))


WPL_HEADER = "QGC WPL 110"


def plan_from_wpl_text(text: str) -> Plan:
    """QGC WPL 110: a header line, then one row per item, `seq current frame command param1..4 x y z
    autocontinue` (tab or space separated). Row 0 is the planned home, not a mission item (as in
    ArduPilot and MAVProxy): it is skipped, and its altitude turns absolute-altitude rows
    (frame 0) into altitudes above home. Items are named by their row number (1 = first item)."""
    lines = text.splitlines()
    if not lines or lines[0].strip() != WPL_HEADER:
        raise PlanError(f"not a waypoint file (first line must be '{WPL_HEADER}')")
    items: list[Item] = []
    home_altitude: float | None = None
    expected = 0  # the next row number
    for number, line in enumerate(lines[1:], start=2):
        fields = line.split()
        if not fields or line.lstrip().startswith("#"):
            continue
        where = f"line {number}"
        if len(fields) != 12:
            raise PlanError(f"{where}: 12 values needed, got {len(fields)}")
        try:
            seq, _current, frame, command = (int(v) for v in fields[:4])
            values = [float(v) for v in fields[4:11]]
        except ValueError:
            raise PlanError(f"{where}: seq, current, frame and command must be integers, the rest numbers") from None
        if seq != expected:
            raise PlanError(f"{where}: row {seq} where row {expected} was expected (row 0 is home)")
        expected += 1
        if seq == 0:  # the home row: not an item
            home_altitude = values[6] if frame in (FRAME_GLOBAL, FRAME_GLOBAL_INT) else None
            continue
        items.append(item_from_mavlink(command, frame, values, home_altitude, where=f"item {seq}"))
    return Plan(tuple(items), Geofence(), "qgc-wpl")


def load_plan(path: str | Path) -> Plan:
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise PlanError(f"cannot read {path}: {exc.strerror}") from None
    if text.lstrip().startswith(WPL_HEADER):
        return plan_from_wpl_text(text)
    return plan_from_qgc_text(text) if path.suffix == ".plan" else plan_from_yaml_text(text)
