"""`-p node.param:=value` overrides for a re-simulation: parsed, checked against what the flight recorded,
applied to the snapshots.

What can change: navigation's EKF constants (c4d_gnc.ekf.EkfConfig fields, e.g. `navigation.gps_gate`,
and the node parameter `mag_declination_deg`), navigation's `external_gate`, the core's barrier
parameters (`avoidance`, `avoid_*`). Everything else the nodes read once into derived objects at
start-up; resim refuses it by name rather than pretend (one line, exit 2).
"""

from __future__ import annotations

import dataclasses
import math
import re
from typing import Any

from c4d_common.barrier import Barrier, BarrierError, BarrierParams

ASSIGNMENT = re.compile(r"^(navigation|core)\.([A-Za-z_][A-Za-z0-9_]*):=(.*)$")
CORE_BARRIER = {"avoid_detection_range": "detection_range", "avoid_protection_radius": "protection_radius",
                "avoid_brake_decel": "brake_decel", "avoid_detour_after_s": "detour_after"}


class OverrideError(ValueError):
    """An override that does not exist, is out of range or cannot be re-simulated; str() is one line."""


def parse(items: list[str]) -> list[tuple[str, str, str]]:
    """(node, name, text) of each `node.param:=value`."""
    out = []
    for item in items:
        m = ASSIGNMENT.match(item)
        if not m:
            raise OverrideError(f"override {item!r}: expected navigation.<param>:=<value> or core.<param>:=<value>")
        out.append((m.group(1), m.group(2), m.group(3)))
    return out


def _number(node: str, name: str, text: str, low: float | None, high: float | None) -> float:
    try:
        value = float(text)
    except ValueError:
        raise OverrideError(f"{node}.{name}: {text!r} is not a number") from None
    if not math.isfinite(value) or (low is not None and value < low) or (high is not None and value > high):
        raise OverrideError(f"{node}.{name}: {text} is outside [{low}, {high}]")
    return value


def apply_navigation(filt: Any, params: dict, name: str, text: str) -> None:
    """Change one navigation parameter in the unpickled filter."""
    ekf = filt.ekf
    fields = {f.name: f for f in dataclasses.fields(ekf.cfg)}
    if name == "mag_declination_deg":
        _, low, high = params[name]
        ekf.cfg = dataclasses.replace(ekf.cfg, mag_declination=math.radians(_number("navigation", name, text, low, high)))
    elif name == "external_gate":
        _, low, high = params[name]
        filt.cfg = dataclasses.replace(filt.cfg, external_gate=_number("navigation", name, text, low, high))
    elif name in fields and name != "mag_declination":
        value = _number("navigation", name, text, 1.0 if name == "home_fixes" else 1e-9, None)
        ekf.cfg = dataclasses.replace(ekf.cfg, **{name: int(value) if name == "home_fixes" else value})
    elif name in params:
        raise OverrideError(f"navigation.{name}: read once at start-up into derived objects; resim cannot change it "
                            "(changeable: mag_declination_deg, external_gate, the EKF constants "
                            f"{', '.join(n for n in fields if n != 'mag_declination')})")
    else:
        raise OverrideError(f"navigation.{name}: no such parameter (changeable: mag_declination_deg, external_gate, "
                            f"{', '.join(n for n in fields if n != 'mag_declination')})")


def apply_core(run: Any, params: Any, ranges: dict, name: str, text: str) -> None:
    """Change one core parameter in the unpickled core."""
    core = run.core
    if name == "avoidance":
        if text.lower() not in ("true", "false"):
            raise OverrideError(f"core.avoidance: {text!r} is not true or false")
        on = text.lower() == "true"
        current = params.barrier() if core.barrier is None else core.barrier.p
        core.barrier = Barrier(current) if on else None
    elif name in CORE_BARRIER:
        low, high = ranges.get(name, (None, None))
        value = _number("core", name, text, low, high)
        if core.barrier is None:
            raise OverrideError(f"core.{name}: the flight ran without avoidance (core.avoidance:=true first)")
        try:
            core.barrier.p = BarrierParams(**{**dataclasses.asdict(core.barrier.p), CORE_BARRIER[name]: value})
        except BarrierError as exc:
            raise OverrideError(f"core.{name}: {exc}") from None
    elif hasattr(params, name):
        raise OverrideError(f"core.{name}: read once at start-up; resim cannot change it (changeable: avoidance, "
                            f"{', '.join(CORE_BARRIER)})")
    else:
        raise OverrideError(f"core.{name}: no such parameter (changeable: avoidance, {', '.join(CORE_BARRIER)})")
