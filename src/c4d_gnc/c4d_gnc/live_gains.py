"""The core's live-tunable gains and limits: airframe fields <-> flat parameters, and back.

What: `core_table(airframe)` lists every controller gain and limit of the cascade (position P,
velocity PID, attitude P, rate PID and its D filter, speed / tilt / rate / thrust limits, the
mixer's idle command, take-off and landing speeds) as scalar parameters named after the airframe
YAML (`gains.rate.roll.p`, `limits.max_tilt_deg`, ...) with unit, range and the airframe's value
as default; `airframe_with(airframe, values)` builds the Airframe those values describe. The
cross-field rule refuses a set that would not fly (min thrust ratio >= max, hover needing more
than the max thrust ratio, the idle command above the min thrust ratio).
Why flat scalars: a ROS parameter per number gives `ros2 param set core gains.rate.roll.p 30`,
a descriptor with range per value, and a one-to-one mapping onto MAVLink's scalar parameters.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace

from c4d_common.airframe import GRAVITY, Airframe, AxisGains
from c4d_common.tunable import Tunable, TunableTable

ROT = ("roll", "pitch", "yaw")
LIN = ("x", "y", "z")

# (field of AxisGains, unit, high, description)
_PID_TERMS = {
    "rate": (("p", "1/s", 200.0, "P gain: angular acceleration per rate error"),
             ("i", "1/s^2", 200.0, "I gain: angular acceleration per integrated rate error"),
             ("d", "1", 10.0, "D gain: angular acceleration per angular acceleration (on the filtered gyro)"),
             ("i_limit", "rad/s^2", 500.0, "integrator clamp")),
    "velocity": (("p", "1/s", 50.0, "P gain: acceleration per velocity error"),
                 ("i", "1/s^2", 50.0, "I gain: acceleration per integrated velocity error"),
                 ("d", "1", 10.0, "D gain: acceleration per measured acceleration"),
                 ("i_limit", "m/s^2", 20.0, "integrator clamp")),
}


def _items(af: Airframe) -> list[Tunable]:
    items: list[Tunable] = []
    for loop, axes in (("rate", ROT), ("velocity", LIN)):
        gains: AxisGains = getattr(af, loop)
        for k, axis in enumerate(axes):
            for term, unit, high, what in _PID_TERMS[loop]:
                items.append(Tunable(f"gains.{loop}.{axis}.{term}", getattr(gains, term)[k], unit, 0.0, high,
                                     f"{loop} loop, {axis}: {what}"))
    items.append(Tunable("gains.rate.d_cutoff_hz", af.rate_d_cutoff_hz, "Hz", 1.0, 250.0,
                         "low-pass cutoff of the rate loop's D term"))
    for k, axis in enumerate(ROT):
        items.append(Tunable(f"gains.attitude.{axis}.p", af.attitude_p[k], "1/s", 0.0, 50.0,
                             f"attitude loop, {axis}: body rate per attitude error"))
    for k, axis in enumerate(LIN):
        items.append(Tunable(f"gains.position.{axis}.p", af.position_p[k], "1/s", 0.0, 20.0,
                             f"position loop, {axis}: velocity per position error"))
    items += [
        Tunable("limits.max_tilt_deg", math.degrees(af.max_tilt), "deg", 5.0, 80.0, "tilt limit of the thrust vector"),
        Tunable("limits.max_horizontal_speed_m_s", af.max_horizontal_speed, "m/s", 0.1, 30.0,
                "horizontal speed limit of the position loop"),
        Tunable("limits.max_climb_speed_m_s", af.max_climb_speed, "m/s", 0.1, 15.0, "climb speed limit"),
        Tunable("limits.max_descent_speed_m_s", af.max_descent_speed, "m/s", 0.1, 10.0, "descent speed limit"),
    ]
    for k, axis in enumerate(ROT):
        items.append(Tunable(f"limits.max_rate_deg_s.{axis}", math.degrees(af.max_rates[k]), "deg/s", 5.0, 2000.0,
                             f"{axis} body-rate limit of the attitude loop"))
    items += [
        Tunable("limits.min_thrust_ratio", af.min_thrust_ratio, "1", 0.0, 1.0,
                "lowest collective thrust commanded in flight, of the total available"),
        Tunable("limits.max_thrust_ratio", af.max_thrust_ratio, "1", 0.05, 1.0,
                "highest collective thrust commanded, of the total available"),
        Tunable("motor.idle_command", af.idle_command, "1", 0.0, 0.5, "mixer: command of an armed motor at zero demand"),
        Tunable("guidance.takeoff_speed_m_s", af.takeoff_speed, "m/s", 0.1, 10.0, "climb speed of a take-off"),
        Tunable("guidance.land_speed_m_s", af.land_speed, "m/s", 0.1, 5.0, "descent speed of a landing"),
    ]
    return items


def core_table(af: Airframe) -> TunableTable:
    """The core's tunables with `af`'s values as defaults, and the rule that they must fly."""

    def cross(values: Mapping[str, float]) -> str:
        lo, hi = values["limits.min_thrust_ratio"], values["limits.max_thrust_ratio"]
        if not lo < hi:
            return f"limits.min_thrust_ratio ({lo:g}) must be below limits.max_thrust_ratio ({hi:g})"
        hover = af.mass * GRAVITY / af.total_max_thrust
        if hover >= hi:
            return f"limits.max_thrust_ratio {hi:g}: the vehicle needs {hover:.2f} of its thrust to hover"
        if values["motor.idle_command"] >= hi:
            return f"motor.idle_command ({values['motor.idle_command']:g}) must be below limits.max_thrust_ratio ({hi:g})"
        return ""

    return TunableTable(_items(af), cross)


def airframe_values(af: Airframe) -> dict[str, float]:
    return {t.name: t.default for t in _items(af)}


def airframe_with(af: Airframe, values: Mapping[str, float]) -> Airframe:
    """`af` with the tunables in `values` (all of them, or a subset: the rest stays `af`'s)."""
    v = {**airframe_values(af), **values}

    def vec(fmt: str, axes: tuple[str, ...]) -> tuple[float, float, float]:
        a, b, c = (float(v[fmt.format(axis)]) for axis in axes)
        return a, b, c

    def pid(loop: str, axes: tuple[str, ...]) -> AxisGains:
        return AxisGains(*(vec(f"gains.{loop}.{{}}.{term}", axes) for term in ("p", "i", "d", "i_limit")))

    rates = vec("limits.max_rate_deg_s.{}", ROT)
    return replace(
        af, rate=pid("rate", ROT), velocity=pid("velocity", LIN), rate_d_cutoff_hz=v["gains.rate.d_cutoff_hz"],
        attitude_p=vec("gains.attitude.{}.p", ROT), position_p=vec("gains.position.{}.p", LIN),
        max_tilt=math.radians(v["limits.max_tilt_deg"]), max_horizontal_speed=v["limits.max_horizontal_speed_m_s"],
        max_climb_speed=v["limits.max_climb_speed_m_s"], max_descent_speed=v["limits.max_descent_speed_m_s"],
        max_rates=(math.radians(rates[0]), math.radians(rates[1]), math.radians(rates[2])),
        min_thrust_ratio=v["limits.min_thrust_ratio"], max_thrust_ratio=v["limits.max_thrust_ratio"],
        idle_command=v["motor.idle_command"], takeoff_speed=v["guidance.takeoff_speed_m_s"],
        land_speed=v["guidance.land_speed_m_s"])
