"""Deterministic closed loop: plant + GNC core + the real cyclic executive on a fake clock.

Why: control performance must be tested at full speed and bit-for-bit reproducibly. This
harness runs exactly what the `core` node runs — the same GncCore tasks, the same
GCD+-phased TickSchedule, the same CyclicExecutive — but the clock is simulated and the
plant is stepped between ticks. The input phase samples the plant's true state with seeded
Gaussian noise (a stand-in for the estimator's output until the navigation node exists).
"""

from __future__ import annotations

import math
import random
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from c4d_common import quat
from c4d_common.airframe import Airframe
from c4d_gnc.gnc import Command, GncCore, Request, StateSample
from c4d_sched.executive import CyclicExecutive, FakeClock
from c4d_sched.tickschedule import schedule_from_config
from c4d_sim.plant import MultirotorPlant


@dataclass(frozen=True)
class Noise:
    position: float = 0.02  # [m] σ
    velocity: float = 0.03  # [m/s] σ
    attitude: float = math.radians(0.2)  # [rad] σ per axis
    gyro: float = 0.01  # [rad/s] σ


NO_NOISE = Noise(0.0, 0.0, 0.0, 0.0)
DEFAULT_NOISE = Noise()


@dataclass
class Trace:
    t: list[float] = field(default_factory=list)
    position: list[tuple[float, float, float]] = field(default_factory=list)
    orientation: list[quat.Quat] = field(default_factory=list)
    commands: list[tuple[float, ...]] = field(default_factory=list)
    mode: list[int] = field(default_factory=list)


class ClosedLoop:
    def __init__(
        self,
        airframe: Airframe,
        executive_config: Mapping,
        noise: Noise = DEFAULT_NOISE,
        seed: int = 0,
        plant_substeps: int = 2,
        phase_method: str | None = None,
        extra_tasks: Mapping[str, Callable[[int], None]] | None = None,
        start_position: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> None:
        self.schedule = schedule_from_config(executive_config, phase_method)
        self.tick_s = self.schedule.tick_us / 1e6
        self.plant = MultirotorPlant(airframe, start_position)
        self.core = GncCore(airframe, self.tick_s)
        self.noise = noise
        self.rng = random.Random(seed)
        self.substeps = plant_substeps
        self.clock = FakeClock()
        self.trace = Trace()
        self.record_every = 1
        self.position_lost_at: float | None = None  # set to a time to simulate GNSS loss from then on
        self.range_lost = False  # no range finder reading (touchdown must be found from the velocity)
        self.input_hook: Callable[[float], None] | None = None  # called each input phase with the time (extra inputs)
        core_functions = self.core.task_functions()
        functions: dict[str, Callable[[int], None]] = {}
        for task in self.schedule.tasks:
            dt = task.divider * self.tick_s
            if task.name in core_functions:
                fn = core_functions[task.name]
                functions[task.name] = lambda k, fn=fn, dt=dt: fn(dt)
            elif extra_tasks and task.name in extra_tasks:
                functions[task.name] = extra_tasks[task.name]
            elif task.name == "status":
                functions[task.name] = lambda k: None
            else:
                raise ValueError(f"no function for task '{task.name}'")
        self.executive = CyclicExecutive(self.schedule, functions, self.clock, name="closed_loop",
                                         input_phase=self._input, latch=lambda k: self.core.latch(),
                                         output_phase=self._output, report_period_s=3600)
        self.executive.start(t0_ns=0)
        self._input(0)

    @property
    def t(self) -> float:
        return self.plant.state.t

    def _noisy(self, v, sigma):
        g = self.rng.gauss
        return tuple(x + g(0.0, sigma) for x in v) if sigma else tuple(v)

    def _input(self, k: int) -> None:
        s, n = self.plant.state, self.noise
        now = k * self.tick_s
        q = s.orientation
        if n.attitude:
            g = self.rng.gauss
            q = quat.mul(q, quat.from_euler(g(0, n.attitude), g(0, n.attitude), g(0, n.attitude)))
        position, velocity = self._noisy(s.position, n.position), self._noisy(s.velocity, n.velocity)
        if self.position_lost_at is not None:  # GNSS lost: dead-reckoned xy drifts at 0.5 m/s, z stays baro-aided
            drift = 0.5 * (now - self.position_lost_at)
            position = (position[0] + drift, position[1], position[2])
            velocity = (velocity[0] + 0.5, velocity[1], velocity[2])
        state = StateSample(now, position, velocity, q, self._noisy(s.angular_velocity, n.gyro),
                            valid_position=self.position_lost_at is None, valid_velocity=self.position_lost_at is None,
                            terrain_distance=math.nan if self.range_lost else s.position[2])
        inputs = self.core.inputs
        inputs.now, inputs.state = now, state
        inputs.gyro, inputs.gyro_stamp = state.angular_velocity, now
        if self.input_hook is not None:
            self.input_hook(now)

    def _output(self, k: int) -> None:
        out = self.core.out
        dt = self.tick_s / self.substeps
        for _ in range(self.substeps):
            self.plant.step(dt, out.commands, out.armed)
        if k % self.record_every == 0:
            tr, s = self.trace, self.plant.state
            tr.t.append(s.t)
            tr.position.append(s.position)
            tr.orientation.append(s.orientation)
            tr.commands.append(out.commands)
            tr.mode.append(int(out.mode))

    def command(self, request: Request) -> None:
        ok, reason = self.core.request(request)
        if not ok:
            raise RuntimeError(reason)

    def run(self, seconds: float) -> None:
        self.executive.run(max_ticks=round(seconds / self.tick_s))

    def run_until(self, predicate: Callable[[], bool], timeout: float) -> bool:
        end = self.t + timeout
        while self.t < end:
            self.executive.step()
            if predicate():
                return True
        return False

    def take_off(self, altitude: float, timeout: float = 20.0) -> None:
        self.command(Request(Command.TAKEOFF, altitude=altitude))
        if not self.run_until(lambda: self.core.out.nav.name == "HOLD", timeout):
            raise RuntimeError(f"take-off to {altitude} m did not complete in {timeout} s")
