"""ROS message ↔ GNC core types. The only place that knows both sides (keeps gnc.py ROS-free)."""

from __future__ import annotations

import math

from c4d_common.vehicle import FailsafeAction
from c4d_interfaces.msg import (
    ActuatorCommand,
    ExecutorStats,
    ExecutorTaskStats,
    GuidanceSetpoint,
    ScheduleEntry,
    ScheduleTable,
    VehicleState,
    VehicleStatus,
)
from c4d_ros.stamps import s_to_stamp, stamp_to_s
from c4d_sched.profiler import ExecutorReport
from c4d_sched.tickschedule import TickSchedule

from .gnc import Level, Outputs, Setpoint, StateSample


def state_from_msg(msg: VehicleState) -> StateSample:
    p, v, q, w = msg.position, msg.velocity, msg.orientation, msg.angular_velocity
    return StateSample(
        stamp=stamp_to_s(msg.header.stamp),
        position=(p.x, p.y, p.z),
        velocity=(v.x, v.y, v.z),
        orientation=(q.w, q.x, q.y, q.z),
        angular_velocity=(w.x, w.y, w.z),
        valid_position=bool(msg.valid & VehicleState.VALID_POSITION_XY) and bool(msg.valid & VehicleState.VALID_POSITION_Z),
        valid_attitude=bool(msg.valid & VehicleState.VALID_ATTITUDE),
        valid_velocity=bool(msg.valid & VehicleState.VALID_VELOCITY_XY),
        terrain_distance=msg.terrain_distance if msg.valid & VehicleState.VALID_TERRAIN_DISTANCE else math.nan,
        origin=(msg.origin.latitude, msg.origin.longitude, msg.origin.altitude)
        if msg.valid & VehicleState.VALID_ORIGIN else None,
    )


def setpoint_from_msg(msg: GuidanceSetpoint) -> Setpoint:
    try:
        level = Level(msg.control_level)
    except ValueError:
        raise ValueError(f"unknown control_level {msg.control_level}") from None
    q = msg.orientation
    return Setpoint(
        stamp=stamp_to_s(msg.header.stamp),
        level=level,
        position=(msg.position.x, msg.position.y, msg.position.z),
        velocity=(msg.velocity.x, msg.velocity.y, msg.velocity.z),
        acceleration=(msg.acceleration.x, msg.acceleration.y, msg.acceleration.z),
        yaw=msg.yaw,
        yaw_rate=msg.yaw_rate,
        orientation=(q.w, q.x, q.y, q.z) if (q.w, q.x, q.y, q.z) != (0.0, 0.0, 0.0, 0.0) else (1.0, 0.0, 0.0, 0.0),
        body_rate=(msg.body_rate.x, msg.body_rate.y, msg.body_rate.z),
        thrust=msg.thrust,
    )


def actuator_msg(out: Outputs, now: float, tick: int) -> ActuatorCommand:
    msg = ActuatorCommand()
    msg.header.stamp = s_to_stamp(now)
    msg.header.frame_id = "base_link"
    msg.armed = out.armed
    msg.outputs = [float(c) for c in out.commands] if out.armed else [0.0] * len(out.commands)
    msg.tick = tick
    msg.input_stamp = s_to_stamp(out.input_stamp)
    return msg


def status_msg(out: Outputs, now: float, arm_time_ns: int, failsafe: tuple[int, str] = (FailsafeAction.NONE, ""),
               setpoints_ignored: int = 0, offboard_stream_s: float = 0.0) -> VehicleStatus:
    msg = VehicleStatus()
    msg.header.stamp = s_to_stamp(now)
    msg.armed = out.armed
    msg.flight_mode = int(out.mode)
    msg.nav_state = int(out.nav)
    msg.landed_state = int(out.landed)
    msg.failsafe_action, msg.failsafe_reason = int(failsafe[0]), failsafe[1]
    msg.arm_time_ns = arm_time_ns
    msg.setpoint_source = int(out.source)
    msg.setpoints_ignored = setpoints_ignored
    msg.offboard_stream_s = offboard_stream_s
    return msg


def stats_msg(report: ExecutorReport, now: float) -> ExecutorStats:
    msg = ExecutorStats()
    msg.header.stamp = s_to_stamp(now)
    for name in ("executor", "tick_rate_hz", "ticks_total", "overruns_total", "skipped_ticks_total", "ticks", "overruns",
                 "skipped_ticks", "load_mean_percent", "load_max_percent", "release_jitter_mean_us",
                 "release_jitter_max_us", "release_jitter_p99_us", "release_jitter_p50_us", "cpu_percent"):
        setattr(msg, name, getattr(report, name))
    msg.tasks = [
        ExecutorTaskStats(name=t.name, group=t.group, divider=t.divider, count=t.count, period_mean_us=t.period_mean_us,
                          period_std_us=t.period_std_us, rate_hz=t.rate_hz, duty_mean_us=t.duty_mean_us,
                          duty_std_us=t.duty_std_us, duty_min_us=t.duty_min_us, duty_max_us=t.duty_max_us,
                          budget_us=t.budget_us, budget_overruns=t.budget_overruns, cpu_percent=t.cpu_percent)
        for t in report.tasks
    ]
    return msg


def schedule_msg(schedule: TickSchedule, executor: str, now: float) -> ScheduleTable:
    msg = ScheduleTable()
    msg.header.stamp = s_to_stamp(now)
    msg.executor = executor
    msg.tick_period_us = float(schedule.tick_us)
    msg.method = schedule.method
    msg.order_variant = schedule.order_variant
    msg.omega_us = float(schedule.omega_us)
    msg.sum_delta_us = float(schedule.sum_delta_us)
    msg.certificate_holds = schedule.certificate
    msg.max_tick_load_us = float(schedule.max_tick_load_us)
    msg.optimality = schedule.optimality
    msg.lower_bound_us = float(schedule.lower_bound_us)
    msg.entries = [ScheduleEntry(name=t.name, group=t.group, divider=t.divider, phase=t.phase, order=t.order,
                                 offset_us=float(t.offset_us), budget_us=float(t.budget_us)) for t in schedule.tasks]
    return msg
