"""Airframe description: mass, inertia, motor geometry and constants, limits, controller gains.

Loaded from YAML and validated field by field (AirframeError names the missing or wrong
field). The motor layout is generated from `frame` (quad_x, hexa_x) and `arm_length_m`, or
given explicitly as `motors: [{angle_deg, spin}]` (angle from body +x towards +y, FLU; spin
`ccw` or `cw` seen from above). A ccw propeller pushes the body clockwise, i.e. it produces a
negative yaw torque (−k_m·f); cw the opposite. Shared by the controller (mixer) and the plant.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .config_file import ConfigError, read_yaml_mapping
from .share import share_file

GRAVITY = 9.80665

FRAMES = {
    # PX4-style numbering: 1 front-right ccw, 2 rear-left ccw, 3 front-left cw, 4 rear-right cw
    "quad_x": [(-45.0, "ccw"), (135.0, "ccw"), (45.0, "cw"), (-135.0, "cw")],
    # hexa-x: arms every 60° starting at +30° (front-left), alternating spin
    "hexa_x": [(30.0, "cw"), (90.0, "ccw"), (150.0, "cw"), (-150.0, "ccw"), (-90.0, "cw"), (-30.0, "ccw")],
}


class AirframeError(ConfigError):
    """Invalid airframe file; the message names the field."""


@dataclass(frozen=True)
class Motor:
    x: float  # [m] position in body FLU
    y: float
    yaw_sign: float  # +1: positive (CCW) yaw torque per newton of thrust, −1 otherwise


@dataclass(frozen=True)
class AxisGains:
    p: tuple[float, float, float]
    i: tuple[float, float, float]
    d: tuple[float, float, float]
    i_limit: tuple[float, float, float]


@dataclass(frozen=True)
class Airframe:
    name: str
    mass: float  # [kg]
    inertia: tuple[float, float, float]  # [kg m²] Ixx, Iyy, Izz (body FLU, principal axes)
    motors: tuple[Motor, ...]
    max_thrust: float  # [N] per motor at command 1.0
    torque_coefficient: float  # [m] yaw torque / thrust
    motor_time_constant: float  # [s]
    idle_command: float  # [1] command of an armed motor at zero demand
    drag_linear: tuple[float, float, float]  # [N/(m/s)] world-axis linear drag
    drag_angular: float  # [N m/(rad/s)]
    max_tilt: float  # [rad]
    max_horizontal_speed: float  # [m/s]
    max_climb_speed: float
    max_descent_speed: float
    max_rates: tuple[float, float, float]  # [rad/s]
    min_thrust_ratio: float  # of the total available thrust
    max_thrust_ratio: float
    position_p: tuple[float, float, float]
    velocity: AxisGains
    attitude_p: tuple[float, float, float]
    rate: AxisGains
    rate_d_cutoff_hz: float
    takeoff_speed: float  # [m/s]
    land_speed: float  # [m/s]

    @property
    def total_max_thrust(self) -> float:
        return self.max_thrust * len(self.motors)

    @property
    def hover_command(self) -> float:
        return self.mass * GRAVITY / self.total_max_thrust


def _get(doc: Mapping[str, Any], path: str) -> Any:
    value: object = doc
    for part in path.split("."):
        if not isinstance(value, Mapping) or part not in value:
            raise AirframeError(f"airframe: missing field '{path}'")
        value = value[part]
    return value


def _num(doc: Mapping[str, Any], path: str, positive: bool = True) -> float:
    value = _get(doc, path)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise AirframeError(f"airframe: field '{path}' must be a number, got {value!r}")
    if positive and value <= 0:
        raise AirframeError(f"airframe: field '{path}' must be > 0, got {value}")
    return float(value)


def _vec3(doc: Mapping[str, Any], path: str, positive: bool = False) -> tuple[float, float, float]:
    value = _get(doc, path)
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise AirframeError(f"airframe: field '{path}' must be a list of 3 numbers")
    out = []
    for k, item in enumerate(value):
        if isinstance(item, bool) or not isinstance(item, (int, float)) or (positive and item <= 0) or item < 0:
            raise AirframeError(f"airframe: field '{path}[{k}]' must be a {'positive' if positive else 'non-negative'} number")
        out.append(float(item))
    return out[0], out[1], out[2]


def _gains(doc: Mapping[str, Any], path: str) -> AxisGains:
    return AxisGains(_vec3(doc, f"{path}.p"), _vec3(doc, f"{path}.i"), _vec3(doc, f"{path}.d"),
                     _vec3(doc, f"{path}.i_limit"))


def _motors(doc: Mapping[str, Any], km: float) -> tuple[Motor, ...]:
    if "motors" in doc:
        layout = []
        for k, m in enumerate(doc["motors"] or []):
            if not isinstance(m, Mapping):
                raise AirframeError(f"airframe: field 'motors[{k}]' must be a mapping")
            layout.append((_num(m, "angle_deg", positive=False), _get(m, "spin")))
    else:
        frame = _get(doc, "frame")
        if frame not in FRAMES:
            raise AirframeError(f"airframe: field 'frame' must be one of {', '.join(FRAMES)} (or give 'motors'), got {frame!r}")
        layout = FRAMES[frame]
    if len(layout) < 4:
        raise AirframeError("airframe: field 'motors' needs at least 4 motors")
    arm = _num(doc, "arm_length_m")
    motors = []
    for k, (angle, spin) in enumerate(layout):
        if spin not in ("ccw", "cw"):
            raise AirframeError(f"airframe: field 'motors[{k}].spin' must be 'ccw' or 'cw'")
        a = math.radians(angle)
        motors.append(Motor(arm * math.cos(a), arm * math.sin(a), -1.0 if spin == "ccw" else 1.0))
    return tuple(motors)


def airframe_from_dict(doc: object) -> Airframe:
    if not isinstance(doc, Mapping):
        raise AirframeError("airframe: the file must hold a mapping")
    ratio_min, ratio_max = _num(doc, "limits.min_thrust_ratio"), _num(doc, "limits.max_thrust_ratio")
    if not 0 < ratio_min < ratio_max <= 1:
        raise AirframeError("airframe: field 'limits.min_thrust_ratio' / 'max_thrust_ratio' need 0 < min < max <= 1")
    airframe = Airframe(
        name=str(doc.get("name", "airframe")),
        mass=_num(doc, "mass_kg"),
        inertia=_vec3(doc, "inertia_kg_m2", positive=True),
        motors=_motors(doc, 0.0),
        max_thrust=_num(doc, "motor.max_thrust_n"),
        torque_coefficient=_num(doc, "motor.torque_coefficient_m"),
        motor_time_constant=_num(doc, "motor.time_constant_s"),
        idle_command=_num(doc, "motor.idle_command", positive=False),
        drag_linear=_vec3(doc, "drag.linear_n_per_m_s"),
        drag_angular=_num(doc, "drag.angular_n_m_per_rad_s", positive=False),
        max_tilt=math.radians(_num(doc, "limits.max_tilt_deg")),
        max_horizontal_speed=_num(doc, "limits.max_horizontal_speed_m_s"),
        max_climb_speed=_num(doc, "limits.max_climb_speed_m_s"),
        max_descent_speed=_num(doc, "limits.max_descent_speed_m_s"),
        max_rates=tuple(math.radians(r) for r in _vec3(doc, "limits.max_rate_deg_s", positive=True)),  # type: ignore[arg-type]
        min_thrust_ratio=ratio_min,
        max_thrust_ratio=ratio_max,
        position_p=_vec3(doc, "gains.position_p"),
        velocity=_gains(doc, "gains.velocity"),
        attitude_p=_vec3(doc, "gains.attitude_p"),
        rate=_gains(doc, "gains.rate"),
        rate_d_cutoff_hz=_num(doc, "gains.rate_d_cutoff_hz"),
        takeoff_speed=_num(doc, "guidance.takeoff_speed_m_s"),
        land_speed=_num(doc, "guidance.land_speed_m_s"),
    )
    if airframe.hover_command >= airframe.max_thrust_ratio:
        raise AirframeError(f"airframe: cannot hover: weight needs {airframe.hover_command:.0%} of the thrust")
    return airframe


def load_airframe(path: str | Path) -> Airframe:
    return airframe_from_dict(read_yaml_mapping(path, "airframe", AirframeError))


def airframe_by_ref(ref: str) -> Airframe:
    """An airframe named by a parameter: a YAML file path (ends .yaml / .yml) or a bundled name."""
    return load_airframe(Path(ref) if ref.endswith((".yaml", ".yml")) else default_airframe_path(ref))


def default_airframe_path(name: str = "quad_x") -> Path:
    """Path of a bundled airframe (installed share/ or the source tree)."""
    candidate = share_file("c4d_common", "config", "airframes", f"{name}.yaml")
    if not candidate.is_file():
        raise AirframeError(f"no bundled airframe named '{name}'")
    return candidate
