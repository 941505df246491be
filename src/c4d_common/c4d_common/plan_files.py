"""Plan files on disk: c4d YAML plans, QGroundControl `.plan` JSON (chosen by suffix) and QGC WPL
110 waypoint files (MAVProxy, Mission Planner, QGroundControl export; chosen by their first line).

Separate from `plan` (the model) because the QGroundControl reader needs the MAVLink item
mapping of `mavlink_items`, which itself builds on the model: plan <- mavlink_items <- plan_files.
"""

from __future__ import annotations

import json
from pathlib import Path

from .mavlink_items import FRAME_GLOBAL, FRAME_GLOBAL_INT, item_from_mavlink
from .plan import NAN, Geofence, Item, Plan, PlanError, plan_from_yaml_text


def plan_from_qgc_text(text: str) -> Plan:
    """QGroundControl `.plan` (JSON): simple mission items, inclusion polygon geofence."""
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
    polygon: list[tuple[float, float]] = []
    fence = doc.get("geoFence") or {}
    for poly in fence.get("polygons") or []:
        if poly.get("inclusion", True) and not polygon:
            polygon = [(float(v[0]), float(v[1])) for v in poly.get("polygon", [])]
    return Plan(tuple(items), Geofence(tuple(polygon)), "qgc-plan", float(mission.get("cruiseSpeed") or 0.0))


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
