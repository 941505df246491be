"""The simulator's lockstep mode (parameter `lockstep`): simulated time advances only when the GNC
core has answered the previous step (c4d_sched.lockstep has the protocol and the ROS-free gates).

What the sim does in lockstep, per IMU period (one step, 2 ms at 500 Hz):
- physics and sensors run as in real time, but on a LockstepClock: the executive's next tick waits
  until the actuator command computed from the step has been taken (stamp ≥ the step's time);
- after the IMU task of a tick it declares the step (time = the newest IMU sample's grid time,
  whether a dropout fault suppressed the sample or not) and publishes /clock (rosgraph_msgs/Clock)
  with it: the core ticks on it, nodes with `use_sim_time` follow it;
- stamps are simulated time (t = 0 at start, like Gazebo), never wall time, so two runs of the same
  scenario are the same bit for bit; the ESC timeout counts simulated time.
While waiting it keeps draining (commands, parameter services) and repeats /clock every 0.5 s of
wall time (late joiners, e.g. a core started after the sim, learn which step is pending).
A chain that never answers (dead or real-time core): after `lockstep_timeout_s` of wall time an
error names the step and what is missing, repeated at that period; the sim holds (never falls back
to real time: a lockstep run is either deterministic or visibly stuck). `lockstep_pause_at_s`
(settable at run time) holds the sim after the first step at or past that simulated time, so a test
issues commands that land at a known tick, then raises it.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from c4d_ros.params import Spec
from c4d_sched.lockstep import LockstepClock, StepGate, pause_ns, step_time_ns

CLOCK_REPEAT_S = 0.5

PARAMS = {
    "lockstep": Spec(False, "lockstep mode: simulated time advances only when the core answered the previous step "
                            "(deterministic; /clock published); false = real time [bool]", read_only=True),
    "lockstep_timeout_s": Spec(5.0, "lockstep: wall time without the awaited command before an error is logged "
                                    "(repeated; the sim holds) [s]", 0.1, 3600.0, read_only=True),
    "lockstep_pause_at_s": Spec(-1.0, "lockstep: hold after the first step at or past this simulated time, until "
                                      "raised (settable at run time); negative = never [s]", -1.0, 1e9),
}


class SimLockstep:
    """Clock, gate and /clock publisher of a lockstep sim; `poll` drains the node while it waits."""

    def __init__(self, node, imu_period_s: float, timeout_s: float, pause_at_s: float, poll: Callable[[], object]) -> None:
        from rosgraph_msgs.msg import Clock

        from c4d_ros.manifest import CLOCK

        self.node, self.log, self.imu_period_s = node, node.get_logger(), imu_period_s
        self._poll = poll
        self.gate = StepGate(pause_ns(pause_at_s))
        self.clock = LockstepClock(self.gate, self.poll, self.on_stall, report_s=timeout_s)
        self.msg = Clock()
        self.pub_clock = node.create_publisher(Clock, CLOCK.name, CLOCK.qos)
        self.next_repeat = 0.0
        self.holding = False

    def set_pause(self, pause_at_s: float) -> None:
        self.gate.pause_at_ns = pause_ns(pause_at_s)
        self.holding = False

    def poll(self) -> None:
        self._poll()
        now = time.monotonic()
        if now >= self.next_repeat:
            self.publish_clock()

    def on_command(self, sec: int, nanosec: int) -> None:
        self.gate.on_command(sec * 1_000_000_000 + nanosec)

    def step_done(self, t_s: float) -> None:
        """After a tick whose IMU task ran, with the plant at simulated time t_s: declare the step, publish /clock."""
        if self.gate.declare(step_time_ns(t_s, self.imu_period_s)):
            self.publish_clock()

    def publish_clock(self) -> None:
        t = max(self.gate.last_step, 0)
        self.msg.clock.sec, self.msg.clock.nanosec = divmod(t, 1_000_000_000)
        self.pub_clock.publish(self.msg)
        self.next_repeat = time.monotonic() + CLOCK_REPEAT_S

    def on_stall(self, deadline_ns: int, missing: tuple[str, ...], waited_s: float) -> bool:
        """Holding: paused is said once; a missing command is an error, repeated; never give up."""
        t = self.gate.last_step / 1e9
        if missing == ("paused",):
            if not self.holding:
                self.log.info(f"lockstep: holding at t = {t:.3f} s (lockstep_pause_at_s)")
                self.holding = True
        else:
            self.log.error(f"lockstep: no actuator command for the step at t = {t:.3f} s after {waited_s:.1f} s; "
                           "the sim holds — is the core running with lockstep: true (and perception/navigation)?")
        return False

    def report(self) -> list[tuple[str, str]]:
        """Diagnostics values: lockstep_t [s] = newest step, lockstep_holding = 1 when answered and paused."""
        gate = self.gate
        return [("lockstep_t", f"{max(gate.last_step, 0) / 1e9:.3f}"), ("lockstep_steps", str(gate.steps)),
                ("lockstep_holding", "1" if gate.missing() == ("paused",) else "0"),
                ("lockstep_stalls", str(self.clock.stalls))]

    def summary(self) -> str:
        return (f"lockstep: {self.gate.steps} steps, {self.gate.matched} answered, {self.clock.stalls} stall report(s), "
                f"t = {max(self.gate.last_step, 0) / 1e9:.3f} s")
