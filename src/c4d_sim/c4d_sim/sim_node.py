"""`ros2 run c4d_sim sim` — real-time SITL vehicle: the plant, its sensors, faults.

The plant is stepped at `physics_rate_hz` (default 1 kHz) by a CyclicExecutive on the wall
clock (absolute deadlines), so simulated time tracks real time without drift. Sensors are
sampled as executive tasks at their rates and published on sensors/* (sensor_msgs: Imu,
NavSatFix — published after the GNSS latency, stamped at measurement time — FluidPressure,
MagneticField, Range, BatteryState); the true state goes on sim/ground_truth
(nav_msgs/Odometry in the home ENU frame). Motor commands come from control/actuators; without
a command for 0.2 s the motors stop (ESC failsafe).

Faults are ROS parameters, changeable at run time (parameter service):
  fault.imu_dropout, fault.imu_freeze, fault.gps_loss, fault.baro_dropout, fault.baro_freeze,
  fault.mag_dropout, fault.range_dropout (bool); fault.gps_drift_m_s ([e, n, u]);
  fault.motor_health (one factor per motor, 1 = nominal, 0 = failed);
  fault.battery_drain_factor; fault.wind_gust_m_s (extra gust amplitude).
Parameters: config (sim YAML). Bad configuration: one line, exit 2.
"""

from __future__ import annotations

import math
import sys
import time
from collections import deque
from pathlib import Path

from c4d_sched.executive import CyclicExecutive, MonotonicClock
from c4d_sched.tickschedule import TaskSpec, build_schedule

from .plant import MultirotorPlant
from .sensors import RANGE_MIN, Faults, SensorSuite
from .sim_config import SimConfigError, default_sim_config, load_sim_config


def main(argv: list[str] | None = None) -> int:
    from c4d_ros import node_runtime

    rclpy = node_runtime.init(argv)
    from nav_msgs.msg import Odometry
    from rcl_interfaces.msg import SetParametersResult
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import BatteryState, FluidPressure, Imu, MagneticField, NavSatFix, NavSatStatus, Range

    from c4d_interfaces.msg import ActuatorCommand

    node = rclpy.create_node("sim")
    try:
        path = node.declare_parameter("config", "").value
        cfg = load_sim_config(Path(path) if path else default_sim_config())
    except SimConfigError as exc:
        return node_runtime.fail("sim", str(exc), node)
    af, sc = cfg["airframe"], cfg["sensors"]
    plant = MultirotorPlant(af, (0.0, 0.0, 0.0), cfg["yaw"])
    faults = Faults()
    suite = SensorSuite(sc, cfg["origin"], seed=cfg["seed"], faults=faults)
    extra_gust = [0.0]
    fault_params = {
        "fault.imu_dropout": False, "fault.imu_freeze": False, "fault.gps_loss": False, "fault.baro_dropout": False,
        "fault.baro_freeze": False, "fault.mag_dropout": False, "fault.range_dropout": False,
        "fault.gps_drift_m_s": [0.0, 0.0, 0.0], "fault.motor_health": [1.0] * len(af.motors),
        "fault.battery_drain_factor": 1.0, "fault.wind_gust_m_s": 0.0,
    }
    for name, default in fault_params.items():
        node.declare_parameter(name, default)

    def on_params(params) -> SetParametersResult:
        for p in params:
            if p.name not in fault_params:
                continue
            value = p.value
            key = p.name.split(".", 1)[1]
            if key == "motor_health":
                if len(value) != len(af.motors) or not all(0.0 <= v <= 1.0 for v in value):
                    return SetParametersResult(successful=False, reason=f"motor_health needs {len(af.motors)} values in [0, 1]")
                plant.motor_health = [float(v) for v in value]
            elif key == "gps_drift_m_s":
                if len(value) != 3:
                    return SetParametersResult(successful=False, reason="gps_drift_m_s needs 3 values")
                faults.gps_drift = tuple(float(v) for v in value)
            elif key == "wind_gust_m_s":
                extra_gust[0] = float(value)
            elif key == "battery_drain_factor":
                if value < 0:
                    return SetParametersResult(successful=False, reason="battery_drain_factor must be >= 0")
                faults.battery_drain_factor = float(value)
            else:
                setattr(faults, key, bool(value))
            node.get_logger().info(f"fault {key} = {value}")
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(on_params)

    sensor_qos = QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
    pub = {
        "imu": node.create_publisher(Imu, "sensors/imu", sensor_qos),
        "gps": node.create_publisher(NavSatFix, "sensors/gps", sensor_qos),
        "baro": node.create_publisher(FluidPressure, "sensors/baro", sensor_qos),
        "mag": node.create_publisher(MagneticField, "sensors/mag", sensor_qos),
        "range": node.create_publisher(Range, "sensors/range_down", sensor_qos),
        "battery": node.create_publisher(BatteryState, "sensors/battery", sensor_qos),
        "truth": node.create_publisher(Odometry, "sim/ground_truth", sensor_qos),
    }
    command = {"outputs": [0.0] * len(af.motors), "armed": False, "t": -math.inf}

    def on_actuators(msg: ActuatorCommand) -> None:
        if len(msg.outputs) == len(af.motors):
            command["outputs"], command["armed"], command["t"] = list(msg.outputs), msg.armed, time.monotonic()

    from c4d_ros.drain import Drainer

    drainer = Drainer(node)
    drainer.subscription(ActuatorCommand, "control/actuators", on_actuators,
                         QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
    drainer.adopt_node_services()  # fault injection via the parameter services, no executor needed
    rate = cfg["rate"]
    dt = 1.0 / rate
    t_wall0 = [0.0]  # wall-clock time of simulated t = 0, fixed at the first physics tick
    gps_queue: deque = deque()
    from c4d_ros.stamps import s_to_stamp

    def stamp(t: float):
        return s_to_stamp(t_wall0[0] + t)

    last_tick = [-1]

    def physics(k: int) -> None:
        if last_tick[0] < 0:  # anchor simulated t = 0 to the wall-clock time of tick 0's deadline
            t_wall0[0] = time.time() - (time.monotonic_ns() - executive.t0_ns) / 1e9 - plant.state.t
        fresh = time.monotonic() - command["t"] < 0.2
        s = plant.state
        gust = (cfg["gust"] + extra_gust[0]) * 0.5 * (1 - math.cos(2 * math.pi * s.t / cfg["gust_period"]))
        plant.wind = (cfg["wind_mean"][0] + gust, cfg["wind_mean"][1], cfg["wind_mean"][2])
        for _ in range(k - last_tick[0]):  # ticks skipped after a stall are simulated too, all of them:
            plant.step(dt, command["outputs"], command["armed"] and fresh)  # sim time stays wall time
        last_tick[0] = k

    def imu(k: int) -> None:
        sample = suite.imu(plant.state, 1.0 / sc.imu_rate_hz)
        if sample is None:
            return
        m = Imu()
        m.header.stamp, m.header.frame_id = stamp(sample.stamp), "base_link"
        m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = sample.gyro
        m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z = sample.accel
        m.orientation_covariance[0] = -1.0  # no orientation estimate in this message
        m.angular_velocity_covariance = [sc.gyro_noise**2, 0.0, 0.0, 0.0, sc.gyro_noise**2, 0.0, 0.0, 0.0, sc.gyro_noise**2]
        m.linear_acceleration_covariance = [sc.accel_noise**2, 0.0, 0.0, 0.0, sc.accel_noise**2, 0.0, 0.0, 0.0,
                                            sc.accel_noise**2]
        pub["imu"].publish(m)

    def gps(k: int) -> None:
        sample = suite.gps(plant.state, 1.0 / sc.gps_rate_hz)
        if sample is not None:
            gps_queue.append(sample)
        while gps_queue and gps_queue[0].stamp + sc.gps_latency_s <= plant.state.t + 1e-9:
            g = gps_queue.popleft()
            m = NavSatFix()
            m.header.stamp, m.header.frame_id = stamp(g.stamp), "gps"
            m.status.status, m.status.service = NavSatStatus.STATUS_FIX, NavSatStatus.SERVICE_GPS
            m.latitude, m.longitude, m.altitude = g.latitude, g.longitude, g.altitude
            m.position_covariance = [g.sigma_h**2, 0.0, 0.0, 0.0, g.sigma_h**2, 0.0, 0.0, 0.0, g.sigma_v**2]
            m.position_covariance_type = NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
            pub["gps"].publish(m)

    def baro(k: int) -> None:
        sample = suite.baro(plant.state)
        if sample is not None:
            m = FluidPressure()
            m.header.stamp, m.header.frame_id = stamp(sample[0]), "base_link"
            m.fluid_pressure, m.variance = sample[1], (12.0 * sc.baro_noise) ** 2
            pub["baro"].publish(m)

    def mag(k: int) -> None:
        sample = suite.mag(plant.state)
        if sample is not None:
            m = MagneticField()
            m.header.stamp, m.header.frame_id = stamp(plant.state.t), "base_link"
            m.magnetic_field.x, m.magnetic_field.y, m.magnetic_field.z = sample
            pub["mag"].publish(m)

    def range_down(k: int) -> None:
        sample = suite.range_down(plant.state)
        if sample is not None:
            m = Range()
            m.header.stamp, m.header.frame_id = stamp(plant.state.t), "range_down"
            m.radiation_type, m.field_of_view, m.min_range, m.max_range = Range.INFRARED, 0.05, RANGE_MIN, sc.range_max
            m.range = sample
            pub["range"].publish(m)

    def battery(k: int) -> None:
        b = suite.battery(plant.state, 1.0 / sc.battery_rate_hz)
        m = BatteryState()
        m.header.stamp = stamp(b.stamp)
        m.voltage, m.current, m.charge = b.voltage, -b.current, b.charge_ah  # ROS: negative while discharging
        m.capacity = m.design_capacity = sc.battery_capacity_ah
        m.percentage = b.percentage
        m.power_supply_status = BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
        m.power_supply_technology = BatteryState.POWER_SUPPLY_TECHNOLOGY_LIPO
        m.present = True
        m.cell_voltage = [b.voltage / sc.battery_cells] * sc.battery_cells
        pub["battery"].publish(m)

    def truth(k: int) -> None:
        s = plant.state
        m = Odometry()
        m.header.stamp, m.header.frame_id, m.child_frame_id = stamp(s.t), "map", "base_link"
        m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.position.z = s.position
        q = s.orientation
        m.pose.pose.orientation.w, m.pose.pose.orientation.x, m.pose.pose.orientation.y, m.pose.pose.orientation.z = q
        m.twist.twist.linear.x, m.twist.twist.linear.y, m.twist.twist.linear.z = s.velocity  # world frame (documented)
        m.twist.twist.angular.x, m.twist.twist.angular.y, m.twist.twist.angular.z = s.angular_velocity
        pub["truth"].publish(m)

    def divider(hz: float) -> int:
        d = round(rate / hz)
        if d < 1 or abs(rate / d - hz) > 1e-6 * hz:
            raise SimConfigError(f"sim config: a {hz} Hz rate does not divide the physics rate {rate} Hz")
        return d

    tasks = {"physics": physics, "imu": imu, "gps": gps, "baro": baro, "mag": mag, "range": range_down,
             "battery": battery, "truth": truth}
    rates = {"physics": rate, "imu": sc.imu_rate_hz, "gps": sc.gps_rate_hz, "baro": sc.baro_rate_hz,
             "mag": sc.mag_rate_hz, "range": sc.range_rate_hz, "battery": sc.battery_rate_hz, "truth": cfg["truth_rate"]}
    try:
        specs = [TaskSpec(n, "input" if n == "physics" else "telemetry", divider(rates[n]), 50 if n == "physics" else 30,
                          0 if n == "physics" else None) for n in tasks]
    except SimConfigError as exc:
        return node_runtime.fail("sim", str(exc), node)
    schedule = build_schedule(1_000_000 // rate, "gcdplus", specs)

    def drain(k: int) -> None:
        drainer.drain()

    # plain sleeps (no spinning): the plant needs real time, not µs release precision
    # a sensor keeps sampling whatever the simulator's lateness: samples whose tick was skipped after
    # a stall are produced (late, once) at the next tick instead of vanishing — otherwise a 10 Hz
    # battery could fall silent for 0.7 s on a loaded machine and the health monitor would declare
    # the sim dead (physics simulates every skipped step itself)
    executive = CyclicExecutive(schedule, tasks, MonotonicClock(spin_ns=0), name="sim", input_phase=drain,
                                report_period_s=3600, manage_gc=True, catch_up=set(tasks) - {"physics"})
    import signal

    signal.signal(signal.SIGINT, lambda s, f: executive.stop())
    signal.signal(signal.SIGTERM, lambda s, f: executive.stop())
    node.get_logger().info(f"sim: {af.name} at {cfg['origin']}, physics {rate} Hz, IMU {sc.imu_rate_hz:.0f} Hz, "
                           f"GNSS {sc.gps_rate_hz:.0f} Hz")
    try:
        executive.run()
    finally:
        executive.release_gc()
        node.get_logger().info(f"sim stopped at t = {plant.state.t:.1f} s; overruns {executive.profiler.overruns_total}")
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
