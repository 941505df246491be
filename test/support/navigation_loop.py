"""Closed loop with the navigation filter in it: plant → c4d_sim sensor models → the real
NavigationFilter (EKF, GNSS integrity monitor, source selection) → the GNC core → plant.

Why: the GNSS fault scenarios of issue 19 (spoofed or lost GNSS with no other horizontal source,
then hold and land) are decided by what the estimate does in dead reckoning and by how the core
flies on it. The whole graph flies them once per CI run; this loop flies them deterministically
(seeded), in ~2 s of wall time each, so that several seeds can be asserted on. The health node's
policy is modelled by its timing (c4d_health/config/failsafe.yaml, gnss_spoofed: HOLD 1 s after
the verdict, LAND 1 s later); the navigation node's rule "station keeping during a HOLD or LAND
failsafe" (unaided-velocity pseudo-measurement) is applied as the node does.
"""

from __future__ import annotations

import math
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


def fly_gnss_fault(seed: int, fault: str, drag: bool = True, altitude: float = 5.0) -> FaultFlight:
    """Take off, hover, then `fault` = "spoof" (a 1 m/s eastward drift of the fixes) or "jam" (no fix
    any more); hold then land as the health policy does; the flight ends at disarm (at most 30 s)."""
    airframe = load_airframe(default_airframe_path("quad_x"))
    with open(default_config_path()) as f:
        loop = ClosedLoop(airframe, yaml.safe_load(f)["executive"], NO_NOISE, seed=seed)
    sensors = SensorSuite(SensorConfig(), HOME, seed=seed)
    ekf = NavigationEkf(drag_config(airframe) if drag else EkfConfig())
    nav = NavigationFilter(ekf, NavigationConfig(horizontal_primary=GNSS, horizontal_secondary=NONE))
    nav.on_ground = True
    dt, tick, jammed = loop.tick_s, [0], [False]

    def sense(now: float) -> None:  # each core input phase: sensors at their rates into the filter
        k, s = tick[0], loop.plant.state
        tick[0] += 1
        imu = sensors.imu(s, dt)
        if imu is not None:
            nav.imu(s.t, imu.gyro, imu.accel)
        if k % 10 == 0:
            mag, baro = sensors.mag(s), sensors.baro(s)
            if mag is not None:
                nav.magnetometer(mag)
            if baro is not None:
                nav.baro(baro[1], s.t)
        if k % 50 == 25 and not jammed[0]:
            fix = sensors.gps(s, 0.1)
            if fix is not None:
                nav.gnss(fix.latitude, fix.longitude, fix.altitude, fix.sigma_h**2, fix.sigma_v**2, s.t)
        if ekf.origin is not None and ekf.aligned:
            old = loop.core.inputs.state
            loop.core.inputs.state = StateSample(now, tuple(ekf.p), tuple(ekf.v), ekf.q, old.angular_velocity,
                                                 valid_position=ekf.position_valid,
                                                 valid_velocity=ekf.velocity_valid,
                                                 terrain_distance=old.terrain_distance)

    loop.input_hook = sense
    loop.run(8.0)
    if ekf.origin is None:
        raise RuntimeError("home was not set in 8 s")
    nav.on_ground = False
    loop.command(Request(Command.TAKEOFF, altitude=altitude))
    loop.run(12.0)
    start, t0, result = loop.plant.state.position, loop.t, FaultFlight()
    if fault == "spoof":
        sensors.faults.gps_drift = (1.0, 0.0, 0.0)
    elif fault == "jam":
        jammed[0] = True
        result.flagged_s = JAM_DETECTED_AFTER_S
    else:
        raise ValueError(f"unknown fault {fault!r}: spoof or jam")
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
