"""Closed loop with the navigation filter in it: plant → c4d_sim sensor models → the real
NavigationFilter (EKF, GNSS integrity monitor, source selection) → the GNC core → plant.

Why: the GNSS fault scenarios of issue 19 (spoofed or lost GNSS with no other horizontal source,
then hold and land) are decided by what the estimate does in dead reckoning and by how the core
flies on it. The whole graph flies them once per CI run; this loop flies them deterministically
(seeded), in ~2 s of wall time each, so that several seeds can be asserted on. The health node's
policy is modelled by its timing (c4d_health/config/failsafe.yaml, gnss_spoofed: HOLD 1 s after
the verdict, LAND 1 s later); the navigation node's rule "station keeping during a HOLD or LAND
failsafe" (unaided-velocity pseudo-measurement) is applied as the node does. `hover_in_wind` measures
what drag fusion costs with GNSS: the estimate's velocity error in steady wind and in gusts.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import yaml
from closed_loop import NO_NOISE, ClosedLoop

from c4d_common.airframe import default_airframe_path, load_airframe
from c4d_common.geodesy import GeoOrigin
from c4d_gnc.core_config import default_config_path
from c4d_gnc.ekf import EkfConfig, NavigationEkf, drag_config
from c4d_gnc.gnc import Command, Request, StateSample
from c4d_gnc.gnss_integrity import IntegrityState
from c4d_gnc.navigation_filter import NavigationConfig, NavigationFilter
from c4d_gnc.source_selection import GNSS, NONE
from c4d_sim.sensors import SensorConfig, SensorSuite
from c4d_sim.world import WindField

HOME = GeoOrigin(43.5629, 1.4815, 146.0)
POLICY_DELAY_S = 1.0  # failsafe.yaml gnss_spoofed: delay_s
THEN_LAND_AFTER_S = 1.0  # ... then_after_s
JAM_DETECTED_AFTER_S = 2.0  # a lost GNSS: the hold starts this long after the last fix (gnss_jammed's delay)


@dataclass
class FaultFlight:
    """What one flight measured: ground truth from the plant."""

    flagged_s: float = math.nan  # [s] from the fault's start to the SPOOFED verdict (jam: JAM_DETECTED_AFTER_S)
    farthest_m: float = 0.0  # [m] largest true horizontal distance from where the fault started
    touchdown_m: float = math.nan  # [m] true horizontal distance at disarm
    at_phase_m: dict[str, float] = field(default_factory=dict)  # true distance when HOLD / LAND began
    velocity_valid_in_descent: bool = True  # the horizontal velocity stayed valid while the position was not


@dataclass
class Rig:
    """The loop, the sensors and the filter of one seeded flight; `jammed`: no fix reaches the filter;
    `wind`: the air's velocity at the plant's time (None: still air)."""

    loop: ClosedLoop
    sensors: SensorSuite
    nav: NavigationFilter
    jammed: bool = False
    wind: WindField | None = None

    @property
    def ekf(self) -> NavigationEkf:
        return self.nav.ekf


def airborne_rig(seed: int, drag: bool, altitude: float = 5.0, wind: WindField | None = None) -> Rig:
    """Home set on the ground (8 s), then take-off to `altitude` and 12 s of hover on GNSS."""
    airframe = load_airframe(default_airframe_path("quad_x"))
    with open(default_config_path()) as f:
        loop = ClosedLoop(airframe, yaml.safe_load(f)["executive"], NO_NOISE, seed=seed)
    nav = NavigationFilter(NavigationEkf(drag_config(airframe) if drag else EkfConfig()),
                           NavigationConfig(horizontal_primary=GNSS, horizontal_secondary=NONE))
    rig = Rig(loop, SensorSuite(SensorConfig(), HOME, seed=seed), nav, wind=wind)
    nav.on_ground = True
    loop.input_hook = _sensing(rig)
    loop.run(8.0)
    if rig.ekf.origin is None:
        raise RuntimeError("home was not set in 8 s")
    nav.on_ground = False
    loop.command(Request(Command.TAKEOFF, altitude=altitude))
    loop.run(12.0)
    return rig


def _sensing(rig: Rig) -> Callable[[float], None]:
    """The core's input-phase hook: the sensors at their rates into the filter, its estimate into the core."""
    loop, sensors, nav, ekf = rig.loop, rig.sensors, rig.nav, rig.ekf
    dt, tick = loop.tick_s, [0]

    def sense(now: float) -> None:
        k, s = tick[0], loop.plant.state
        tick[0] += 1
        if rig.wind is not None:
            loop.plant.wind = rig.wind.at(s.t)
        imu = sensors.imu(s, dt)
        if imu is not None:
            nav.imu(s.t, imu.gyro, imu.accel)
        if k % 10 == 0:
            mag, baro = sensors.mag(s), sensors.baro(s)
            if mag is not None:
                nav.magnetometer(mag)
            if baro is not None:
                nav.baro(baro[1], s.t)
        if k % 50 == 25 and not rig.jammed:
            fix = sensors.gps(s, 0.1)
            if fix is not None:
                nav.gnss(fix.latitude, fix.longitude, fix.altitude, fix.sigma_h**2, fix.sigma_v**2, s.t)
        if ekf.origin is not None and ekf.aligned:
            old = loop.core.inputs.state
            loop.core.inputs.state = StateSample(now, tuple(ekf.p), tuple(ekf.v), ekf.q, old.angular_velocity,
                                                 valid_position=ekf.position_valid,
                                                 valid_velocity=ekf.velocity_valid,
                                                 terrain_distance=old.terrain_distance)
    return sense


def fly_gnss_fault(seed: int, fault: str, drag: bool = True, altitude: float = 5.0) -> FaultFlight:
    """Take off, hover, then `fault` = "spoof" (a 1 m/s eastward drift of the fixes) or "jam" (no fix
    any more); hold then land as the health policy does; the flight ends at disarm (at most 30 s)."""
    if fault not in ("spoof", "jam"):
        raise ValueError(f"unknown fault {fault!r}: spoof or jam")
    rig = airborne_rig(seed, drag, altitude)
    loop, nav, ekf = rig.loop, rig.nav, rig.ekf
    start, t0, result = loop.plant.state.position, loop.t, FaultFlight()
    if fault == "spoof":
        rig.sensors.faults.gps_drift = (1.0, 0.0, 0.0)
    else:
        rig.jammed = True
        result.flagged_s = JAM_DETECTED_AFTER_S
    while loop.t - t0 < 30.0:
        loop.run(0.1)
        elapsed = loop.t - t0
        distance = math.dist(loop.plant.state.position[:2], start[:2])
        result.farthest_m = max(result.farthest_m, distance)
        if math.isnan(result.flagged_s) and nav.verdict.state == IntegrityState.SPOOFED:
            result.flagged_s = elapsed
        if math.isnan(result.flagged_s):
            continue
        if "HOLD" not in result.at_phase_m and elapsed >= result.flagged_s + POLICY_DELAY_S:
            nav.station_keeping = True
            loop.command(Request(Command.HOLD))
            result.at_phase_m["HOLD"] = distance
        if "HOLD" in result.at_phase_m and "LAND" not in result.at_phase_m \
                and elapsed >= result.flagged_s + POLICY_DELAY_S + THEN_LAND_AFTER_S:
            loop.command(Request(Command.LAND))
            result.at_phase_m["LAND"] = distance
        if "LAND" in result.at_phase_m:
            if not ekf.position_valid and not ekf.velocity_valid:
                result.velocity_valid_in_descent = False
            if not loop.core.out.armed:
                break
    result.touchdown_m = math.dist(loop.plant.state.position[:2], start[:2])
    return result


@dataclass
class HoverInWind:
    """A hover on GNSS in wind: the estimate's horizontal velocity error against the plant's."""

    velocity_rms: float  # [m/s]
    velocity_max: float  # [m/s]
    drag_rejected: int  # drag samples the gate refused
    wind_error: float  # [m/s] |estimated − true| horizontal wind at the end (nan without drag fusion)


def hover_in_wind(seed: int, drag: bool, wind: WindField, seconds: float = 30.0) -> HoverInWind:
    """Hover at 5 m with GNSS in `wind` (from the take-off on); sample the estimate every 0.1 s."""
    rig = airborne_rig(seed, drag, wind=wind)
    errors = []
    for _ in range(round(seconds / 0.1)):
        rig.loop.run(0.1)
        true_v = rig.loop.plant.state.velocity
        errors.append(math.hypot(rig.ekf.v[0] - true_v[0], rig.ekf.v[1] - true_v[1]))
    true_w = rig.wind.at(rig.loop.plant.state.t) if rig.wind is not None else (0.0, 0.0, 0.0)
    wind_error = math.hypot(rig.ekf.wind[0] - true_w[0], rig.ekf.wind[1] - true_w[1]) if drag else math.nan
    return HoverInWind(math.sqrt(sum(e * e for e in errors) / len(errors)), max(errors),
                       rig.ekf.rejected["drag"], wind_error)
