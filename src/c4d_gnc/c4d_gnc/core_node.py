"""`ros2 run c4d_gnc core` — the GNC core node: a thin rclpy edge around GncCore.

The node never uses rclpy timers and no executor spins it: it runs the CyclicExecutive
(absolute deadlines) in the main thread, and each tick's input phase drains the
subscriptions, the command service and the parameter services without blocking (Drainer)
into the GncCore blackboard.

Interfaces (c4d_ros.manifest, docs/ARCHITECTURE.md):
  subscribes  <imu_topic> (perception/imu: the gyro for the rate loop), navigation/state, and the setpoints of
              guidance/setpoint (mission), guidance/pilot (bridge), guidance/offboard (offboard gateway): the mode
              picks the one that steers (setpoint_sources); the others are ignored and counted in vehicle/status;
              perception/surroundings and geofence/active (latched) for the avoidance barrier (docs/daa.md),
              converted to local ENU once when they (or home) arrive, never per tick
  serves      gnc/command (arm, disarm, take-off, land, hold, set mode, go-to; applied at the next tick)
  publishes   control/actuators (every tick; the only publisher), vehicle/status (latched, on change
              and at 5 Hz), gnc/executor_stats (every report_period_s), gnc/schedule (latched, once)
Parameters: PARAMS below (`ros2 param describe core <name>`), read-only (a change needs a restart);
config, airframe and phase_method report the values in force (the file's, unless overridden). Every gain
and limit of the airframe is a live parameter (c4d_gnc.live_gains, docs/parameters.md): a change is checked
when set (refused with the reason) and applied at the next tick's latch (logged with the tick index);
with `vehicle` set, changes persist in that vehicle's store and are restored at start.
SIGINT/SIGTERM: the loop stops, zero motor commands (armed = false) are published, exit 0.
Bad configuration or parameter: one line on stderr, exit 2, nothing armed.
"""

from __future__ import annotations

import array
import pickle
import signal
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import partial

from rclpy.serialization import serialize_message
from sensor_msgs.msg import Imu
from std_msgs.msg import UInt8MultiArray

from c4d_common.barrier import BarrierError, BarrierParams
from c4d_common.plan import Geofence, PlanError
from c4d_common.tunable import TunableError, VehicleStore
from c4d_common.vehicle import Command, SetpointSource
from c4d_interfaces.msg import (
    ActuatorCommand,
    ExecutorStats,
    GuidanceSetpoint,
    ScheduleTable,
    Surroundings,
    VehicleState,
    VehicleStatus,
)
from c4d_interfaces.msg import Geofence as GeofenceMsg
from c4d_interfaces.srv import VehicleCommand
from c4d_ros import lifecycle, node_runtime
from c4d_ros.component import ComponentError
from c4d_ros.drain import Drainer
from c4d_ros.live_params import LiveParameters, describe
from c4d_ros.manifest import (
    ACTUATORS,
    CLOCK,
    CORE_COMMAND,
    CORE_JOURNAL,
    EXECUTOR_STATS,
    GEOFENCE,
    NAV_STATE,
    OFFBOARD_SETPOINT,
    P_IMU,
    PILOT_SETPOINT,
    SCHEDULE,
    SETPOINT,
    STATUS,
    SURROUNDINGS,
)
from c4d_ros.params import Declaration, ParameterError, Spec
from c4d_ros.plan_msgs import geofence_from_msg
from c4d_ros.qos import newest_only
from c4d_sched.executive import Clock, CyclicExecutive, MonotonicClock, grid_start_ns
from c4d_sched.lockstep import CLOCK as SIM_CLOCK
from c4d_sched.lockstep import InputGate, LockstepClock
from c4d_sched.profiler import ExecutorReport, format_table

from . import journal as jr
from . import ros_conversions as conv
from . import wire
from .core_commands import answer_command
from .core_config import CoreConfig, CoreConfigError, load_core_config
from .core_inputs import fence_local, obstacles_from_msg
from .gnc import GncCore
from .live_gains import airframe_with, core_table
from .status_cadence import StatusCadence

NAME = "core"
PARAMS = {
    "config": Spec("", "core YAML: airframe + executive schedule [file path]; empty: the package's config/core.yaml",
                   read_only=True),
    "airframe": Spec("", "airframe, overrides the config's [name in config/airframes or YAML file path]; empty: the config's",
                     read_only=True),
    "phase_method": Spec("", "task phase assignment, overrides the config's [gcdplus | optimal | paparazzi | zero]; "
                             "empty: the config's", read_only=True),
    "imu_topic": Spec(P_IMU.name, "gyro source of the rate loop [topic name]", read_only=True),
    "log_table": Spec(False, "print the profiler table with each report [bool]", read_only=True),
    "rt_priority": node_runtime.RT_PRIORITY,
    "tick_phase": Spec(0.5, "where the ticks fall on CLOCK_MONOTONIC: tick k at (n + k + tick_phase) periods, n whole; the "
                            "sim samples the IMU at whole IMU periods, so the gyro a tick reads is tick_phase periods old "
                            "plus nothing random [fraction of a tick, 0..0.95]", 0.0, 0.95, read_only=True),
    "lockstep": Spec(False, "lockstep mode: tick on the sim's /clock, each tick waiting for the gyro and navigation "
                            "state of its step (deterministic); false = real time on the monotonic clock [bool]",
                     read_only=True),
    "lockstep_input_timeout_s": Spec(1.0, "lockstep: wall time a tick waits for a running input (gyro, state) that "
                                          "missed its step before it runs without it (logged) [s]", 0.01, 3600.0,
                                     read_only=True),
    "vehicle": Spec("", "vehicle whose changed gains persist in $XDG_DATA_HOME/c4d/vehicles/<vehicle>/core.yaml and are "
                        "restored at start; empty: changes are not persisted [name]", read_only=True),
    "avoidance": Spec(True, "obstacle and geofence barrier on the velocity setpoint in guided modes (docs/daa.md) [bool]",
                      read_only=True),
    "avoid_detection_range": Spec(2.0, "barrier detection range D: the potential is zero beyond this distance to an "
                                       "obstacle's surface or the fence [m]", 0.2, 50.0, read_only=True),
    "avoid_protection_radius": Spec(0.5, "barrier protection radius r: the potential is infinite here; the vehicle "
                                         "stays outside it [m]", 0.05, 20.0, read_only=True),
    "avoid_brake_decel": Spec(4.0, "deceleration the barrier's braking cap plans with (braking margin v^2/2a) [m/s^2]",
                              0.5, 15.0, read_only=True),
    "avoid_detour_after_s": Spec(1.0, "blocked progress with an obstacle inside D for this long starts a tangential "
                                      "detour [s]", 0.1, 60.0, read_only=True),
}
LOCKSTEP_STREAMS = ("gyro", "state")
JOURNAL_TICKS = 50  # a journal batch every 50 ticks (10 Hz at 500 Hz)
ARMING = (Command.ARM, Command.TAKEOFF)


@dataclass(frozen=True)
class CoreParams:
    config: str
    airframe: str
    phase_method: str
    imu_topic: str
    log_table: bool
    rt_priority: int
    tick_phase: float = 0.5
    lockstep: bool = False
    lockstep_input_timeout_s: float = 1.0
    avoidance: bool = True
    avoid_detection_range: float = 2.0
    avoid_protection_radius: float = 0.5
    avoid_brake_decel: float = 4.0
    avoid_detour_after_s: float = 1.0
    vehicle: str = ""

    def barrier(self) -> BarrierParams:
        """The barrier's parameters; BarrierError (one line) when they contradict each other (D <= r)."""
        return BarrierParams(detection_range=self.avoid_detection_range, protection_radius=self.avoid_protection_radius,
                             brake_decel=self.avoid_brake_decel, detour_after=self.avoid_detour_after_s)

    def load_config(self) -> CoreConfig:
        return load_core_config(self.config or None, self.airframe or None, self.phase_method or None)


class CoreNode:
    """Maps the core's topics and service onto GncCore and drives it with the CyclicExecutive.

    Per tick: input phase (drain, stamp the blackboard), latch, the scheduled tasks, output
    phase (actuator command). Nothing here waits or allocates beyond the messages it sends.
    """

    def __init__(self, node, cfg: CoreConfig, params: CoreParams, live: LiveParameters | None = None) -> None:
        self.node, self.cfg, self.params, self.live = node, cfg, params, live
        self.log = node.get_logger()
        self.clock = node.get_clock()
        self.core = GncCore(cfg.airframe, cfg.schedule.tick_us / 1e6, barrier=params.barrier(), avoidance=params.avoidance)
        self.geofence: Geofence | None = None  # geofence/active as received (geodetic)
        self.origin: tuple[float, float, float] | None = None  # home the fence was converted with
        self.status = StatusCadence()
        # input consumption journal for `resim` (c4d_gnc.journal): every tick's clock and inputs, a snapshot at arm
        self.journal, self.now_ns, self.journal_k = jr.JournalWriter(), 0, 0
        self.pub_journal = node.create_publisher(UInt8MultiArray, CORE_JOURNAL.name, CORE_JOURNAL.qos)
        self.drainer = Drainer(node)
        # the 500 Hz inputs and output go serialized (c4d_gnc.wire: ~1 µs instead of ~40 µs per message)
        self.drainer.subscription(Imu, params.imu_topic, self.on_imu, newest_only(P_IMU.qos), raw=True)  # newest gyro
        self.drainer.subscription(VehicleState, NAV_STATE.name, self.on_state, NAV_STATE.qos, raw=True)
        for source, topic in ((SetpointSource.MISSION, SETPOINT), (SetpointSource.PILOT, PILOT_SETPOINT),
                              (SetpointSource.OFFBOARD, OFFBOARD_SETPOINT)):
            self.drainer.subscription(GuidanceSetpoint, topic.name, partial(self.on_setpoint, source, topic.name), topic.qos)
        if params.avoidance:
            self.drainer.subscription(Surroundings, SURROUNDINGS.name, self.on_surroundings, SURROUNDINGS.qos)
            self.drainer.subscription(GeofenceMsg, GEOFENCE.name, self.on_geofence, GEOFENCE.qos)
        self.drainer.service(VehicleCommand, CORE_COMMAND.name, self.on_command)
        self.pub_actuators = node.create_publisher(ActuatorCommand, ACTUATORS.name, ACTUATORS.qos)
        self.pub_status = node.create_publisher(VehicleStatus, STATUS.name, STATUS.qos)
        self.pub_stats = node.create_publisher(ExecutorStats, EXECUTOR_STATS.name, EXECUTOR_STATS.qos)
        self.pub_schedule = node.create_publisher(ScheduleTable, SCHEDULE.name, SCHEDULE.qos)
        self.drainer.adopt_node_services()  # parameter services too: no executor spins this node
        clock: Clock = MonotonicClock()
        self.lockstep: LockstepClock | None = None
        if params.lockstep:
            clock = self.lockstep = self._lockstep_clock(cfg.schedule.tick_us * 1000)
        self.executive = CyclicExecutive(
            cfg.schedule, self._task_functions(), clock, name=cfg.executive_name, input_phase=self.input_phase,
            latch=self.latch, output_phase=self.output_phase, report_period_s=cfg.report_period_s,
            on_report=self.on_report, manage_gc=True)

    def _task_functions(self) -> dict[str, Callable[[int], None]]:
        schedule, core_tasks = self.cfg.schedule, self.core.task_functions()
        functions: dict[str, Callable[[int], None]] = {}
        for task in schedule.tasks:
            if task.name == "status":
                functions[task.name] = self.status_task
            else:
                fn, dt = core_tasks[task.name], task.divider * schedule.tick_us / 1e6
                functions[task.name] = lambda k, fn=fn, dt=dt: fn(dt)
        return functions

    def clock_s(self) -> float:
        self.now_ns = self.lockstep.now_ns() if self.lockstep else self.clock.now().nanoseconds
        return self.now_ns * 1e-9

    # ----------------------------------------------------------------- lockstep (simulated time)
    def _lockstep_clock(self, tick_ns: int) -> LockstepClock:
        """The executive's clock in lockstep: tick d runs when the sim's /clock reached d and the running inputs
        (gyro, navigation state) delivered their samples stamped d (c4d_sched.lockstep.InputGate)."""
        from rosgraph_msgs.msg import Clock as ClockMsg

        self.gate = InputGate(tick_ns, LOCKSTEP_STREAMS)
        self.drainer.subscription(ClockMsg, CLOCK.name, self._on_clock, CLOCK.qos)
        return LockstepClock(self.gate, self._lockstep_poll, self._lockstep_stall,
                             report_s=self.params.lockstep_input_timeout_s)

    def _on_clock(self, msg) -> None:
        self.gate.on_clock(msg.clock.sec * 1_000_000_000 + msg.clock.nanosec)

    def _lockstep_poll(self) -> None:
        """While a tick waits: drain (inputs, commands, parameters) and tell the gate what arrived."""
        self.drainer.drain()
        inputs = self.core.inputs
        if inputs.gyro is not None:
            self.gate.on_sample("gyro", round(inputs.gyro_stamp * 1e9))
        if inputs.state is not None:
            self.gate.on_sample("state", round(inputs.state.stamp * 1e9))

    def _lockstep_stall(self, deadline_ns: int, missing: tuple[str, ...], waited_s: float) -> bool:
        """Simulated time holding (sim paused or stopped) is waited for silently; a running input that
        missed its step is given up after lockstep_input_timeout_s, with a warning."""
        if missing == (SIM_CLOCK,):
            return False
        self.log.warning(f"lockstep: tick t = {deadline_ns / 1e9:.3f} s runs without {', '.join(missing)} "
                         f"(not received after {waited_s:.1f} s)")
        return True

    def _wait_for_sim_time(self) -> int:
        """Lockstep start: the first simulated time seen (the step the sim waits on) is tick 0's deadline."""
        assert self.lockstep is not None
        next_note = time.monotonic() + 5.0
        while self.gate.clock_ns is None and not self.lockstep.interrupted:
            self._lockstep_poll()
            if time.monotonic() >= next_note:
                self.log.info(f"lockstep: waiting for the sim's {CLOCK.name} (sim running with lockstep: true?)")
                next_note += 30.0
            time.sleep(0.001)
        return self.gate.clock_ns or 0

    # ----------------------------------------------------------------- inputs (drained each tick)
    def on_imu(self, raw: bytes) -> None:
        inputs = self.core.inputs
        inputs.gyro, inputs.gyro_stamp = wire.gyro_from_cdr(raw)
        self.journal.stamp(jr.C_GYRO, jr.cdr_stamp_ns(raw))

    def on_state(self, raw: bytes) -> None:
        state = self.core.inputs.state = wire.state_from_cdr(raw)
        self.journal.stamp(jr.C_STATE, jr.cdr_stamp_ns(raw))
        if state.origin != self.origin and state.origin is not None:
            self.origin = state.origin
            self._convert_fence()

    def on_surroundings(self, msg: Surroundings) -> None:
        """Obstacles as the barrier's cylinders (local ENU), once per message; stamped with the scan's time when it
        is plausible (movers are extrapolated from it), else with the arrival time."""
        now = self.clock_s()
        self.journal.surroundings(self.now_ns, jr.stamp_ns(msg.header.stamp.sec, msg.header.stamp.nanosec))
        inputs = self.core.inputs
        inputs.obstacles = obstacles_from_msg(msg, now)
        inputs.obstacles_stamp = now

    def on_geofence(self, msg: GeofenceMsg) -> None:
        self.journal.blob(jr.C_FENCE, serialize_message(msg))
        try:
            self.geofence = geofence_from_msg(msg)
        except PlanError as exc:
            self.log.error(f"{GEOFENCE.name}: fence ignored, the previous one stays in force: {exc}")
            return
        self._convert_fence()

    def _convert_fence(self) -> None:
        """The fence in local ENU for the barrier: when a fence or a new home arrives (never per tick)."""
        if self.geofence is None or self.origin is None:
            return
        fence = fence_local(self.geofence, self.origin)
        self.core.inputs.fence = fence
        self.log.info("geofence in force: " + ("none" if fence is None else
                      f"{len(fence.inclusion)}-vertex inclusion, {len(fence.exclusion_polygons)} exclusion polygons, "
                      f"{len(fence.exclusion_circles)} circles, ceiling {fence.ceiling:g} m, floor {fence.floor:g} m, "
                      f"max distance {fence.max_distance:g} m"))

    def on_setpoint(self, source: SetpointSource, topic: str, msg: GuidanceSetpoint) -> None:
        self.core.inputs.now = self.clock_s()  # arrival time: the offboard stream's proof of life
        self.journal.setpoint(int(source), self.now_ns, jr.stamp_ns(msg.header.stamp.sec, msg.header.stamp.nanosec))
        try:
            self.core.receive_setpoint(source, conv.setpoint_from_msg(msg))
        except ValueError as exc:
            self.log.warning(f"{topic}: setpoint ignored: {exc}", throttle_duration_sec=5.0)

    def on_command(self, request: VehicleCommand.Request, response: VehicleCommand.Response) -> VehicleCommand.Response:
        self.core.inputs.now = self.clock_s()
        self.journal.command(self.now_ns, request.command, request.mode, request.force, request.altitude)
        result, response.message = answer_command(self.core, request.command, request.mode, request.altitude, request.force)
        response.result = int(result)
        return response

    # ----------------------------------------------------------------- executive phases and tasks
    def input_phase(self, k: int) -> None:
        self.drainer.drain()  # take what is queued, never wait (c4d_ros.drain)
        self.core.inputs.now = self.clock_s()
        core = self.core
        if not core.out.armed and any(r.command in ARMING for r in core.pending):  # resim's start point
            self.journal.queue_snapshot({
                "core": core, "geofence": self.geofence, "origin": self.origin, "cfg": self.cfg, "params": self.params,
                "ranges": {n: (p.low, p.high) for n, p in PARAMS.items()}})

    def latch(self, k: int) -> None:
        if self.live is not None:
            changes = self.live.take()  # validated when set; in force from this tick's first task on
            if changes:
                self.journal.blob(jr.C_RETUNE, pickle.dumps(changes))
                self.core.retune(airframe_with(self.core.af, changes))
                self.log.info(f"parameters applied at tick {k}: {describe(changes)}")
        self.core.latch()

    def output_phase(self, k: int) -> None:
        self.pub_actuators.publish(wire.actuator_cdr(self.core.out, self.core.inputs.now, k))
        self.journal.tick(k, self.now_ns)  # after the tick: a retune journaled at the latch precedes it
        if k - self.journal_k >= JOURNAL_TICKS:
            self.journal_k = k
            for payload in self.journal.flush():
                self.pub_journal.publish(UInt8MultiArray(data=array.array("B", payload)))

    def status_task(self, k: int) -> None:
        out, now = self.core.out, self.core.inputs.now
        if self.status.due(out, now):
            self.pub_status.publish(conv.status_msg(out, now, self.status.arm_time_ns, setpoints_ignored=self.ignored(),
                                                    offboard_stream_s=self.core.offboard_live_s()))
        for event in out.events:
            self.log.info(f"event: {event}")
        out.events.clear()

    def ignored(self) -> int:
        return self.core.inputs.setpoints.ignored & 0xFFFFFFFF

    def on_report(self, report: ExecutorReport) -> None:
        self.pub_stats.publish(conv.stats_msg(report, self.clock_s()))
        self.log.info(
            f"{report.ticks} ticks, load mean {report.load_mean_percent:.1f} % max {report.load_max_percent:.1f} %, "
            f"jitter p99 {report.release_jitter_p99_us:.0f} µs, overruns {report.overruns_total}, "
            f"skipped {report.skipped_ticks_total}, CPU {report.cpu_percent:.0f} %")
        if self.params.log_table:
            self.log.info("\n" + format_table(report))

    # ----------------------------------------------------------------- run and stop
    def run(self) -> int:
        """Run the executive until SIGINT/SIGTERM, then command the motors to zero; returns 0."""
        signal.signal(signal.SIGINT, self._stop)
        signal.signal(signal.SIGTERM, self._stop)
        node_runtime.apply_rt_priority(self.params.rt_priority, self.log)
        schedule = self.cfg.schedule
        self.pub_schedule.publish(conv.schedule_msg(schedule, self.cfg.executive_name, self.clock_s()))
        self.input_phase(0)  # warm-up outside the timed loop: first-call costs must not count as an overrun
        if not self.lockstep:  # (in lockstep a command is the answer to a step: none before the first)
            self.output_phase(0)
        variant = f" ({schedule.order_variant})" if schedule.order_variant else ""
        self.log.info(
            f"{self.cfg.executive_name}: {1e6 / schedule.tick_us:.0f} Hz, {len(schedule.tasks)} tasks, phases by "
            f"{schedule.method}{variant}, max tick load {schedule.max_tick_load_us} µs of {schedule.tick_us}; "
            f"{schedule.certificate_reason}; airframe {self.cfg.airframe.name}")
        if schedule.warning:  # e.g. phase_method optimal found nothing in its time limit: GCD+ phases instead
            self.log.warning(schedule.warning)
        if self.lockstep:
            self.log.info("LOCKSTEP: ticks follow the sim's simulated time (/clock), each waits for its step's inputs")
            self.executive.start(t0_ns=self._wait_for_sim_time())
        else:
            tick_ns = self.executive.tick_ns
            phase_ns = round(self.params.tick_phase * tick_ns)
            self.executive.start(t0_ns=grid_start_ns(time.monotonic_ns(), tick_ns, tick_ns, phase_ns))
        try:
            self.executive.run()
        finally:
            self._motors_to_zero()
            if self.live is not None:
                self.live.flush()  # the last change is on disk before the process ends
        return 0

    def _stop(self, signum, frame) -> None:
        self.executive.stop()
        if self.lockstep:
            self.lockstep.interrupt()

    def _motors_to_zero(self) -> None:
        out = self.core.out
        out.armed = False  # motors to zero first, then tear down
        out.commands = tuple(0.0 for _ in out.commands)
        now = self.clock_s()
        self.pub_actuators.publish(conv.actuator_msg(out, now, self.executive.tick))
        self.pub_status.publish(conv.status_msg(out, now, self.status.arm_time_ns, setpoints_ignored=self.ignored()))
        time.sleep(0.2)  # let the last messages leave
        self.log.info("stopped: motors commanded to zero")


def main(argv: list[str] | None = None) -> int:
    rclpy = node_runtime.init(argv)
    try:
        node = lifecycle.create_node(rclpy, NAME)  # a managed node (c4d_ros.lifecycle, docs/lifecycle.md)
    except ComponentError as exc:
        return node_runtime.fail(NAME, str(exc))

    def configure() -> CoreNode:  # lifecycle configure: parameters and config loaded and checked, entities created
        declared = Declaration(node, PARAMS)
        cfg = CoreParams(**declared.values).load_config()
        params = CoreParams(**declared.settle(cfg.parameters()))
        params.barrier()
        store = VehicleStore.of(params.vehicle, NAME) if params.vehicle else None
        live = LiveParameters(node, core_table(cfg.airframe), store, node.get_logger().info)
        cfg = replace(cfg, airframe=airframe_with(cfg.airframe, live.values))
        return CoreNode(node, cfg, params, live)
    return lifecycle.LoopWork(node, configure, (ParameterError, CoreConfigError, BarrierError, TunableError),
                              stop=lambda owner: owner._stop(0, None), refuse=armed_refusal).run(NAME)


def armed_refusal(owner: CoreNode) -> str | None:
    """Why the core may not be deactivated or shut down now: the motors are armed."""
    return "the vehicle is armed: land and disarm first" if owner.core.out.armed else None


if __name__ == "__main__":
    sys.exit(main())
