"""Plan files on disk: c4d YAML plans and QGroundControl `.plan` JSON, chosen by suffix.

Separate from `plan` (the model) because the QGroundControl reader needs the MAVLink item
mapping of `mavlink_items`, which itself builds on the model: plan <- mavlink_items <- plan_files.
"""

from __future__ import annotations

import json
from pathlib import Path

from .mavlink_items import item_from_mavlink
from .plan import NAN, Geofence, Plan, PlanError, plan_from_yaml_text


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


def load_plan(path: str | Path) -> Plan:
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise PlanError(f"cannot read {path}: {exc.strerror}") from None
    return plan_from_qgc_text(text) if path.suffix == ".plan" else plan_from_yaml_text(text)
