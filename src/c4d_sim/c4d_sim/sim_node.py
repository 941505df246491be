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
  fault.mag_dropout, fault.range_dropout (bool); GNSS spoofing fault.gps_drift_m_s ([e, n, u] m/s),
  fault.gps_jump_m ([e, n, u] m), fault.gps_delay_s (meaconing); jamming fault.gps_jam_dropout,
  fault.gps_jam_sigma_factor;
  fault.motor_health (one factor per motor, 1 = nominal, 0 = failed);
  fault.battery_drain_factor; fault.wind_gust_m_s (extra gust amplitude).
Parameters: config (sim YAML); world (world YAML: obstacles, movers, wind — docs/flight_loop.md; empty = none);
scan_rate_hz, scan_beams, scan_range_max_m, scan_noise_m (the lidar). With a world the sim renders a
horizontal lidar scan on sensors/scan (lidar.py, vectorised ray casting in its own executive task)
and publishes the true obstacles and wind on sim/obstacles (10 Hz); without one both topics exist
but stay silent. Bad configuration or world: one line, exit 2.
External-pose emulator (external_pose.*, external_pose.py): VIO / mocap from the ground truth on
navigation/external/odometry and/or MAVLink VISION_POSITION_ESTIMATE to the bridge (mavlink_out.py).
The behaviour is `simulation.Simulation` (ROS-free); this node maps it to topics and parameters.
"""

from __future__ import annotations

import array
import signal
import sys
import time
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import SetParametersResult
from sensor_msgs.msg import BatteryState, FluidPressure, Imu, LaserScan, MagneticField, NavSatFix, NavSatStatus, Range

from c4d_common import quat
from c4d_interfaces.msg import ActuatorCommand, Obstacle, Surroundings
from c4d_ros import cdr, lifecycle, manifest, node_runtime
from c4d_ros.component import ComponentError
from c4d_ros.drain import Drainer
from c4d_ros.params import ParameterError, Spec, declare, declare_all
from c4d_ros.stamps import s_to_stamp
from c4d_sched.executive import Clock, CyclicExecutive, MonotonicClock, grid_start_ns
from c4d_sched.tickschedule import build_schedule

from . import lockstep_sim
from .actuator_link import ActuatorLinkMonitor
from .external_pose import (
    OUTPUTS,
    SIGMA_FLOOR_RAD,
    ExternalPoseEmulator,
    ExternalPoseSample,
    ExternalPoseSettings,
    mavlink_vision_position,
    parse_udpout,
)
from .lidar import Lidar, LidarConfig
from .sensors import RANGE_MIN, ImuSample
from .sim_config import SimConfig, SimConfigError, default_sim_config, load_sim_config
from .simulation import SENSOR_TASKS, Simulation, task_specs
from .world import World, WorldError, load_world, truth

FAULT = "fault."
CONFIG = Spec("", "sim YAML file (airframe, start, rates, noise, wind); empty = the bundled config/sim.yaml [path]",
              read_only=True, empty=default_sim_config)
WORLD_PARAMS = {
    "world": Spec("", "world YAML file (static obstacles, movers, wind; docs/flight_loop.md); empty = no world [path]",
                  read_only=True),
    "scan_rate_hz": Spec(10.0, "lidar scan rate on sensors/scan (must divide the physics rate) [Hz]", 10.0, 20.0,
                         read_only=True),
    "scan_beams": Spec(360, "lidar beams per 360° scan [count]", 8, 4096, read_only=True),
    "scan_range_max_m": Spec(30.0, "lidar maximum range: farther surfaces read +inf [m]", 1.0, 200.0, read_only=True),
    "scan_noise_m": Spec(0.02, "lidar range noise, 1 sigma [m]", 0.0, 1.0, read_only=True),
}
OBSTACLES_RATE_HZ = 10.0  # sim/obstacles
EXTERNAL = "external_pose."
EXTERNAL_POSE_PARAMS = {EXTERNAL + name: spec for name, spec in {
    "enabled": Spec(False, "external-pose emulator on (settable at run time; false = the source is lost) [bool]"),
    "rate_hz": Spec(100.0, "external pose sample rate (must divide the physics rate) [Hz]", 1.0, 1000.0, read_only=True),
    "latency_s": Spec(0.03, "external pose delivery delay: published this long after its sample time, stamped with the "
                            "sample time (a multiple of 1/rate_hz; else rounded up to one) [s]", 0.0, 1.0, read_only=True),
    "noise_m": Spec(0.01, "external pose position noise, 1 sigma per axis (also the reported covariance) [m]", 0.0, 10.0),
    "yaw_noise_deg": Spec(0.2, "external pose heading noise, 1 sigma (also the reported orientation covariance) [deg]",
                          0.0, 45.0),
    "velocity_noise_m_s": Spec(0.02, "external odometry body-velocity noise, 1 sigma per axis [m/s]", 0.0, 10.0),
    "dropout_probability": Spec(0.0, "probability that an external pose sample is lost [0..1]", 0.0, 1.0),
    "frame_yaw_deg": Spec(0.0, "yaw of the emulated source's frame in the sim's ENU world, ccw from east; the pose is "
                               "published in that frame (a change counts a reset) [deg]", -180.0, 180.0),
    "frame_offset_m": Spec([0.0, 0.0, 0.0], "origin of the emulated source's frame in the sim's ENU world, [x, y, z] "
                                            "(a change counts a reset) [m]"),
    "frame_id": Spec("odom", "frame_id of navigation/external/odometry (the source's frame) [name]", read_only=True),
    "output": Spec("ros", "where the external pose goes: ros (navigation/external/odometry), mavlink "
                          "(VISION_POSITION_ESTIMATE to mavlink_url) or both [ros|mavlink|both]", read_only=True),
    "mavlink_url": Spec("udpout:127.0.0.1:14550", "MAVLink destination of VISION_POSITION_ESTIMATE: the bridge's "
                                                  "udpin endpoint [udpout:HOST:PORT]", read_only=True),
    "mavlink_sysid": Spec(1, "MAVLink system id of the vehicle (the bridge's SYSID_THISMAV); the emulator is its "
                             "component 197, MAV_COMP_ID_VISUAL_INERTIAL_ODOMETRY [id]", 1, 255, read_only=True),
}.items()}
RUNTIME_EXTERNAL = ("enabled", "noise_m", "yaw_noise_deg", "velocity_noise_m_s", "dropout_probability", "frame_yaw_deg",
                    "frame_offset_m")


def fault_specs(motors: int) -> dict[str, Spec]:
    """The run-time fault parameters (settable through the parameter service)."""
    flags = {"imu_dropout": "the IMU publishes nothing", "imu_freeze": "the IMU repeats its last sample",
             "gps_loss": "no GNSS fix", "baro_dropout": "the barometer publishes nothing",
             "baro_freeze": "the barometer repeats its last pressure", "mag_dropout": "the magnetometer publishes nothing",
             "range_dropout": "the range finder publishes nothing"}
    specs = {FAULT + name: Spec(False, f"fault: {what} [bool]") for name, what in flags.items()}
    specs[FAULT + "gps_drift_m_s"] = Spec([0.0, 0.0, 0.0], "fault: drift rate of the reported GNSS position, [e, n, u] [m/s]")
    specs[FAULT + "gps_jump_m"] = Spec([0.0, 0.0, 0.0], "fault: step added to the reported GNSS position (spoofing), "
                                                        "[e, n, u] [m]")
    specs[FAULT + "gps_delay_s"] = Spec(0.0, "fault: meaconing — GNSS fixes report the true position this long ago, "
                                             "stamped now; 0 = off [s]", 0.0, 60.0)
    specs[FAULT + "gps_jam_dropout"] = Spec(0.0, "fault: jamming — probability that a GNSS fix is lost [0..1]", 0.0, 1.0)
    specs[FAULT + "gps_jam_sigma_factor"] = Spec(1.0, "fault: jamming — GNSS noise and reported covariance σ multiplied "
                                                      "(HDOP-like); 1 = nominal [factor]", 1.0, 1000.0)
    specs[FAULT + "motor_health"] = Spec([1.0] * motors, f"fault: thrust factor of each of the {motors} motors, "
                                                         "1 = nominal, 0 = failed [0..1]")
    specs[FAULT + "battery_drain_factor"] = Spec(1.0, "fault: multiplies the charge drawn from the battery [factor]",
                                                 0.0, 1e6)
    specs[FAULT + "wind_gust_m_s"] = Spec(0.0, "fault: added to the amplitude of the (1 - cos) gust from the east [m/s]",
                                          -50.0, 50.0)
    return specs


def read_rt_priority(node) -> int:
    return int(declare(node, "rt_priority", node_runtime.RT_PRIORITY))


def read_external_pose(node, physics_rate_hz: int) -> tuple[ExternalPoseSettings, dict[str, Any]]:
    """The emulator's settings and its read-only output parameters; ParameterError naming a bad one."""
    p = {name.removeprefix(EXTERNAL): value for name, value in declare_all(node, EXTERNAL_POSE_PARAMS).items()}
    divider = physics_rate_hz / p["rate_hz"]
    if abs(divider - round(divider)) > 1e-9:
        raise ParameterError(f"parameter 'external_pose.rate_hz': {p['rate_hz']:g} Hz does not divide the physics rate "
                             f"{physics_rate_hz} Hz (50, 100, 200 do)")
    if p["output"] not in OUTPUTS:
        raise ParameterError(f"parameter 'external_pose.output': {p['output']!r} is not one of {', '.join(OUTPUTS)}")
    if p["output"] != "ros":
        try:
            parse_udpout(p["mavlink_url"])
        except ValueError as exc:
            raise ParameterError(f"parameter 'external_pose.mavlink_url': {exc}") from None
    settings = ExternalPoseSettings(rate_hz=float(p["rate_hz"]), latency_s=float(p["latency_s"]))
    probe = ExternalPoseEmulator(settings)
    for name in RUNTIME_EXTERNAL:  # start values go through the same checks as run-time ones
        reason = probe.set(name, p[name])
        if reason:
            raise ParameterError(f"parameter 'external_pose.{name}': {reason}")
    return settings, p


def read_config(node) -> SimConfig:
    path = declare(node, "config", CONFIG)
    return load_sim_config(Path(path) if path else default_sim_config())


def read_world(node, physics_rate_hz: int = 1000) -> tuple[World | None, LidarConfig]:
    """The world file (None without one) and the lidar parameters; WorldError when the file is unusable,
    ParameterError when a parameter is (a scan rate must divide the physics rate: the scan is an executive task)."""
    p = declare_all(node, WORLD_PARAMS)
    divider = physics_rate_hz / p["scan_rate_hz"]
    if abs(divider - round(divider)) > 1e-9:
        raise ParameterError(f"parameter 'scan_rate_hz': {p['scan_rate_hz']:g} Hz does not divide the physics rate "
                             f"{physics_rate_hz} Hz (10, 12.5, 20 do)")
    lidar = LidarConfig(beams=int(p["scan_beams"]), range_max=float(p["scan_range_max_m"]), noise=float(p["scan_noise_m"]),
                        rate_hz=float(p["scan_rate_hz"]))
    return (load_world(p["world"]) if p["world"] else None), lidar


def diagonal_6x6(diagonal: tuple[float, ...]) -> array.array:
    """A 6x6 row-major covariance with this diagonal (the float64 array an Odometry covariance takes)."""
    out = array.array("d", bytes(8 * 36))
    for i, value in enumerate(diagonal):
        out[7 * i] = value
    return out


class SimNode:
    """The simulator's ROS face: fault parameters, sensors/* and sim/ground_truth publishers fed
    by executive tasks, control/actuators and the parameter services drained in the executive's
    input phase (no ROS executor: nothing wakes up per sample)."""

    def __init__(self, node, config: SimConfig, rt_priority: int = 0, world: World | None = None,
                 lidar: LidarConfig | None = None) -> None:
        self.node, self.rt_priority = node, rt_priority
        self.sim = Simulation(config, lambda: self.executive.t0_ns, world)
        self.lidar_config = lidar or LidarConfig()
        self.lidar = Lidar(self.lidar_config, world, config.seed) if world else None
        lockstep = declare_all(node, lockstep_sim.PARAMS)
        self.lockstep: lockstep_sim.SimLockstep | None = None
        self.plant, self.suite, self.sensors = self.sim.plant, self.sim.suite, config.sensors
        for name, value in declare_all(node, fault_specs(self.sim.motors)).items():  # start values apply too
            reason = self.sim.set_fault(name.removeprefix(FAULT), value)
            if reason:
                raise ParameterError(f"parameter '{name}': {reason}")
        settings, ext = read_external_pose(node, config.physics_rate_hz)
        self.external = ExternalPoseEmulator(settings, config.seed)
        self.external_ros = ext["output"] in ("ros", "both")
        self.vision = None
        if ext["output"] in ("mavlink", "both"):
            from .mavlink_out import VisionSender  # pymavlink only when MAVLink output is on

            self.vision = VisionSender(ext["mavlink_url"], int(ext["mavlink_sysid"]))
        node.add_on_set_parameters_callback(self.on_parameters)
        self.pub_imu = node.create_publisher(Imu, manifest.IMU.name, manifest.IMU.qos)
        self.pub_gps = node.create_publisher(NavSatFix, manifest.GPS.name, manifest.GPS.qos)
        self.pub_baro = node.create_publisher(FluidPressure, manifest.BARO.name, manifest.BARO.qos)
        self.pub_mag = node.create_publisher(MagneticField, manifest.MAG.name, manifest.MAG.qos)
        self.pub_range = node.create_publisher(Range, manifest.RANGE_DOWN.name, manifest.RANGE_DOWN.qos)
        self.pub_battery = node.create_publisher(BatteryState, manifest.BATTERY.name, manifest.BATTERY.qos)
        self.pub_truth = node.create_publisher(Odometry, manifest.GROUND_TRUTH.name, manifest.GROUND_TRUTH.qos)
        # always created (the graph matches the manifest); publishes while external_pose.enabled with output ros|both
        self.pub_external = node.create_publisher(Odometry, manifest.EXTERNAL_ODOMETRY.name, manifest.EXTERNAL_ODOMETRY.qos)
        self.external_msg = Odometry()
        self.external_msg.header.frame_id, self.external_msg.child_frame_id = ext["frame_id"], "base_link"
        self.pub_link = node.create_publisher(DiagnosticStatus, manifest.ACTUATOR_LINK.name, manifest.ACTUATOR_LINK.qos)
        # both exist without a world too (the graph matches the manifest); they publish only with one
        self.pub_scan = node.create_publisher(LaserScan, manifest.SCAN.name, manifest.SCAN.qos)
        self.pub_obstacles = node.create_publisher(Surroundings, manifest.SIM_OBSTACLES.name, manifest.SIM_OBSTACLES.qos)
        self.obstacles_msg: Surroundings | None = None  # built at the first publication
        self.link = ActuatorLinkMonitor()
        self.next_link_report = time.monotonic() + 1.0
        self.drainer = Drainer(node)
        # serialized take and publication on the 500 Hz paths (c4d_ros.cdr: ~1 µs instead of ~40 µs per message)
        self.drainer.subscription(ActuatorCommand, manifest.ACTUATORS.name, self.on_actuators, manifest.ACTUATORS.qos,
                                  raw=True)
        self.imu_frame = cdr.text("base_link")
        gyro_var, accel_var = config.sensors.gyro_noise ** 2, config.sensors.accel_noise ** 2
        self.imu_orientation = (0.0, 0.0, 0.0, 0.0, -1.0) + (0.0,) * 8  # no orientation estimate in this message
        self.imu_gyro_cov = (gyro_var, 0.0, 0.0, 0.0, gyro_var, 0.0, 0.0, 0.0, gyro_var)
        self.imu_accel_cov = (accel_var, 0.0, 0.0, 0.0, accel_var, 0.0, 0.0, 0.0, accel_var)
        self.drainer.adopt_node_services()  # fault injection via the parameter services, no executor needed
        tasks = dict(zip(("physics", *SENSOR_TASKS), (self.sim.physics, self.imu, self.gps, self.baro, self.mag,
                                                      self.range_down, self.battery, self.truth), strict=True))
        extra_rates = {"external_pose": settings.rate_hz}
        extra_rates.update({"scan": self.lidar_config.rate_hz, "obstacles": OBSTACLES_RATE_HZ} if world else {})
        tasks.update({"external_pose": self.external_pose})
        tasks.update({"scan": self.scan, "obstacles": self.obstacles} if world else {})
        schedule = build_schedule(1_000_000 // config.physics_rate_hz, "gcdplus", task_specs(config, extra_rates))
        clock: Clock = MonotonicClock(spin_ns=0)
        if lockstep["lockstep"]:  # simulated time: the executive's clock waits for the core (lockstep_sim)
            self.lockstep = lockstep_sim.SimLockstep(node, 1.0 / config.sensors.imu_rate_hz, lockstep["lockstep_timeout_s"],
                                                     lockstep["lockstep_pause_at_s"], lambda: self.drain(-1))
            clock = self.lockstep.clock
            self.sim.now, self.sim.anchor_epoch = (lambda: self.plant.state.t), False
        # plain sleeps (no spinning): the plant needs real time, not µs release precision
        # a sensor keeps sampling whatever the simulator's lateness: samples whose tick was skipped after
        # a stall are produced (late, once) at the next tick instead of vanishing — otherwise a 10 Hz
        # battery could fall silent for 0.7 s on a loaded machine and the health monitor would declare
        # the sim dead (physics simulates every skipped step itself and samples the IMU at each of its
        # periods: the imu task then publishes every sample with its own stamp, Simulation.imu)
        self.executive = CyclicExecutive(schedule, tasks, clock, name="sim", input_phase=self.drain,
                                         output_phase=self.step_done if self.lockstep else None,
                                         report_period_s=3600, manage_gc=True,
                                         catch_up={*SENSOR_TASKS, *extra_rates})

    def external_pose(self, k: int) -> None:
        """The external-pose emulator: a sample of the truth now; the samples whose latency has passed go out
        as navigation/external/odometry and/or VISION_POSITION_ESTIMATE."""
        emulator, state = self.external, self.plant.state
        emulator.sample(state)
        for sample in emulator.due(state.t):
            if self.external_ros:
                self.publish_external(sample)
            if self.vision is not None:
                self.vision.send(mavlink_vision_position(sample, self.sim.wall_epoch))

    def publish_external(self, sample: ExternalPoseSample) -> None:
        """nav_msgs/Odometry in the source's frame, child base_link: pose covariance = the emulated noise, twist
        (body velocity, angular rate) in base_link."""
        m = self.external_msg  # one message, refilled (publish serialises it at once): ~10 µs less per sample
        m.header.stamp = self.stamp(sample.stamp)
        pose, twist = m.pose.pose, m.twist.twist
        pose.position.x, pose.position.y, pose.position.z = sample.position
        pose.orientation.w, pose.orientation.x, pose.orientation.y, pose.orientation.z = sample.orientation
        twist.linear.x, twist.linear.y, twist.linear.z = sample.velocity_body
        twist.angular.x, twist.angular.y, twist.angular.z = sample.angular_velocity
        sp, so, sv = sample.sigma_position ** 2, sample.sigma_orientation ** 2, sample.sigma_velocity ** 2
        m.pose.covariance = diagonal_6x6((sp, sp, sp, so, so, so))
        m.twist.covariance = diagonal_6x6((sv, sv, sv, SIGMA_FLOOR_RAD ** 2, SIGMA_FLOOR_RAD ** 2, SIGMA_FLOOR_RAD ** 2))
        self.pub_external.publish(m)

    def scan(self, k: int) -> None:
        """sensors/scan: the lidar rendered at the vehicle's true position and heading."""
        assert self.lidar is not None
        s, cfg = self.plant.state, self.lidar_config
        x, y, z = s.position
        ranges = self.lidar.scan(x, y, z, quat.yaw_of(s.orientation), s.t)
        m = LaserScan()
        m.header.stamp, m.header.frame_id = self.stamp(s.t), "base_link"
        m.angle_min, m.angle_increment = cfg.angle_min, cfg.increment
        m.angle_max = cfg.angle_min + cfg.increment * (cfg.beams - 1)
        m.time_increment, m.scan_time = 0.0, 1.0 / cfg.rate_hz  # rendered at one instant
        m.range_min, m.range_max = cfg.range_min, cfg.range_max
        m.ranges = array.array("f", ranges.tobytes())  # array('f'): no per-element check or copy in Python
        self.pub_scan.publish(m)

    def obstacles(self, k: int) -> None:
        """sim/obstacles: the world's true obstacles (bounding circles) and the wind in force. The message
        is built once; each publication updates the stamp, ages, movers and wind (50 fresh Obstacle
        messages cost ~0.3 ms of the sim's tick)."""
        world = self.sim.world
        assert world is not None
        t = self.plant.state.t
        m = self.obstacles_msg
        if m is None:
            m = self.obstacles_msg = Surroundings()
            m.header.frame_id, m.wind_valid, m.wind_std = "map", True, 0.0
            for o in truth(world, t):
                ob = Obstacle(id=o.id, radius=o.radius, height=o.height, confidence=1.0)
                ob.position.x, ob.position.y, ob.position.z = o.x, o.y, 0.5 * o.height
                m.obstacles.append(ob)
        m.header.stamp = self.stamp(t)
        for ob, mover in zip(m.obstacles[len(m.obstacles) - len(world.movers):], world.movers, strict=True):
            (ob.position.x, ob.position.y), (ob.velocity.x, ob.velocity.y) = mover.state(t)
        for ob in m.obstacles:
            ob.age = t  # they exist since the world was loaded (simulated t = 0)
        m.wind.x, m.wind.y, m.wind.z = self.plant.wind
        self.pub_obstacles.publish(m)

    def on_parameters(self, params: list[Any]) -> SetParametersResult:
        for p in params:
            if p.name == "lockstep_pause_at_s" and self.lockstep:
                self.lockstep.set_pause(p.value)
                self.node.get_logger().info(f"lockstep: pause at t = {p.value:g} s")
            if p.name.startswith(EXTERNAL):
                reason = self.external.set(p.name.removeprefix(EXTERNAL), p.value)
                if reason:
                    return SetParametersResult(successful=False, reason=reason)
                self.node.get_logger().info(f"{p.name} = {p.value}")
            if not p.name.startswith(FAULT):
                continue
            reason = self.sim.set_fault(p.name.removeprefix(FAULT), p.value)
            if reason:
                return SetParametersResult(successful=False, reason=reason)
            self.node.get_logger().info(f"fault {p.name.removeprefix(FAULT)} = {p.value}")
        return SetParametersResult(successful=True)

    def on_actuators(self, raw: bytes) -> None:
        v = cdr.ACTUATOR_COMMAND.unpack(raw, ActuatorCommand)  # 0 CDR, 1-2 stamp, 3-4 frame, 5 armed, 6 n, outputs
        sec, nanosec = v[1], v[2]
        self.sim.command(v[7:7 + v[6]], v[5])
        if self.lockstep:
            self.lockstep.on_command(sec, nanosec)
        self.link.on_command(sec + nanosec * 1e-9)

    def drain(self, k: int) -> None:
        self.drainer.drain()
        now = time.monotonic()
        if now >= self.next_link_report:
            self.next_link_report = now + 1.0
            self.publish_link_report()

    def publish_link_report(self) -> None:
        """The sim's diagnostics (1 Hz): command gaps as received, and whether the simulated IMU kept its
        rate: samples published late (catch-up after a stall) or dropped (the sim fell too far behind: WARN)."""
        r, imu = self.link.report(), self.sim.imu
        m = DiagnosticStatus(level=DiagnosticStatus.WARN if imu.dropped else DiagnosticStatus.OK, name="sim/actuator_link",
                             hardware_id="sim", message=f"worst gap {r.max_gap_ms:.1f} ms, {r.long_gaps_total} gap(s) > 20 ms; "
                                                        f"IMU {imu.late} late, {imu.dropped} dropped")
        m.values = [KeyValue(key=key, value=f"{value:g}") for key, value in (
            ("messages", r.messages_total), ("window_max_gap_ms", r.window_max_gap_ms), ("max_gap_ms", r.max_gap_ms),
            ("p999_gap_ms", r.p999_gap_ms), ("gaps_over_20ms", r.long_gaps_total), ("imu_samples", imu.sampled),
            ("imu_late", imu.late), ("imu_dropped", imu.dropped), ("overruns", self.executive.profiler.overruns_total))]
        if self.lockstep:  # the step reached, and whether the sim holds there (answered, paused)
            m.values += [KeyValue(key=key, value=value) for key, value in self.lockstep.report()]
        self.pub_link.publish(m)

    def step_done(self, k: int) -> None:
        """Lockstep output phase: a tick whose IMU task ran ends a step (declared, /clock published)."""
        assert self.lockstep is not None
        if any(task.name == "imu" for task in self.executive.due(k)):
            self.lockstep.step_done(self.plant.state.t)

    def stamp(self, t: float):
        return s_to_stamp(self.sim.wall_epoch + t)

    def imu(self, k: int) -> None:
        """Publish every IMU sample taken since the last call (more than one after a stall), each with its stamp."""
        for sample in self.sim.imu.take(self.sim.present()):  # none before its stamp (honest stamps)
            self.publish_imu(sample)

    def publish_imu(self, sample: ImuSample) -> None:
        """One sensor_msgs/Imu, written straight to CDR (c4d_ros.cdr)."""
        frame = self.imu_frame
        self.pub_imu.publish(cdr.IMU.pack(
            frame[:1], *cdr.split_stamp(self.sim.wall_epoch + sample.stamp), *frame, *self.imu_orientation,
            *sample.gyro, *self.imu_gyro_cov, *sample.accel, *self.imu_accel_cov))

    def gps(self, k: int) -> None:
        for g in self.sim.gps_fixes():
            m = NavSatFix()
            m.header.stamp, m.header.frame_id = self.stamp(g.stamp), "gps"
            m.status.status, m.status.service = NavSatStatus.STATUS_FIX, NavSatStatus.SERVICE_GPS
            m.latitude, m.longitude, m.altitude = g.latitude, g.longitude, g.altitude
            m.position_covariance = [g.sigma_h**2, 0.0, 0.0, 0.0, g.sigma_h**2, 0.0, 0.0, 0.0, g.sigma_v**2]
            m.position_covariance_type = NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
            self.pub_gps.publish(m)

    def baro(self, k: int) -> None:
        sample = self.suite.baro(self.plant.state)
        if sample is not None:
            m = FluidPressure()
            m.header.stamp, m.header.frame_id = self.stamp(sample[0]), "base_link"
            m.fluid_pressure, m.variance = sample[1], (12.0 * self.sensors.baro_noise) ** 2
            self.pub_baro.publish(m)

    def mag(self, k: int) -> None:
        state = self.plant.state
        sample = self.suite.mag(state)
        if sample is not None:
            m = MagneticField()
            m.header.stamp, m.header.frame_id = self.stamp(state.t), "base_link"
            m.magnetic_field.x, m.magnetic_field.y, m.magnetic_field.z = sample
            self.pub_mag.publish(m)

    def range_down(self, k: int) -> None:
        state = self.plant.state
        sample = self.suite.range_down(state)
        if sample is not None:
            m = Range()
            m.header.stamp, m.header.frame_id = self.stamp(state.t), "range_down"
            m.radiation_type, m.field_of_view, m.min_range = Range.INFRARED, 0.05, RANGE_MIN
            m.max_range = self.sensors.range_max
            m.range = sample
            self.pub_range.publish(m)

    def battery(self, k: int) -> None:
        sc = self.sensors
        b = self.suite.battery(self.plant.state, 1.0 / sc.battery_rate_hz)
        m = BatteryState()
        m.header.stamp = self.stamp(b.stamp)
        m.voltage, m.current, m.charge = b.voltage, -b.current, b.charge_ah  # ROS: negative while discharging
        m.capacity = m.design_capacity = sc.battery_capacity_ah
        m.percentage = b.percentage
        m.power_supply_status = BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
        m.power_supply_technology = BatteryState.POWER_SUPPLY_TECHNOLOGY_LIPO
        m.present = True
        m.cell_voltage = [b.voltage / sc.battery_cells] * sc.battery_cells
        self.pub_battery.publish(m)

    def truth(self, k: int) -> None:
        s = self.plant.state
        m = Odometry()
        m.header.stamp, m.header.frame_id, m.child_frame_id = self.stamp(s.t), "map", "base_link"
        m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.position.z = s.position
        q = s.orientation
        m.pose.pose.orientation.w, m.pose.pose.orientation.x, m.pose.pose.orientation.y, m.pose.pose.orientation.z = q
        m.twist.twist.linear.x, m.twist.twist.linear.y, m.twist.twist.linear.z = s.velocity  # world frame (documented)
        m.twist.twist.angular.x, m.twist.twist.angular.y, m.twist.twist.angular.z = s.angular_velocity
        self.pub_truth.publish(m)

    def run(self) -> int:
        """Run the executive until SIGINT/SIGTERM or a lifecycle deactivate (executive.stop()); 0."""
        executive, log = self.executive, self.node.get_logger()
        def stop(signum, frame) -> None:
            executive.stop()
            if self.lockstep:
                self.lockstep.clock.interrupt()  # a held sim stops too

        signal.signal(signal.SIGINT, stop)
        signal.signal(signal.SIGTERM, stop)
        cfg = self.sim.config
        log.info(f"sim: {cfg.airframe.name} at {cfg.origin}, physics {cfg.physics_rate_hz} Hz, "
                 f"IMU {self.sensors.imu_rate_hz:.0f} Hz, GNSS {self.sensors.gps_rate_hz:.0f} Hz")
        if self.sim.world:
            w, lc = self.sim.world, self.lidar_config
            log.info(f"sim: world '{w.name}': {w.obstacle_count} obstacle(s) ({len(w.movers)} moving), wind "
                     f"{self.sim.wind_field.mean} m/s; lidar {lc.beams} beams at {lc.rate_hz:g} Hz, max {lc.range_max:g} m")
        node_runtime.apply_rt_priority(self.rt_priority, log)
        if self.lockstep:
            log.info(f"sim: LOCKSTEP — simulated time (/clock) advances only when the core answers each "
                     f"{1e3 / self.sensors.imu_rate_hz:g} ms step")
            executive.start(t0_ns=0)
        else:  # simulated t = 0 on a whole IMU period of CLOCK_MONOTONIC: the core ticks at a fixed phase to the samples
            tick_ns, imu_ns = executive.tick_ns, round(1e9 / self.sensors.imu_rate_hz)
            executive.start(t0_ns=grid_start_ns(time.monotonic_ns(), tick_ns, imu_ns))
        try:
            executive.run()
        finally:
            executive.release_gc()
            imu = self.sim.imu
            log.info(f"sim stopped at t = {self.plant.state.t:.1f} s; overruns {executive.profiler.overruns_total}; "
                     f"IMU {imu.sampled} samples, {imu.late} late, {imu.dropped} dropped")
            if self.lockstep:
                log.info(self.lockstep.summary())
        return 0


def main(argv: list[str] | None = None) -> int:
    rclpy = node_runtime.init(argv)
    try:
        node = lifecycle.create_node(rclpy, "sim")  # a managed node (c4d_ros.lifecycle, docs/lifecycle.md)
    except ComponentError as exc:
        return node_runtime.fail("sim", str(exc))

    def configure() -> SimNode:  # lifecycle configure: sim config and world loaded and checked, entities created
        config = read_config(node)
        world, lidar = read_world(node, config.physics_rate_hz)
        return SimNode(node, config, read_rt_priority(node), world, lidar)
    return lifecycle.LoopWork(node, configure, (SimConfigError, WorldError, ParameterError),
                              stop=lambda owner: owner.executive.stop()).run("sim")


if __name__ == "__main__":
    sys.exit(main())
