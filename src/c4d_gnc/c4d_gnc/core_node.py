"""`ros2 run c4d_gnc core` — the GNC core node: a thin rclpy edge around GncCore.

The node never uses rclpy timers: it runs the CyclicExecutive (absolute deadlines) in the
main thread, and each tick's input phase drains the subscriptions and the command service
without blocking (spin_once with a zero timeout) into the GncCore blackboard.

Interfaces (docs/ARCHITECTURE.md):
  subscribes  <imu_topic> (sensor_msgs/Imu, gyro for the rate loop), navigation/state
              (c4d_interfaces/VehicleState), guidance/setpoint (c4d_interfaces/GuidanceSetpoint)
  serves      gnc/command (c4d_interfaces/VehicleCommand: arm, disarm, take-off, land, hold, set mode)
  publishes   control/actuators (ActuatorCommand, every tick; the only publisher),
              vehicle/status (VehicleStatus, latched, on change and at 2 Hz),
              gnc/executor_stats (ExecutorStats, at report_period_s), gnc/schedule (ScheduleTable, latched)
Parameters: config (core YAML), airframe (name or path), phase_method (gcdplus|paparazzi|zero),
            imu_topic, log_table (print the profiler table each report), rt_priority (SCHED_FIFO
            priority for the process, 0 = normal scheduling).
SIGINT/SIGTERM: the loop stops, zero motor commands (armed = false) are published, exit 0.
Bad configuration: one line on stderr, exit 2, nothing armed.
"""

from __future__ import annotations

import os
import signal
import sys
import time

from c4d_ros.drain import Drainer
from c4d_sched.executive import CyclicExecutive, MonotonicClock
from c4d_sched.profiler import format_table

from .core_config import CoreConfigError, load_core_config
from .gnc import Command, GncCore, Mode, Request

RESULT_ACCEPTED, RESULT_TEMPORARILY_REJECTED, RESULT_DENIED, RESULT_UNSUPPORTED = 0, 1, 2, 3
STATUS_PERIOD_S = 0.2  # 5 Hz: also the heartbeat health watches


def main(argv: list[str] | None = None) -> int:
    import rclpy
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.signals import SignalHandlerOptions
    from sensor_msgs.msg import Imu

    from c4d_interfaces.msg import ActuatorCommand, ExecutorStats, GuidanceSetpoint, ScheduleTable, VehicleState, VehicleStatus
    from c4d_interfaces.srv import VehicleCommand

    from . import ros_conversions as conv

    rclpy.init(args=argv if argv is not None else sys.argv, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("core")
    try:
        config_path = node.declare_parameter("config", "").value
        airframe = node.declare_parameter("airframe", "").value
        method = node.declare_parameter("phase_method", "").value
        imu_topic = node.declare_parameter("imu_topic", "perception/imu").value
        log_table = node.declare_parameter("log_table", False).value
        rt_priority = int(node.declare_parameter("rt_priority", 0).value)
        cfg = load_core_config(config_path or None, airframe or None, method or None)
    except CoreConfigError as exc:
        print(f"core: error: {exc}", file=sys.stderr)
        node.destroy_node()
        rclpy.try_shutdown()
        return 2

    schedule = cfg.schedule
    core = GncCore(cfg.airframe, schedule.tick_us / 1e6)
    sensor_qos = QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT, history=HistoryPolicy.KEEP_LAST)
    state_qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT, history=HistoryPolicy.KEEP_LAST)
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    stats_qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)

    def clock_s() -> float:
        return node.get_clock().now().nanoseconds * 1e-9

    def on_imu(msg: Imu) -> None:
        w = msg.angular_velocity
        core.inputs.gyro = (w.x, w.y, w.z)
        core.inputs.gyro_stamp = conv.stamp_to_s(msg.header.stamp)

    def on_state(msg: VehicleState) -> None:
        core.inputs.state = conv.state_from_msg(msg)

    def on_setpoint(msg: GuidanceSetpoint) -> None:
        try:
            core.inputs.setpoint = conv.setpoint_from_msg(msg)
        except ValueError as exc:
            node.get_logger().warning(f"guidance setpoint ignored: {exc}")

    def on_command(request: VehicleCommand.Request, response: VehicleCommand.Response) -> VehicleCommand.Response:
        core.inputs.now = clock_s()
        try:
            command = Command(request.command)
        except ValueError:
            response.result, response.message = RESULT_UNSUPPORTED, f"command {request.command} is not served by the core"
            return response
        try:
            mode = Mode(request.mode) if command == Command.SET_MODE else Mode.UNKNOWN
        except ValueError:
            response.result, response.message = RESULT_DENIED, f"unknown mode {request.mode}"
            return response
        ok, reason = core.request(Request(command, mode, float(request.altitude), bool(request.force)))
        if ok:
            response.result, response.message = RESULT_ACCEPTED, reason
        else:
            stale = "stale" in reason or "valid" in reason
            response.result = RESULT_TEMPORARILY_REJECTED if stale else RESULT_DENIED
            response.message = reason
        return response

    drainer = Drainer(node)
    drainer.subscription(Imu, imu_topic, on_imu, sensor_qos)
    drainer.subscription(VehicleState, "navigation/state", on_state, state_qos)
    drainer.subscription(GuidanceSetpoint, "guidance/setpoint", on_setpoint, state_qos)
    drainer.service(VehicleCommand, "gnc/command", on_command)
    pub_actuators = node.create_publisher(ActuatorCommand, "control/actuators", state_qos)
    pub_status = node.create_publisher(VehicleStatus, "vehicle/status", latched)
    pub_stats = node.create_publisher(ExecutorStats, "gnc/executor_stats", stats_qos)
    pub_schedule = node.create_publisher(ScheduleTable, "gnc/schedule", latched)
    drainer.adopt_node_services()  # parameter services too: no executor spins this node

    last_status: dict[str, object] = {"key": None, "time": 0.0, "arm_ns": 0, "armed": False}

    def input_phase(k: int) -> None:
        drainer.drain()  # take what is queued, never wait (see ros_drain.py)
        core.inputs.now = clock_s()

    def status_task(k: int) -> None:
        out, now = core.out, core.inputs.now
        if out.armed and not last_status["armed"]:
            last_status["arm_ns"] = int(now * 1e9)
        last_status["armed"] = out.armed
        key = (out.armed, out.mode, out.nav, out.landed)
        if key != last_status["key"] or now - float(last_status["time"]) >= STATUS_PERIOD_S:
            pub_status.publish(conv.status_msg(out, now, int(last_status["arm_ns"])))
            last_status["key"], last_status["time"] = key, now
        for event in out.events:
            node.get_logger().info(f"event: {event}")
        out.events.clear()

    def output_phase(k: int) -> None:
        pub_actuators.publish(conv.actuator_msg(core.out, core.inputs.now, k))

    def on_report(report) -> None:
        pub_stats.publish(conv.stats_msg(report, clock_s()))
        node.get_logger().info(
            f"{report.ticks} ticks, load mean {report.load_mean_percent:.1f} % max {report.load_max_percent:.1f} %, "
            f"jitter p99 {report.release_jitter_p99_us:.0f} µs, overruns {report.overruns_total}, "
            f"skipped {report.skipped_ticks_total}, CPU {report.cpu_percent:.0f} %")
        if log_table:
            node.get_logger().info("\n" + format_table(report))

    functions = {}
    for task in schedule.tasks:
        if task.name == "status":
            functions[task.name] = status_task
        else:
            fn, dt = core.task_functions()[task.name], task.divider * schedule.tick_us / 1e6
            functions[task.name] = lambda k, fn=fn, dt=dt: fn(dt)
    executive = CyclicExecutive(schedule, functions, MonotonicClock(), name=cfg.executive_name, input_phase=input_phase,
                                latch=lambda k: core.latch(), output_phase=output_phase,
                                report_period_s=cfg.report_period_s, on_report=on_report, manage_gc=True)

    def stop(signum, frame) -> None:
        executive.stop()

    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    if rt_priority > 0:
        try:  # real-time FIFO scheduling: the executive preempts the rest of the graph on wake-up
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(rt_priority))
            node.get_logger().info(f"SCHED_FIFO priority {rt_priority}")
        except (PermissionError, OSError) as exc:
            node.get_logger().warning(f"rt_priority {rt_priority} not applied ({exc}); running with normal priority")
    pub_schedule.publish(conv.schedule_msg(schedule, cfg.executive_name, clock_s()))
    input_phase(0)  # warm-up outside the timed loop: first-call costs must not count as an overrun
    output_phase(0)
    node.get_logger().info(
        f"{cfg.executive_name}: {1e6 / schedule.tick_us:.0f} Hz, {len(schedule.tasks)} tasks, phases by "
        f"{schedule.method}{' (' + schedule.order_variant + ')' if schedule.order_variant else ''}, max tick load "
        f"{schedule.max_tick_load_us} µs of {schedule.tick_us}; {schedule.certificate_reason}; airframe {cfg.airframe.name}")
    try:
        executive.run()
    finally:
        core.out.armed = False  # motors to zero first, then tear down
        core.out.commands = tuple(0.0 for _ in core.out.commands)
        now = clock_s()
        pub_actuators.publish(conv.actuator_msg(core.out, now, executive.tick))
        pub_status.publish(conv.status_msg(core.out, now, int(last_status["arm_ns"])))
        time.sleep(0.2)  # let the last messages leave
        node.get_logger().info("stopped: motors commanded to zero")
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
