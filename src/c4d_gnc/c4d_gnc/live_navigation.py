"""The navigation node's live-tunable EKF noises and gates: EkfConfig fields <-> flat parameters.

What: `navigation_table(cfg)` lists every noise, gate and timeout of the EKF (c4d_gnc.ekf.EkfConfig:
IMU noises, bias random walks, GNSS gate, baro / magnetometer noise, validity and reset times,
zero-velocity and unaided-velocity pseudo-measurement sigmas, drag fusion's
coefficients and noise, the wind's random walk) as scalar parameters `ekf.<field>`
in the field's own unit (radians for the heading noise, as PX4's EKF2_HEAD_NOISE), with ranges and
`cfg`'s values as defaults; `ekf_with(cfg, values)` is the frozen EkfConfig those values describe
(dataclasses.replace: the navigation node swaps `ekf.cfg` whole, between two IMU samples).
Not here: the source selection, the external-pose settings and the geodetic origin (read once at
configure into derived objects: read-only parameters of the node), `mag_declination_deg` (read-only,
part of the vehicle's site) and `home_fixes` (used once, before take-off).
Why a table: the same checks for `ros2 param set`, MAVLink PARAM_SET (EKF2_* names) and
`c4d param`, and the per-vehicle store (c4d_common.tunable).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

from c4d_common.airframe import Airframe
from c4d_common.tunable import Tunable, TunableTable

from .ekf import EkfConfig, drag_config

PREFIX = "ekf."
# field: (unit, low, high, description)
FIELDS: dict[str, tuple[str, float, float, str]] = {
    "gyro_noise": ("rad/s", 1e-5, 1.0, "gyro noise, 1σ per sample (process noise of the attitude)"),
    "accel_noise": ("m/s^2", 1e-4, 10.0, "accelerometer noise, 1σ per sample (process noise of the velocity)"),
    "gyro_bias_walk": ("rad/s/sqrt(s)", 0.0, 0.1, "gyro bias random walk"),
    "accel_bias_walk": ("m/s^2/sqrt(s)", 0.0, 1.0, "accelerometer bias random walk"),
    "gps_gate": ("sigma", 1.0, 100.0, "GNSS position innovation gate (Mahalanobis distance per axis)"),
    "baro_noise": ("m", 0.01, 50.0, "barometric altitude noise, 1σ"),
    "mag_heading_noise": ("rad", 1e-3, 3.0, "magnetometer heading noise, 1σ"),
    "position_valid_s": ("s", 0.05, 60.0, "a position fix younger than this keeps the position valid"),
    "gps_reset_after_s": ("s", 0.1, 600.0, "after a GNSS outage this long, a fix the gate rejects resets the position"),
    "zero_velocity_sigma": ("m/s", 1e-3, 10.0, "zero-velocity update 1σ while the vehicle stands on the ground"),
    "unaided_velocity_sigma": ("m/s", 0.0, 100.0,
                               "horizontal zero-velocity pseudo-measurement 1σ in flight without aiding (0 = off)"),
    "heading_valid_s": ("s", 0.05, 600.0, "a magnetometer heading younger than this keeps the heading valid"),
    "drag_horizontal_per_s": ("1/s", 0.0, 10.0, "horizontal linear drag per unit mass (drag fusion; 0 = off)"),
    "drag_vertical_per_s": ("1/s", 0.0, 10.0, "vertical linear drag per unit mass (drag fusion)"),
    "drag_noise": ("m/s^2", 1e-4, 10.0, "drag fusion: 1σ of the 0.1 s mean horizontal specific force"),
    "wind_walk": ("m/s/sqrt(s)", 0.0, 10.0, "horizontal wind random walk (drag fusion)"),
}


def navigation_table(cfg: EkfConfig | None = None, airframe: Airframe | None = None) -> TunableTable:
    """The navigation node's tunables with `cfg`'s values (EkfConfig() when None) as defaults; with
    `airframe`, its drag as drag fusion's coefficients (the node's defaults, c4d_gnc.ekf.drag_config)."""
    cfg = cfg or EkfConfig()
    if airframe is not None:
        cfg = drag_config(airframe, cfg)
    return TunableTable(Tunable(PREFIX + f, float(getattr(cfg, f)), unit, low, high, what)
                        for f, (unit, low, high, what) in FIELDS.items())


def ekf_with(cfg: EkfConfig, values: Mapping[str, float]) -> EkfConfig:
    """`cfg` with the tunables in `values` (any subset; names `ekf.<field>`) replaced."""
    return replace(cfg, **{name[len(PREFIX):]: float(value) for name, value in values.items()})
