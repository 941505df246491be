"""resim's engine on a small synthetic flight, without DDS: a standing-then-hovering vehicle's sensor
stream is fed to the real NavigationFilter and GncCore the way their nodes do (journal records written
by the same JournalWriter, navigation/state by state_wire, control/actuators by wire), recorded with
the project's BagWriter; resim must re-create both streams byte for byte, and a tighter GNSS gate must
part the streams at the IMU sample right after a GNSS fix."""

from __future__ import annotations

import array
import math
import pickle
from collections.abc import Callable

import numpy as np
from rclpy.serialization import serialize_message
from sensor_msgs.msg import FluidPressure, Imu, MagneticField, NavSatFix
from std_msgs.msg import UInt8MultiArray

from c4d_common.geodesy import GeoOrigin, pressure_at_altitude
from c4d_common.vehicle import Command, Nav
from c4d_data.bag_writer import BagWriter
from c4d_gnc import journal as jr
from c4d_gnc import wire
from c4d_gnc.core_commands import answer_command
from c4d_gnc.core_config import load_core_config
from c4d_gnc.ekf import EkfConfig, NavigationEkf
from c4d_gnc.gnc import GncCore
from c4d_gnc.gnss_integrity import IntegrityState
from c4d_gnc.live_navigation import ekf_with
from c4d_gnc.navigation_filter import NavigationFilter
from c4d_gnc.state_wire import state_cdr
from c4d_resim.run import resimulate

T0 = 1_795_000_000_000_000_000
HOME = GeoOrigin(43.5629, 1.4815, 150.0)
TOPICS = {"/perception/imu": "sensor_msgs/msg/Imu", "/perception/gps": "sensor_msgs/msg/NavSatFix",
          "/perception/baro": "sensor_msgs/msg/FluidPressure", "/perception/mag": "sensor_msgs/msg/MagneticField",
          "/navigation/state": "c4d_interfaces/msg/VehicleState", "/control/actuators": "c4d_interfaces/msg/ActuatorCommand",
          "/navigation/journal": "std_msgs/msg/UInt8MultiArray", "/gnc/journal": "std_msgs/msg/UInt8MultiArray"}


def _stamp(msg, ns: int):
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 1_000_000_000)
    return msg


def _journal(writer: BagWriter, topic: str, payload: bytes | None, ns: int) -> None:
    if payload is not None:
        writer.write(topic, serialize_message(UInt8MultiArray(data=array.array("B", payload))), ns, ns)


Request = tuple[int, int, float, bool]  # (command, mode, altitude, force) as the core's service serves it


def record(path, seconds: float = 10.0, arm_at: float = 3.0, gnss_noise_m: float = 1.5, drift_from: float | None = None,
           drift_m_s: float = 0.0, health: Callable[[NavigationFilter, float], Request | None] | None = None,
           retune: tuple[float, dict[str, float]] | None = None) -> list[tuple[bool, int, int]]:
    """Fly the synthetic flight through the real filter and core, journalled as the nodes do; the core's
    (armed, mode, nav) changes. `gnss_noise_m`: the fixes' white noise (1σ; their reported σ stays 1.5 m).
    `drift_from` [s]: the GNSS fixes walk east at `drift_m_s` from then on (a spoofer).
    `health(filter, t)`, asked before each armed tick's latch: a command to serve (journalled like the health
    node's service call) or None. `retune` (t [s], {ekf.<field>: value}): a live navigation parameter change
    applied before the first IMU sample at or after t, journalled as navigation_node.retune does."""
    rng = np.random.default_rng(7)
    w = BagWriter(path)
    for name, type_name in TOPICS.items():
        w.add_topic(name, type_name, "", "")
    filt = NavigationFilter(NavigationEkf(EkfConfig()))
    filt.on_ground = True
    cfg = load_core_config()
    core = GncCore(cfg.airframe, cfg.schedule.tick_us / 1e6)
    nav_j, core_j = jr.JournalWriter(), jr.JournalWriter()
    tasks = core.task_functions()
    armed = False
    modes: list[tuple[bool, int, int]] = []
    for i in range(int(seconds * 500)):
        ns = T0 + i * 2_000_000
        t = jr.stamp_s(ns)
        imu = _stamp(Imu(), ns)
        gyro = rng.normal(0.0, 0.003, 3)
        accel = np.array([0.0, 0.0, 9.80665]) + rng.normal(0.0, 0.05, 3)
        imu.angular_velocity.x, imu.angular_velocity.y, imu.angular_velocity.z = gyro.tolist()
        imu.linear_acceleration.x, imu.linear_acceleration.y, imu.linear_acceleration.z = accel.tolist()
        raw = serialize_message(imu)
        w.write("/perception/imu", raw, ns, ns)
        if retune is not None and t >= jr.stamp_s(T0) + retune[0]:  # navigation: on_imu, a change queued
            nav_j.blob(jr.N_RETUNE, pickle.dumps(retune[1]))
            filt.ekf.cfg = ekf_with(filt.ekf.cfg, retune[1])
            retune = None
        nav_j.stamp(jr.N_IMU, ns)  # navigation: on_imu
        if filt.imu(t, tuple(gyro), tuple(accel)):
            sec, nanosec = divmod(ns, 1_000_000_000)
            state = state_cdr(filt, sec, nanosec, t)
            w.write("/navigation/state", state, ns, ns)
        else:
            state = None
        if i % 10 == 5:  # baro, mag at 50 Hz
            baro = _stamp(FluidPressure(), ns)
            baro.fluid_pressure = pressure_at_altitude(HOME.altitude + rng.normal(0.0, 0.1))
            w.write("/perception/baro", serialize_message(baro), ns, ns)
            nav_j.stamp(jr.N_BARO, ns)
            filt.baro(baro.fluid_pressure, t)
            mag = _stamp(MagneticField(), ns)
            mag.magnetic_field.x, mag.magnetic_field.y, mag.magnetic_field.z = 2e-5, 0.0, -4e-5
            w.write("/perception/mag", serialize_message(mag), ns, ns)
            nav_j.stamp(jr.N_MAG, ns)
            filt.magnetometer((2e-5, 0.0, -4e-5))
        if i % 50 == 25:  # GNSS at 10 Hz, 1.5 m noise, fixes 50 ms old
            fix_ns = ns - 50_000_000
            east = drift_m_s * (t - jr.stamp_s(T0) - drift_from) if drift_from is not None and \
                t - jr.stamp_s(T0) > drift_from else 0.0
            noise = rng.normal(0.0, gnss_noise_m, 3).tolist()
            lat, lon, alt = HOME.to_geodetic(noise[0] + east, noise[1], noise[2])
            fix = _stamp(NavSatFix(latitude=lat, longitude=lon, altitude=alt), fix_ns)
            fix.position_covariance[0] = fix.position_covariance[4] = 1.5 ** 2
            fix.position_covariance[8] = 3.0 ** 2
            w.write("/perception/gps", serialize_message(fix), ns, ns)
            nav_j.gnss(False, fix_ns)
            filt.gnss(lat, lon, alt, 1.5 ** 2, 3.0 ** 2, jr.stamp_s(fix_ns))
        # core tick i, half a period after the IMU sample
        now_ns = ns + 1_000_000
        inputs = core.inputs
        inputs.gyro, inputs.gyro_stamp = wire.gyro_from_cdr(raw)
        core_j.stamp(jr.C_GYRO, ns)
        if state is not None:
            inputs.state = wire.state_from_cdr(state)
            core_j.stamp(jr.C_STATE, ns)
        inputs.now = now_ns * 1e-9
        if not armed and t >= jr.stamp_s(T0) + arm_at and inputs.state is not None and inputs.state.valid_position:
            core_j.command(now_ns, 3, 0, False, 3.0)  # TAKEOFF to 3 m, served in this tick's input phase
            result = answer_command(core, 3, 0, 3.0, False)
            assert result[0] == 0, result
            for payload in core_j.snapshot({"core": core, "geofence": None, "origin": None, "cfg": cfg,
                                            "params": None}):
                _journal(w, "/gnc/journal", payload, now_ns)
            for payload in nav_j.snapshot({"filter": filt, "params": {}}):  # the status edge, in the same tick here
                _journal(w, "/navigation/journal", payload, now_ns)
            nav_j.status(jr.STATUS_ARMED)
            filt.on_ground = False
            armed = True
        elif armed and health is not None:
            request = health(filt, t)
            if request is not None:
                core_j.command(now_ns, request[0], request[1], request[3], request[2])
                answer_command(core, request[0], request[1], request[2], request[3])
        core.latch()
        for task in cfg.schedule.due(i):
            fn = tasks.get(task.name)
            if fn is None:
                core.out.events.clear()
            else:
                fn(task.divider * cfg.schedule.tick_us / 1e6)
        w.write("/control/actuators", wire.actuator_cdr(core.out, inputs.now, i), now_ns, now_ns)
        key = (bool(core.out.armed), int(core.out.mode), int(core.out.nav))
        if armed and (not modes or modes[-1] != key):
            modes.append(key)
        core_j.tick(i, now_ns)
        if i % 50 == 49:
            _journal(w, "/gnc/journal", core_j.take(), now_ns)
            _journal(w, "/navigation/journal", nav_j.take(), now_ns)
    _journal(w, "/gnc/journal", core_j.take(), T0 + int(seconds * 1e9))
    _journal(w, "/navigation/journal", nav_j.take(), T0 + int(seconds * 1e9))
    w.close()
    return modes


def test_synthetic_flight_is_re_created_bit_for_bit_and_a_gate_change_parts_at_a_fix(tmp_path):
    path = tmp_path / "synthetic.mcap"
    record(path)
    same = resimulate(path, output=tmp_path / "out.mcap")
    assert same.counts.missing == {} and same.state.compared > 2000 and same.actuators.compared > 2000
    assert same.exact, (same.state.first_divergence, same.actuators.first_divergence)
    assert any(m[0] for m in same.modes_resim)  # the take-off armed the re-simulated core
    gated = resimulate(path, ["navigation.gps_gate:=0.05"])
    key = gated.state.first_key
    assert key is not None and not gated.exact
    # the first differing state is the IMU sample right after a GNSS fix; all before it are identical
    before = None
    for _, payload in gated.flight.nav.batches:
        for rec in jr.records(payload):
            if rec[0] == jr.N_IMU and rec[1] == key:
                assert before == jr.N_GNSS
                break
            before = rec[0]
        else:
            continue
        break
    assert gated.state.identical == sum(1 for t in gated.state.t if t < gated.state.first_divergence)
    assert math.isfinite(gated.state.max_diff) and gated.state.max_diff > 0


def test_a_live_navigation_retune_is_replayed_at_its_sample(tmp_path):
    """A live ekf.* change in flight (navigation_node.retune: N_RETUNE before the IMU sample it applies to)
    is re-applied by resim at the same sample: the re-created stream stays bit for bit, though the change
    (baro and accelerometer noises raised) moves the estimate."""
    path, plain = tmp_path / "retuned.mcap", tmp_path / "plain.mcap"
    record(path, seconds=6.0, retune=(4.0, {"ekf.baro_noise": 5.0, "ekf.accel_noise": 0.5}))
    record(plain, seconds=6.0)
    same = resimulate(path)
    assert same.counts.missing == {} and same.exact, (same.state.first_divergence, same.actuators.first_divergence)
    assert any(rec[0] == jr.N_RETUNE for _, payload in same.flight.nav.batches for rec in jr.records(payload))
    other = resimulate(plain)
    states, plain_states = (dict(r.flight.logged["/navigation/state"]) for r in (same, other))
    changed = sorted(ns for ns, raw in states.items() if plain_states.get(ns) != raw)
    assert changed and jr.stamp_s(changed[0]) >= jr.stamp_s(T0) + 4.0  # the change moved the estimate, from t on


class SpoofedHealth:
    """The health node's GNSS-spoofing failsafe as the core receives it: HOLD when navigation reports SPOOFED,
    LAND `land_after_s` later (health's policy: hold, then land). Its decision is journalled as the service
    call the core served, so re-simulation replays it — it is not re-decided."""

    def __init__(self, land_after_s: float = 2.0) -> None:
        self.land_after_s = land_after_s
        self.spoofed_at: float | None = None
        self.undone_m = 0.0
        self.landing = False

    def __call__(self, filt: NavigationFilter, t: float) -> Request | None:
        if self.spoofed_at is None and filt.verdict.state == IntegrityState.SPOOFED:
            self.spoofed_at, self.undone_m = t, filt.gnss_undone_m
            return (Command.HOLD, 0, 0.0, False)
        if self.spoofed_at is not None and not self.landing and t - self.spoofed_at >= self.land_after_s:
            self.landing = True
            return (Command.LAND, 0, 0.0, False)
        return None


def test_gnss_spoofing_failsafe_is_re_created(tmp_path):
    """A spoofer walks the fixes away after take-off: the recorded navigation goes SPOOFED, cuts GNSS off and
    undoes what it fused since the onset; 'health' commands HOLD then LAND. Re-simulated: navigation re-decides
    the verdict, the cut-off and the undo itself (its states are bit-identical, its filter ends SPOOFED with the
    same undo); the core gets the journalled HOLD / LAND and flies the same mode sequence, byte for byte."""
    path = tmp_path / "spoofed.mcap"
    health = SpoofedHealth()
    modes = record(path, seconds=14.0, gnss_noise_m=0.3, drift_from=7.0, drift_m_s=2.0, health=health)
    assert health.spoofed_at is not None and health.landing and health.undone_m > 0.5  # the fault did happen
    navs = [m[2] for m in modes]
    assert navs.index(Nav.TAKEOFF) < navs.index(Nav.HOLD) < navs.index(Nav.LAND), modes
    r = resimulate(path, processes=1)  # in this process: the re-simulated filter is inspected below
    assert r.counts.missing == {} and r.state.compared > 5000 and r.actuators.compared > 5000
    assert r.exact, (r.state.first_divergence, r.actuators.first_divergence)
    assert r.modes_resim == modes
    filt = r.flight.nav.snapshot["filter"]  # the snapshot's filter, run to the end of the flight
    assert filt.verdict.state == IntegrityState.SPOOFED and filt.gnss_undone_m == health.undone_m
