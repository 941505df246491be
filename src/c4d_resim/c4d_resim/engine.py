"""Re-simulation engine: navigation (NavigationFilter) and the GNC core (GncCore + its static schedule)
re-run from their arm snapshots over the journalled inputs — no DDS, no clock, as fast as the CPU goes.

Navigation: each journal record is the callback the node ran (IMU, GNSS, baro, mag, range, vehicle
status), fed with the recorded sample of that stamp; an accepted IMU sample yields navigation/state
written by the node's own function (c4d_gnc.state_wire). Core: records between two ticks are the
drained inputs and served commands, each at its recorded clock; a TICK record runs latch, the tasks due
at that tick index (TickSchedule.due) and the output (c4d_gnc.wire.actuator_cdr). The core reads the
re-simulated navigation/state of the journalled stamp; states from before navigation's snapshot
(navigation arms a few ms after the core) are the recorded ones.
Perception is not re-run: it forwards accepted samples unchanged, so its recorded outputs are the inputs.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

from rclpy.serialization import deserialize_message

from c4d_common.plan import PlanError
from c4d_common.vehicle import SetpointSource
from c4d_gnc import journal as jr
from c4d_gnc import ros_conversions as conv
from c4d_gnc import wire
from c4d_gnc.core_commands import answer_command
from c4d_gnc.core_inputs import fence_local, obstacles_from_msg
from c4d_gnc.gnc import GncCore
from c4d_gnc.navigation_filter import NavigationFilter
from c4d_gnc.state_wire import state_cdr
from c4d_interfaces.msg import Geofence, GuidanceSetpoint, Surroundings
from c4d_ros import cdr
from c4d_ros.plan_msgs import geofence_from_msg

from . import decode
from .flight import IMU, SENSORS, SETPOINTS, Flight


class JournalEnd(Exception):
    """Navigation's journal ended (the file's end cuts the two journals at different batches): the core stops."""


@dataclass
class Counts:
    """What the re-simulation could not feed as recorded (each makes exactness impossible from there)."""

    missing: dict[str, int] = field(default_factory=dict)  # input samples the journal names but the file lacks
    unsupported: dict[str, int] = field(default_factory=dict)  # journalled inputs resim does not re-run

    def miss(self, what: str) -> None:
        self.missing[what] = self.missing.get(what, 0) + 1

    def skip(self, what: str) -> None:
        self.unsupported[what] = self.unsupported.get(what, 0) + 1


def _records(batches: list[tuple[int, bytes]]) -> Iterator[tuple]:
    for _, payload in batches:
        yield from jr.records(payload)


def navigation(flight: Flight, filt: NavigationFilter, counts: Counts) -> Iterator[tuple[int, bytes]]:
    """(stamp ns, navigation/state CDR) for every IMU sample the filter accepts, in the node's order."""
    imu, sensors = flight.by_stamp[IMU], {k: flight.by_stamp[t] for k, t in SENSORS.items()}
    gps, external_gnss, baro, mag, range_down = (sensors[k] for k in ("gps", "external_gnss", "baro", "mag", "range"))
    gyro, accel = cdr.IMU_GYRO, cdr.IMU_ACCEL
    stamp_s = jr.stamp_s

    for rec in _records(flight.nav.batches):
        kind = rec[0]
        if kind == jr.N_IMU:
            raw = imu.get(rec[1])
            if raw is None:
                counts.miss(IMU)
                continue
            v = decode.IMU(raw)
            t = v[1] + v[2] * 1e-9
            if filt.imu(t, v[gyro], v[accel]):
                yield rec[1], state_cdr(filt, v[1], v[2], t)
        elif kind == jr.N_GNSS:
            raw = (external_gnss if rec[1] else gps).get(rec[2])
            if raw is None:
                counts.miss(SENSORS["external_gnss" if rec[1] else "gps"])
                continue
            v = decode.GNSS(raw)
            lat = decode.GNSS_LAT
            filt.gnss(v[lat], v[lat + 1], v[lat + 2], v[decode.GNSS_COV0], v[decode.GNSS_COV8], stamp_s(rec[2]))
        elif kind == jr.N_BARO:
            raw = baro.get(rec[1])
            if raw is None:
                counts.miss(SENSORS["baro"])
                continue
            filt.baro(decode.BARO(raw)[5], stamp_s(rec[1]))
        elif kind == jr.N_RANGE:
            raw = range_down.get(rec[1])
            if raw is None:
                counts.miss(SENSORS["range"])
                continue
            filt.range_down(decode.RANGE(raw)[decode.RANGE_VALUE], stamp_s(rec[1]))
        elif kind == jr.N_MAG:
            raw = mag.get(rec[1])
            if raw is None:
                counts.miss(SENSORS["mag"])
                continue
            filt.magnetometer(decode.MAG(raw)[5:8])
        elif kind == jr.N_STATUS:
            filt.on_ground = not rec[1] & jr.STATUS_ARMED
            filt.station_keeping = bool(rec[1] & jr.STATUS_STATION_KEEPING)
        elif kind == jr.N_EXTERNAL:
            counts.skip("navigation/external")
        elif kind == jr.N_RETUNE:  # a live ekf.* change, in force from the next IMU sample (navigation_node.retune)
            from c4d_gnc.live_navigation import ekf_with, navigation_table

            changes = jr.safe_loads(rec[1])
            reason = navigation_table().check(changes, {}) if isinstance(changes, dict) else "not a mapping"
            if reason:
                raise jr.JournalError(f"navigation retune record: {reason}")
            filt.ekf.cfg = ekf_with(filt.ekf.cfg, changes)


@dataclass
class CoreRun:
    """The core's snapshot and what its node kept beside GncCore (the fence as received, home)."""

    core: GncCore
    cfg: object
    geofence: object
    origin: tuple[float, float, float] | None

    @classmethod
    def from_snapshot(cls, snap: dict) -> CoreRun:
        return cls(snap["core"], snap["cfg"], snap["geofence"], snap["origin"])

    def convert_fence(self) -> None:
        if self.geofence is not None and self.origin is not None:
            self.core.inputs.fence = fence_local(self.geofence, self.origin)  # type: ignore[arg-type]


def core_ticks(flight: Flight, run: CoreRun, state_of: Callable[[int], bytes | None], counts: Counts,
               ) -> Iterator[tuple[int, int, bytes]]:
    """(tick, now ns, control/actuators CDR) per journalled tick, from the core's snapshot on."""
    core, schedule = run.core, run.cfg.schedule  # type: ignore[attr-defined]
    tick_s = schedule.tick_us / 1e6
    functions = core.task_functions()
    tasks = {t.name: (functions.get(t.name), t.divider * tick_s) for t in schedule.tasks}
    period = math.lcm(*(t.divider for t in schedule.tasks)) if schedule.tasks else 1
    due = [[tasks[t.name] for t in schedule.due(k)] for k in range(period)]  # TickSchedule.due(k) == due[k % period]
    imu, inputs, gyro = flight.by_stamp[IMU], core.inputs, cdr.IMU_GYRO
    setpoints = {s: flight.by_stamp[t] for s, t in SETPOINTS.items()}
    surroundings = flight.by_stamp[SENSORS["surroundings"]]
    for rec in _records(flight.core.batches):
        kind = rec[0]
        if kind == jr.C_TICK:
            k, now_ns = rec[1], rec[2]
            inputs.now = now = now_ns * 1e-9
            core.latch()
            for fn, dt in due[k % period]:
                if fn is None:  # the status task: publishes vehicle/status, then forgets the tick's events
                    core.out.events.clear()
                else:
                    fn(dt)  # type: ignore[operator]
            yield k, now_ns, wire.actuator_cdr(core.out, now, k)
        elif kind == jr.C_GYRO:
            raw = imu.get(rec[1])
            if raw is None:
                counts.miss(IMU)
            else:
                v = decode.IMU(raw)  # as wire.gyro_from_cdr
                inputs.gyro, inputs.gyro_stamp = v[gyro], v[1] + v[2] * 1e-9
        elif kind == jr.C_STATE:
            raw = state_of(rec[1])
            if raw is None:
                counts.miss("/navigation/state")
                continue
            state = inputs.state = wire.state_from_cdr(raw)
            if state.origin != run.origin and state.origin is not None:
                run.origin = state.origin
                run.convert_fence()
        elif kind == jr.C_SETPOINT:
            inputs.now = rec[2] * 1e-9
            raw = setpoints.get(rec[1], {}).get(rec[3])
            if raw is None:
                counts.miss(SETPOINTS.get(rec[1], f"setpoint source {rec[1]}"))
                continue
            try:
                core.receive_setpoint(SetpointSource(rec[1]), conv.setpoint_from_msg(
                    deserialize_message(raw, GuidanceSetpoint)))
            except ValueError:
                pass  # the node logged it and ignored the setpoint
        elif kind == jr.C_COMMAND:
            inputs.now = rec[1] * 1e-9
            answer_command(core, rec[2], rec[3], rec[5], rec[4])
        elif kind == jr.C_SURROUNDINGS:
            raw = surroundings.get(rec[2])
            if raw is None:
                counts.miss(SENSORS["surroundings"])
                continue
            now = rec[1] * 1e-9
            inputs.obstacles, inputs.obstacles_stamp = obstacles_from_msg(deserialize_message(raw, Surroundings), now), now
        elif kind == jr.C_FENCE:
            try:
                run.geofence = geofence_from_msg(deserialize_message(rec[1], Geofence))
            except PlanError:
                continue
            run.convert_fence()
        elif kind == jr.C_RETUNE:
            from c4d_gnc.live_gains import airframe_with

            changes = jr.safe_loads(rec[1])
            if not isinstance(changes, dict) or not all(isinstance(v, int | float) for v in changes.values()):
                raise jr.JournalError("retune record is not a {name: number} mapping")
            core.retune(airframe_with(core.af, changes))
