"""The simulator's YAML configuration (airframe, start point, physics rate, wind, sensors).

Kept apart from the node so that `c4d fly` can validate a sim config before any process starts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from c4d_common.airframe import GRAVITY, Airframe, AirframeError, default_airframe_path, load_airframe
from c4d_common.config_file import ConfigError, read_yaml_mapping, reject_unknown
from c4d_common.geodesy import GeoOrigin
from c4d_common.share import share_file

from .sensors import SensorConfig, SensorConfigError


class SimConfigError(ConfigError):
    """The sim configuration is unusable; the text is one line naming the field."""


@dataclass(frozen=True)
class SimConfig:
    """The simulated vehicle and its world, as read from the sim YAML."""

    airframe: Airframe
    sensors: SensorConfig
    physics_rate_hz: int
    origin: GeoOrigin  # home: the ENU frame of the plant and the ground truth starts here
    yaw: float  # [rad] ENU heading at the start
    truth_rate_hz: float  # sim/ground_truth
    seed: int
    wind_mean: tuple[float, float, float]  # [m/s] ENU
    gust: float  # [m/s] amplitude of the (1 - cos) gust from the east
    gust_period: float  # [s]

    @property
    def hover_current_a(self) -> float:
        """[A] the simulated pack's current at hover (the battery model of sensors.py: avionics plus
        motor current per newton of the airframe's weight); `c4d fly` checks endurance with it."""
        return self.sensors.avionics_amps + self.sensors.amps_per_newton * self.airframe.mass * GRAVITY


def default_sim_config() -> Path:
    return share_file("c4d_sim", "config", "sim.yaml")


def _number(doc: dict, key: str, where: str, positive: bool = False) -> float:
    value = doc.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or (positive and value <= 0):
        raise SimConfigError(f"sim config: field '{where}{key}' must be a {'positive ' if positive else ''}number, got {value!r}")
    return float(value)


def load_sim_config(path: Path) -> SimConfig:
    doc = read_yaml_mapping(path, "sim config", SimConfigError)
    reject_unknown(doc, {"airframe", "start", "physics_rate_hz", "ground_truth_rate_hz", "seed", "wind", "sensors"}, "sim config",
                   SimConfigError)
    start = doc.get("start") or {}
    for key in ("latitude", "longitude", "altitude"):
        _number(start, key, "start.")
    rate = _number(doc, "physics_rate_hz", "", positive=True) if "physics_rate_hz" in doc else 1000.0
    if rate < 1000 or 1_000_000 % int(rate) or rate != int(rate):
        raise SimConfigError("sim config: field 'physics_rate_hz' must be an integer >= 1000 dividing 1000000")
    wind = doc.get("wind") or {}
    mean = wind.get("mean_enu_m_s", [0.0, 0.0, 0.0])
    if not isinstance(mean, list) or len(mean) != 3:
        raise SimConfigError("sim config: field 'wind.mean_enu_m_s' must be a list of 3 numbers")
    try:
        sensors = SensorConfig.from_dict(doc.get("sensors"))
    except SensorConfigError as exc:
        raise SimConfigError(str(exc)) from None
    name = str(doc.get("airframe", "quad_x"))
    try:
        frame_path = Path(name) if name.endswith((".yaml", ".yml")) else default_airframe_path(name)
        airframe = load_airframe(frame_path)
    except AirframeError as exc:
        raise SimConfigError(str(exc)) from None
    return SimConfig(
        airframe=airframe, sensors=sensors, physics_rate_hz=int(rate),
        origin=GeoOrigin(float(start["latitude"]), float(start["longitude"]), float(start["altitude"])),
        yaw=math.radians(float(start.get("yaw_deg", 0.0))),
        truth_rate_hz=_number(doc, "ground_truth_rate_hz", "", positive=True) if "ground_truth_rate_hz" in doc else 100.0,
        seed=int(doc.get("seed", 1)),
        wind_mean=(float(mean[0]), float(mean[1]), float(mean[2])),
        gust=float(wind.get("gust_m_s", 0.0)), gust_period=float(wind.get("gust_period_s", 6.0)),
    )
