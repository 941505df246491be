#!/usr/bin/env python3
"""Fly a 3-D lemniscate in OFFBOARD from an external ROS 2 node (c4d's public offboard API).

What it does, as any researcher's node would (it imports only rclpy, c4d_interfaces and
standard messages — no c4d Python package):
1. waits for navigation/state to have a position and a home (the estimate is in `map`, ENU,
   origin = home);
2. streams offboard/trajectory_setpoint (c4d_interfaces/GuidanceSetpoint, LEVEL_POSITION) at
   `--rate` Hz: first the lemniscate's start point (`--altitude` above the centre);
3. after >= 1.2 s of streaming asks vehicle/command SET_MODE OFFBOARD (the core accepts it only
   with a stream live for >= 1 s), then ARM: armed in OFFBOARD on the ground with a setpoint
   above, the vehicle takes off and climbs to the start point;
4. once there (navigation/pose within 0.3 m for 1 s), flies `--laps` laps of a lemniscate of
   Gerono (or Bernoulli) `--length` x `--width` m with a `--swing` m altitude swing at
   `--speed` m/s peak, with velocity and acceleration feed-forward; the speed ramps up and down
   smoothly over `--ramp` s, so the setpoint never jumps;
5. asks vehicle/command LAND and exits 0 once the vehicle is disarmed.

If this node stops streaming (crash, Ctrl-C, kill -9), the core holds where the stream went
stale and health's `offboard_loss` failsafe decides what next (default: hold, land after 5 s).

    . ./env.sh && python examples/offboard_lemniscate.py --laps 2 --speed 3
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass

import rclpy
from geometry_msgs.msg import PoseStamped
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from c4d_interfaces.msg import GuidanceSetpoint, VehicleState, VehicleStatus
from c4d_interfaces.srv import VehicleCommand

Vec = tuple[float, float, float]
NAN = float("nan")
SETTLE_RADIUS_M = 0.3  # the start point is reached within this distance ...
SETTLE_S = 1.0  # ... held for this long
MODE_DELAY_S = 1.2  # stream this long before asking for OFFBOARD (the core needs >= 1 s)
RETRY_S = 20.0  # how long a TEMPORARILY_REJECTED command is retried (pre-arm checks, stream not live yet)
BERNOULLI_Y_MAX = math.sqrt(2.0) / 4.0  # max of sin(p)cos(p)/(1+cos^2 p): scales the Bernoulli width to 1


def unit_curve(shape: str, phi: float) -> Vec:
    """The curve at parameter `phi` (one lap = 2 pi) in unit extents: x, y in [-1, 1], z swing in
    [-1, 1]; phi = 0 is the centre crossing."""
    if shape == "gerono":
        return math.sin(phi), math.sin(2.0 * phi), math.sin(phi)
    c, s = math.cos(phi), math.sin(phi)
    return s / (1.0 + c * c), s * c / (1.0 + c * c) / BERNOULLI_Y_MAX, s


@dataclass(frozen=True)
class Sample:
    position: Vec  # [m] map (ENU)
    velocity: Vec  # [m/s]
    acceleration: Vec  # [m/s^2]


class Lemniscate:
    """A lemniscate trajectory in `map` (ROS-free): position, velocity and acceleration at time
    tau [s] from its start. The curve parameter advances at a constant rate chosen so the peak
    speed is `speed`, ramped up from rest and down to rest with a smoothstep over `ramp_s` (the
    acceleration feed-forward includes the ramp's term), and covers exactly `laps` laps."""

    H = 1e-3  # curve parameter step of the numerical derivatives [rad]

    def __init__(self, shape: str, length: float, width: float, swing: float, altitude: float,
                 center: tuple[float, float], speed: float, laps: int, ramp_s: float) -> None:
        self.shape, self.scale = shape, (length / 2.0, width / 2.0, swing / 2.0)
        self.origin = (center[0], center[1], altitude)
        peak = max(self._norm(self._d1(2.0 * math.pi * k / 3600)) for k in range(3600))  # |dp/dphi| max [m/rad]
        self.rate = speed / peak  # [rad/s] at full speed
        self.ramp_s, self.total = ramp_s, 2.0 * math.pi * laps
        self.duration = 2.0 * ramp_s + (self.total - self.rate * ramp_s) / self.rate  # [s]
        if self.total < self.rate * ramp_s:
            raise ValueError(f"--ramp {ramp_s:g} s is longer than the laps allow (at most {self.total / self.rate:.1f} s)")

    @staticmethod
    def _norm(v: Vec) -> float:
        return math.sqrt(v[0] ** 2 + v[1] ** 2 + v[2] ** 2)

    def _p(self, phi: float) -> Vec:
        u = unit_curve(self.shape, phi)
        return (self.origin[0] + self.scale[0] * u[0], self.origin[1] + self.scale[1] * u[1],
                self.origin[2] + self.scale[2] * u[2])

    def _d1(self, phi: float) -> Vec:
        a, b = self._p(phi + self.H), self._p(phi - self.H)
        return (a[0] - b[0]) / (2 * self.H), (a[1] - b[1]) / (2 * self.H), (a[2] - b[2]) / (2 * self.H)

    def _d2(self, phi: float) -> Vec:
        a, m, b = self._p(phi + self.H), self._p(phi), self._p(phi - self.H)
        h2 = self.H * self.H
        return (a[0] - 2 * m[0] + b[0]) / h2, (a[1] - 2 * m[1] + b[1]) / h2, (a[2] - 2 * m[2] + b[2]) / h2

    def phase(self, tau: float) -> tuple[float, float, float]:
        """Curve parameter, its rate and its acceleration at tau (smoothstep ramps at both ends)."""
        w, tr = self.rate, self.ramp_s
        tau = min(max(tau, 0.0), self.duration)
        if tau < tr:
            u = tau / tr
            return w * tr * (u ** 3 - u ** 4 / 2), w * (3 * u * u - 2 * u ** 3), w * (6 * u - 6 * u * u) / tr
        if tau > self.duration - tr:
            u = (self.duration - tau) / tr
            return self.total - w * tr * (u ** 3 - u ** 4 / 2), w * (3 * u * u - 2 * u ** 3), -w * (6 * u - 6 * u * u) / tr
        return w * tr / 2 + w * (tau - tr), w, 0.0

    def start(self) -> Vec:
        return self._p(0.0)

    def at(self, tau: float) -> Sample:
        phi, dphi, ddphi = self.phase(tau)
        d1, d2 = self._d1(phi), self._d2(phi)
        return Sample(self._p(phi), (d1[0] * dphi, d1[1] * dphi, d1[2] * dphi),
                      tuple(d2[i] * dphi * dphi + d1[i] * ddphi for i in range(3)))

    def laps_done(self, tau: float) -> int:
        return int(self.phase(tau)[0] / (2 * math.pi) + 1e-9)


def setpoint(stamp, sample: Sample, yaw_mode: str) -> GuidanceSetpoint:
    """A LEVEL_POSITION GuidanceSetpoint with velocity and acceleration feed-forward; yaw NaN
    (keep) or along the horizontal path (with the turn rate as yaw_rate feed-forward)."""
    msg = GuidanceSetpoint(control_level=GuidanceSetpoint.LEVEL_POSITION)
    msg.header.stamp, msg.header.frame_id = stamp, "map"
    p, v, a = sample.position, sample.velocity, sample.acceleration
    msg.position.x, msg.position.y, msg.position.z = p
    msg.velocity.x, msg.velocity.y, msg.velocity.z = v
    msg.acceleration.x, msg.acceleration.y, msg.acceleration.z = a
    msg.yaw = msg.yaw_rate = NAN
    speed2 = v[0] ** 2 + v[1] ** 2
    if yaw_mode == "path" and speed2 > 0.3 ** 2:
        msg.yaw = math.atan2(v[1], v[0])
        msg.yaw_rate = (v[0] * a[1] - v[1] * a[0]) / speed2
    msg.thrust = msg.max_horizontal_speed = msg.max_vertical_speed = NAN
    return msg


class LemniscateFlight:
    """The node: stream, switch to OFFBOARD, arm, climb, fly the laps, land."""

    def __init__(self, node, args: argparse.Namespace, path: Lemniscate) -> None:
        self.node, self.args, self.path = node, args, path
        best_effort = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.pub = node.create_publisher(GuidanceSetpoint, "offboard/trajectory_setpoint", best_effort)
        self.command = node.create_client(VehicleCommand, "vehicle/command")
        self.status: VehicleStatus | None = None
        self.pose: PoseStamped | None = None
        self.state_ready = False
        node.create_subscription(VehicleStatus, "vehicle/status", self._on_status, latched)
        node.create_subscription(PoseStamped, "navigation/pose", self._on_pose, best_effort)
        # 500 Hz: only until the estimate is ready, then navigation/pose (50 Hz) is enough
        self.state_sub = node.create_subscription(VehicleState, "navigation/state", self._on_state, best_effort)

    def _on_status(self, msg: VehicleStatus) -> None:
        self.status = msg

    def _on_pose(self, msg: PoseStamped) -> None:
        self.pose = msg

    def _on_state(self, msg: VehicleState) -> None:
        ready = VehicleState.VALID_POSITION_XY | VehicleState.VALID_ORIGIN
        if msg.valid & ready == ready:
            self.state_ready = True

    def now(self) -> float:
        return time.monotonic()

    def spin_until(self, deadline: float, done, stream: Sample | None = None) -> bool:
        """Spin (and keep streaming `stream`, if given) until done() or the deadline."""
        period, next_tick = 1.0 / self.args.rate, self.now()
        while not done():
            if self.now() > deadline:
                return False
            if stream is not None and self.now() >= next_tick:
                self.pub.publish(setpoint(self.node.get_clock().now().to_msg(), stream, self.args.yaw))
                next_tick += period
            rclpy.spin_once(self.node, timeout_sec=max(0.0, min(next_tick - self.now(), 0.05)) if stream is not None else 0.05)
        return True

    def ask(self, command: int, hold: Sample | None, what: str, mode: int = 0) -> None:
        """vehicle/command, streaming `hold` meanwhile; TEMPORARILY_REJECTED is retried for RETRY_S."""
        if not self.spin_until(self.now() + 10.0, lambda: self.command.service_is_ready(), hold):
            raise FlightError("vehicle/command not available (is the mission node running?)")
        deadline = self.now() + RETRY_S
        while True:
            future = self.command.call_async(VehicleCommand.Request(command=command, mode=mode))
            if not self.spin_until(self.now() + 10.0, future.done, hold):
                raise FlightError(f"{what}: no reply from vehicle/command")
            reply = future.result()
            if reply.result == VehicleCommand.Response.RESULT_ACCEPTED:
                print(f"{what}: accepted", flush=True)
                return
            if reply.result != VehicleCommand.Response.RESULT_TEMPORARILY_REJECTED or self.now() > deadline:
                raise FlightError(f"{what} refused: {reply.message}")
            self.spin_until(self.now() + 1.0, lambda: False, hold)

    def near(self, target: Vec) -> bool:
        if self.pose is None:
            return False
        p = self.pose.pose.position
        return math.dist((p.x, p.y, p.z), target) < SETTLE_RADIUS_M

    def run(self) -> None:
        args, path = self.args, self.path
        if not self.spin_until(self.now() + args.timeout, lambda: self.state_ready):
            raise FlightError(f"navigation/state has no position and home after {args.timeout:g} s (is c4d running?)")
        self.node.destroy_subscription(self.state_sub)
        start = Sample(path.start(), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
        print(f"estimate ready; streaming the start point {tuple(round(c, 2) for c in start.position)}", flush=True)
        self.spin_until(self.now() + MODE_DELAY_S, lambda: False, start)
        self.ask(VehicleCommand.Request.CMD_SET_MODE, start, "OFFBOARD", VehicleStatus.MODE_OFFBOARD)
        if self.status is None or not self.status.armed:
            self.ask(VehicleCommand.Request.CMD_ARM, start, "arm")
        settled: list[float] = []

        def at_start() -> bool:
            if not self.near(start.position):
                settled.clear()
                return False
            settled.append(self.now())
            return self.now() - settled[0] >= SETTLE_S
        if not self.spin_until(self.now() + args.timeout, at_start, start):
            raise FlightError(f"did not reach the start point within {args.timeout:g} s")
        print(f"at the start point: {args.laps} lap(s) of {path.duration:.1f} s at {args.speed:g} m/s peak", flush=True)
        t0, period, lap = self.now(), 1.0 / args.rate, 0
        next_tick = t0
        while (tau := self.now() - t0) <= path.duration:
            if self.status is not None and self.status.flight_mode != VehicleStatus.MODE_OFFBOARD:
                raise FlightError(f"left OFFBOARD (mode {self.status.flight_mode}) during the lemniscate")
            if self.now() >= next_tick:
                self.pub.publish(setpoint(self.node.get_clock().now().to_msg(), path.at(tau), args.yaw))
                next_tick += period
                if path.laps_done(tau) > lap:
                    lap = path.laps_done(tau)
                    print(f"lap {lap}/{args.laps} done", flush=True)
            rclpy.spin_once(self.node, timeout_sec=max(0.0, next_tick - self.now()))
        end = path.at(path.duration)
        self.spin_until(self.now() + SETTLE_S, lambda: False, end)
        self.ask(VehicleCommand.Request.CMD_LAND, end, "land")
        if not self.spin_until(self.now() + args.timeout, lambda: self.status is not None and not self.status.armed):
            raise FlightError(f"not disarmed {args.timeout:g} s after LAND")
        print("landed and disarmed", flush=True)


class FlightError(RuntimeError):
    pass


def positive(kind: type = float, low: float = 0.0, high: float = math.inf):
    """argparse type: a number in (low, high]."""
    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a{'n integer' if kind is int else ' number'}: {text!r}") from None
        if not (low < value <= high) or (isinstance(value, float) and not math.isfinite(value)):
            raise argparse.ArgumentTypeError(f"{text} is outside ({low:g}, {high:g}]")
        return value
    return parse


def parse_args(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description="Fly a 3-D lemniscate in OFFBOARD (external node over c4d's public API).")
    parser.add_argument("--shape", choices=("gerono", "bernoulli"), default="gerono", help="lemniscate of Gerono or Bernoulli")
    parser.add_argument("--laps", type=positive(int, 0, 100), default=2, help="laps to fly (default 2)")
    parser.add_argument("--speed", type=positive(float, 0.0, 10.0), default=3.0, help="peak speed [m/s] (default 3)")
    parser.add_argument("--length", type=positive(float, 0.0, 200.0), default=20.0, help="extent along x (east) [m]")
    parser.add_argument("--width", type=positive(float, 0.0, 200.0), default=10.0, help="extent along y (north) [m]")
    parser.add_argument("--swing", type=float, default=4.0, help="altitude swing, peak to peak [m] (default 4)")
    parser.add_argument("--altitude", type=positive(float, 0.0, 120.0), default=6.0,
                        help="altitude of the centre above home [m] (default 6)")
    parser.add_argument("--center", type=float, nargs=2, default=(0.0, 0.0), metavar=("EAST", "NORTH"),
                        help="centre of the figure in map (ENU from home) [m] (default 0 0: above home)")
    parser.add_argument("--yaw", choices=("none", "path"), default="none",
                        help="none: keep the heading (yaw NaN); path: face along the path")
    parser.add_argument("--rate", type=positive(float, 0.0, 100.0), default=50.0, help="setpoint rate [Hz] (10-100)")
    parser.add_argument("--ramp", type=positive(float, 0.0, 60.0), default=3.0, help="speed ramp up and down [s]")
    parser.add_argument("--timeout", type=positive(float, 0.0, 3600.0), default=120.0,
                        help="longest wait for the estimate, the start point, the landing [s]")
    args = parser.parse_args(argv)
    if not 0.0 <= args.swing <= 50.0:
        parser.error(f"--swing {args.swing:g} is outside [0, 50] m")
    if args.altitude - args.swing / 2 < 1.0:
        parser.error(f"--altitude {args.altitude:g} with --swing {args.swing:g} goes below 1 m above home")
    if args.rate < 10.0:
        parser.error(f"--rate {args.rate:g} is below 10 Hz (the stream must stay live: >= 2 Hz, smooth: >= 10 Hz)")
    if not all(math.isfinite(c) for c in args.center):
        parser.error("--center must be finite")
    return args


def main(argv: list[str] | None = None) -> int:
    from rclpy.utilities import remove_ros_args
    argv = list(sys.argv if argv is None else argv)
    args = parse_args(remove_ros_args(argv)[1:])
    try:
        path = Lemniscate(args.shape, args.length, args.width, args.swing, args.altitude, tuple(args.center),
                          args.speed, args.laps, args.ramp)
    except ValueError as exc:
        print(f"offboard_lemniscate: error: {exc}", file=sys.stderr)
        return 2
    rclpy.init(args=argv)
    node = rclpy.create_node("offboard_lemniscate")
    try:
        LemniscateFlight(node, args, path).run()
        return 0
    except FlightError as exc:
        print(f"offboard_lemniscate: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("offboard_lemniscate: interrupted: stream stopped (c4d holds, then its offboard_loss policy acts)",
              file=sys.stderr)
        return 130
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
