"""The simulated vehicle in real time, free of ROS: plant, sensors, faults, motor command, schedule.

Why here and not in the node: what the simulator does each physics tick (wind and gust, every
skipped step simulated after a stall so simulated time stays wall time, an IMU sample taken every
IMU period of those steps so the IMU keeps its rate and stamps, the ESC failsafe), how a
fault setting is applied or refused, and which executive task runs at which divider are the
simulator's behaviour; the node only maps them to topics and parameters. All of it is testable
without DDS.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from c4d_sched.tickschedule import TaskSpec

from .plant import MultirotorPlant
from .sensors import GPS_DELAY_MAX_S, Faults, GpsSample, ImuSample, SensorSuite
from .sim_config import SimConfig, SimConfigError
from .world import WindField, World

ESC_TIMEOUT_S = 0.2  # without a motor command for this long the ESCs stop the motors
IMU_MAX_BACKLOG_S = 0.1  # IMU samples older than this when the sim catches up are dropped (and counted)
SENSOR_TASKS = ("imu", "gps", "baro", "mag", "range", "battery", "truth")  # executive tasks after "physics"
WORLD_TASK_BUDGET_US = 400  # scan / sim/obstacles task budget (bench/lidar_raycast.py: p99 of a 720-beam scan of 50 obstacles)
# external-pose task (sample + Odometry and/or a MAVLink frame), bench/sim_external_pose.py: p99 in the running sim
# on the loaded 2-core VM ~370 µs with output ros, ~540 µs with both (hot in-process: ~35 µs ros, ~15 µs MAVLink)
EXTERNAL_POSE_BUDGET_US = 400
BOOL_FAULTS = frozenset({"imu_dropout", "imu_freeze", "gps_loss", "baro_dropout", "baro_freeze", "mag_dropout",
                         "range_dropout"})
GPS_NUMBER_FAULTS = {"gps_delay_s": (0.0, GPS_DELAY_MAX_S), "gps_jam_dropout": (0.0, 1.0),
                     "gps_jam_sigma_factor": (1.0, 1000.0)}  # fault → its [low, high]


@dataclass
class ImuBacklog:
    """IMU samples on the sensor's own clock, queued until the node publishes them.

    Why: a real IMU delivers every sample at its rate whatever its host does. The simulator's
    process is sometimes late (a stall on a busy 2-core machine); it then steps the plant through
    the skipped ticks and samples the IMU every IMU period of them, so each sample has its own
    stamp and its own filtered interval, and the node publishes the backlog at once (catch-up).
    Bounded: beyond `max_samples` the oldest are dropped and counted, so the sim says when it could
    not keep up (sim diagnostics) instead of silently slowing down.
    """

    max_samples: int
    pending: deque[ImuSample] = field(default_factory=deque)
    sampled: int = 0  # samples taken (dropout fault: none)
    late: int = 0  # published after a newer sample was already due (catch-up after a stall)
    dropped: int = 0  # beyond the backlog bound: never published

    def add(self, sample: ImuSample) -> None:
        self.sampled += 1
        self.pending.append(sample)
        if len(self.pending) > self.max_samples:
            self.pending.popleft()
            self.dropped += 1

    def take(self, until: float = math.inf) -> list[ImuSample]:
        """The queued samples stamped at or before `until` [s, simulated], oldest first; all but the
        newest count as late. Why `until`: the plant is stepped a physics period ahead of the tick
        that steps it, so after a stall the newest sample of the catch-up can lie in the future;
        it waits for its time (a real IMU never delivers a sample before measuring it)."""
        pending, out = self.pending, []
        while pending and pending[0].stamp <= until:
            out.append(pending.popleft())
        self.late += max(0, len(out) - 1)
        return out


class Simulation:
    """Plant + sensor suite + faults, stepped by `physics(k)` once per executive tick k.

    `tick0_ns()` returns the monotonic deadline of tick 0 (the executive's t0_ns); it is read at
    the first tick to anchor simulated t = 0 to wall-clock time (`wall_epoch`), so sensor stamps
    are wall times. Motor commands arrive through `command()`; one older than ESC_TIMEOUT_S
    (monotonic clock) leaves the motors unpowered.
    """

    def __init__(self, config: SimConfig, tick0_ns: Callable[[], int | None], world: World | None = None) -> None:
        self.config = config
        self.world = world  # obstacles (lidar, sim/obstacles) and, when it has one, the wind field
        self.wind_field = world.wind if world and world.wind else WindField(config.wind_mean, config.gust, config.gust_period)
        self.motors = len(config.airframe.motors)
        self.plant = MultirotorPlant(config.airframe, (0.0, 0.0, 0.0), config.yaw)
        self.faults = Faults()
        self.suite = SensorSuite(config.sensors, config.origin, seed=config.seed, faults=self.faults)
        self.extra_gust = 0.0  # [m/s] fault: added to the configured gust amplitude
        self.outputs: list[float] = [0.0] * self.motors
        self.armed = False
        self.command_t = -math.inf  # time of the last motor command on `now`
        self.now: Callable[[], float] = time.monotonic  # clock of the ESC timeout; simulated time in lockstep
        self.wall_epoch = 0.0  # wall-clock time of simulated t = 0, fixed at the first physics tick
        self.anchor_epoch = True  # False (lockstep): stamps are simulated time + wall_epoch as set by the node
        self.gps_pending: deque[GpsSample] = deque()  # measured, waiting for the GNSS latency
        self._tick0_ns = tick0_ns
        self._dt = 1.0 / config.physics_rate_hz
        self._last_tick = -1
        self._steps = 0
        self._imu_divider = max(1, round(config.physics_rate_hz / config.sensors.imu_rate_hz))
        self.imu = ImuBacklog(max(1, round(IMU_MAX_BACKLOG_S * config.sensors.imu_rate_hz)))

    def command(self, outputs: Sequence[float], armed: bool) -> None:
        """A motor command (one output per motor in [0, 1]); ignored when the count is wrong."""
        if len(outputs) == self.motors:
            self.outputs, self.armed, self.command_t = list(outputs), armed, self.now()

    def physics(self, k: int) -> None:
        """Executive task: advance the plant to tick k (ticks skipped after a stall are simulated too),
        sampling the IMU at each IMU period of the steps (stamps on the IMU's own 1/rate grid)."""
        plant = self.plant
        if self._last_tick < 0 and self.anchor_epoch:  # anchor simulated t = 0 to the wall-clock time of tick 0's deadline
            self.wall_epoch = time.time() - (time.monotonic_ns() - (self._tick0_ns() or 0)) / 1e9 - plant.state.t
        fresh = self.now() - self.command_t < ESC_TIMEOUT_S
        plant.wind = self.wind_field.at(plant.state.t, self.extra_gust)
        imu_dt = self._dt * self._imu_divider
        for _ in range(k - self._last_tick):  # every skipped tick is simulated: sim time stays wall time
            plant.step(self._dt, self.outputs, self.armed and fresh)
            self._steps += 1
            if self._steps % self._imu_divider == 0:  # the IMU samples on its own clock, late or not
                sample = self.suite.imu(plant.state, imu_dt)
                if sample is not None:
                    self.imu.add(sample)
        self._last_tick = k

    def present(self) -> float:
        """Simulated time of this instant: what a sample's stamp may not exceed when it is published
        (real time: monotonic time since tick 0's deadline, which is simulated t = 0 — immune to wall-clock
        steps; lockstep: no bound, simulated time is the present)."""
        if not self.anchor_epoch:
            return math.inf
        return (time.monotonic_ns() - (self._tick0_ns() or 0)) / 1e9

    def gps_fixes(self) -> list[GpsSample]:
        """Sample the GNSS receiver when due; return the fixes whose latency has passed, oldest first."""
        sample = self.suite.gps(self.plant.state, 1.0 / self.config.sensors.gps_rate_hz)
        pending = self.gps_pending
        if sample is not None:
            pending.append(sample)
        due, latency, now = [], self.config.sensors.gps_latency_s, self.plant.state.t + 1e-9
        while pending and pending[0].stamp + latency <= now:
            due.append(pending.popleft())
        return due

    def set_fault(self, name: str, value: Any) -> str | None:
        """Apply fault `name` (without the 'fault.' prefix); return the reason when refused."""
        if name == "motor_health":
            values = list(value)
            if len(values) != self.motors or not all(0.0 <= v <= 1.0 for v in values):
                return f"motor_health needs {self.motors} values in [0, 1]"
            self.plant.motor_health = [float(v) for v in values]
        elif name in ("gps_drift_m_s", "gps_jump_m"):
            values = [float(v) for v in value]
            if len(values) != 3 or not all(math.isfinite(v) for v in values):
                return f"{name} needs 3 finite values [e, n, u]"
            setattr(self.faults, "gps_drift" if name == "gps_drift_m_s" else "gps_jump", (values[0], values[1], values[2]))
            if name == "gps_drift_m_s" and not any(values):  # the spoofing ends: fixes return to the truth
                self.suite.drift = [0.0, 0.0, 0.0]
        elif name in GPS_NUMBER_FAULTS:
            low, high = GPS_NUMBER_FAULTS[name]
            if not low <= float(value) <= high:
                return f"{name} must be in [{low:g}, {high:g}]"
            setattr(self.faults, name, float(value))
        elif name == "wind_gust_m_s":
            self.extra_gust = float(value)
        elif name == "battery_drain_factor":
            if float(value) < 0:
                return "battery_drain_factor must be >= 0"
            self.faults.battery_drain_factor = float(value)
        elif name in BOOL_FAULTS:
            setattr(self.faults, name, bool(value))
        else:
            return f"unknown fault '{name}'"
        return None


def task_specs(config: SimConfig, extra_rates: dict[str, float] | None = None) -> list[TaskSpec]:
    """The executive's tasks: physics first in the input class, then the sensors at their rates,
    then `extra_rates` (the external-pose emulator: {"external_pose": rate}; with a world also
    {"scan": lidar rate, "obstacles": truth rate}).

    Raises SimConfigError when a rate does not divide the physics rate."""
    rate, sc = config.physics_rate_hz, config.sensors
    rates = {"imu": sc.imu_rate_hz, "gps": sc.gps_rate_hz, "baro": sc.baro_rate_hz, "mag": sc.mag_rate_hz,
             "range": sc.range_rate_hz, "battery": sc.battery_rate_hz, "truth": config.truth_rate_hz,
             **(extra_rates or {})}

    def divider(hz: float) -> int:
        d = round(rate / hz)
        if d < 1 or abs(rate / d - hz) > 1e-6 * hz:
            raise SimConfigError(f"sim config: a {hz} Hz rate does not divide the physics rate {rate} Hz")
        return d

    budgets = {"scan": WORLD_TASK_BUDGET_US, "obstacles": WORLD_TASK_BUDGET_US, "external_pose": EXTERNAL_POSE_BUDGET_US}
    return [TaskSpec("physics", "input", 1, 50, 0)] + [TaskSpec(name, "telemetry", divider(rates[name]),
                                                                budgets.get(name, 30), None)
                                                       for name in (*SENSOR_TASKS, *(extra_rates or {}))]
