"""The GNC core logic: modes, latched requests, guidance profiles and the cascade as tasks.

ROS-free. The core node (or a test harness) fills the blackboard (`inputs`) during the input
phase, calls `latch()` once per tick, runs the task functions of TASKS at their schedule
rates, and reads `outputs`. Requests (arm, disarm, set mode, take-off, land, hold, kill) are
validated when they arrive and applied at the next `latch()` — a mode change never happens in
the middle of a control chain.

Modes (c4d_interfaces/VehicleStatus numbering): RATE and ATTITUDE follow the pilot's setpoints of
that level; OFFBOARD follows the offboard gateway's stream (entered only once that stream has been
live for 1 s; on the ground a setpoint above it takes off; stale → hold where the vehicle is);
POSITION holds the position and heading captured on entry; AUTO runs a navigation
state — TAKEOFF (climb at the airframe's take-off speed to the target, then HOLD), HOLD, LAND
(descend at the landing speed, detect touchdown, disarm), MISSION/GOTO/RTL (follow external
guidance setpoints, holding if they go stale; RTL is the mission node flying a return home, kept
apart from GOTO so that the vehicle's status says what it does); KILL stops the motors at once.
Which source's setpoints steer is decided by the mode alone (setpoint_sources.owner).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from c4d_common import quat
from c4d_common.airframe import GRAVITY, Airframe
from c4d_common.barrier import Barrier, BarrierParams, FenceGeometry, Obstacle
from c4d_common.vehicle import Command, Landed, Level, Mode, Nav, SetpointSource

from .control.mixer import Mixer, MixResult
from .control.rotation import RotationController
from .control.translation import TranslationController
from .setpoint_sources import OFFBOARD_ENTRY_S, SetpointInputs, owner

NAN = float("nan")
Vec = tuple[float, float, float]


@dataclass
class StateSample:
    """Navigation state as the core uses it (world ENU, body FLU)."""

    stamp: float
    position: Vec
    velocity: Vec
    orientation: quat.Quat
    angular_velocity: Vec
    valid_position: bool = True
    valid_attitude: bool = True
    valid_velocity: bool = True  # horizontal velocity (valid with the position, or dead reckoning on drag fusion)
    terrain_distance: float = NAN  # [m] downward range to the ground, NaN when unknown
    origin: Vec | None = None  # (latitude [deg], longitude [deg], altitude [m]) of home, None until set


@dataclass
class Setpoint:
    """A guidance target (c4d_interfaces/GuidanceSetpoint); NaN = not set. For level POSITION
    a NaN position component makes that axis velocity-controlled with velocity[k]."""

    stamp: float
    level: Level
    position: Vec = (NAN, NAN, NAN)
    velocity: Vec = (NAN, NAN, NAN)
    acceleration: Vec = (NAN, NAN, NAN)
    yaw: float = NAN
    yaw_rate: float = NAN
    orientation: quat.Quat = quat.IDENTITY
    body_rate: Vec = (0.0, 0.0, 0.0)
    thrust: float = NAN  # [0, 1] of the total thrust


@dataclass
class Inputs:
    """Blackboard: the newest data of each input, written in the input phase only."""

    now: float = 0.0
    state: StateSample | None = None
    gyro: Vec | None = None
    gyro_stamp: float = -math.inf
    setpoints: SetpointInputs[Setpoint] = field(default_factory=SetpointInputs)
    obstacles: tuple[Obstacle, ...] = ()  # local ENU, as perception/surroundings last said (converted on arrival)
    obstacles_stamp: float = -math.inf  # [s] when they were received; older than OBSTACLE_TIMEOUT_S: ignored
    fence: FenceGeometry | None = None  # geofence/active in local ENU (converted when it or home changes)


@dataclass
class Outputs:
    commands: tuple[float, ...] = ()
    armed: bool = False
    mode: Mode = Mode.POSITION
    nav: Nav = Nav.NONE
    landed: Landed = Landed.ON_GROUND
    source: SetpointSource = SetpointSource.CORE  # who steers the cascade now
    input_stamp: float = 0.0  # sample time of the data the last command came from
    mix: MixResult | None = None
    events: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class Request:
    command: Command
    mode: Mode = Mode.UNKNOWN
    altitude: float = 0.0
    force: bool = False


@dataclass(frozen=True)
class Verdict:
    """The core's answer to a request. `retry`: refused only because the estimate is not (yet)
    fresh or valid — worth asking again (the service answers TEMPORARILY_REJECTED, not DENIED)."""

    accepted: bool
    reason: str
    retry: bool = False


STATE_TIMEOUT_S = 0.1
GYRO_TIMEOUT_S = 0.02
SETPOINT_TIMEOUT_S = 0.5
LANDED_TIME_S = 1.0
LIFTOFF_MARGIN_M = 0.3  # OFFBOARD on the ground: a position target this far above the vehicle (or climb velocity) lifts off
BRAKE_ACCEL = 4.0  # [m/s^2] stale stream: hold at the point a brake at this deceleration would reach
OBSTACLE_TIMEOUT_S = 1.0  # obstacles not refreshed for this long (perception silent) are dropped
BLIND_SLOW_BELOW_M = 2.0  # [m] a blind landing (no valid horizontal position) descends fast down to this height
AVOID_MIN_HEIGHT_M = 1.0  # take-off and landing: the barrier acts only above this height over the ground


class GncCore:
    TASKS = ("state_update", "guidance", "position_control", "attitude_control", "rate_control", "mixer")

    def __init__(self, airframe: Airframe, tick_s: float, default_takeoff_altitude: float = 2.5,
                 barrier: BarrierParams | None = None, avoidance: bool = True) -> None:
        self.af = airframe
        self.tick_s = tick_s
        self.default_takeoff_altitude = default_takeoff_altitude
        self.inputs = Inputs()
        self.out = Outputs(commands=tuple(0.0 for _ in airframe.motors))
        self.translation = TranslationController(airframe)
        self.rotation = RotationController(airframe)
        self.mixer = Mixer(airframe)
        self.pending: list[Request] = []
        self.state: StateSample | None = None
        self.setpoint: Setpoint | None = None
        self.hold: Vec = (0.0, 0.0, 0.0)
        self.hold_yaw = 0.0
        self.takeoff_target = 0.0
        self.ramp_z = 0.0
        self.thrust = 0.0
        self.attitude_target = quat.IDENTITY
        self.rate_target: Vec = (0.0, 0.0, 0.0)
        self.torque: Vec = (0.0, 0.0, 0.0)
        self.yaw_rate_ff = 0.0
        self.landed_timer = 0.0
        self.landing_velocity: Vec = (0.0, 0.0, 0.0)
        self.active: Setpoint | None = None
        self.following = False  # the owner's stream steered the last guidance step
        # DAA and geofence preservation (c4d_common.barrier, docs/daa.md); None: disabled
        self.barrier: Barrier | None = Barrier(barrier) if avoidance else None

    # ----------------------------------------------------------------- setpoint inputs
    def receive_setpoint(self, source: SetpointSource, setpoint: Setpoint) -> bool:
        """A setpoint from `source` at the blackboard's time; False when ignored (source does not own the stream)."""
        out = self.out
        return self.inputs.setpoints.receive(source, setpoint, self.inputs.now, owner(out.mode, out.nav))

    def offboard_live_s(self) -> float:
        """[s] how long the offboard stream has been live (0: none)."""
        return self.inputs.setpoints.offboard.live_for(self.inputs.now)

    # ----------------------------------------------------------------- requests & latch
    def inputs_fresh(self) -> str:
        """Empty string when state and gyro are fresh and valid, else the reason."""
        i = self.inputs
        if i.state is None or i.now - i.state.stamp > STATE_TIMEOUT_S:
            return "navigation state is stale"
        if i.gyro is None or i.now - i.gyro_stamp > GYRO_TIMEOUT_S:
            return "gyro (IMU) is stale"
        if not i.state.valid_attitude:
            return "attitude estimate is not valid"
        return ""

    def request(self, req: Request) -> tuple[bool, str]:
        """Validate now, apply at the next tick boundary. Returns (accepted, reason)."""
        verdict = self.submit(req)
        return verdict.accepted, verdict.reason

    def submit(self, req: Request) -> Verdict:
        """Validate now, apply at the next tick boundary; the typed answer of `request()`."""
        armed, landed = self.out.armed, self.out.landed
        if req.command in (Command.ARM, Command.TAKEOFF):
            reason = self.inputs_fresh()
            if reason and not (req.force and req.command == Command.ARM):
                return Verdict(False, f"refusing to arm: {reason}", retry=True)
            if req.command == Command.TAKEOFF and self.inputs.state and not self.inputs.state.valid_position:
                return Verdict(False, "take-off needs a valid position estimate", retry=True)
        if req.command == Command.DISARM and armed and landed not in (Landed.ON_GROUND,) and not req.force:
            return Verdict(False, "refusing to disarm in the air (use force)")
        if req.command == Command.SET_MODE and req.mode not in (Mode.RATE, Mode.ATTITUDE, Mode.POSITION, Mode.AUTO, Mode.KILL,
                                                                Mode.OFFBOARD):
            return Verdict(False, f"unknown mode {int(req.mode)}")
        if req.command == Command.SET_MODE and req.mode == Mode.OFFBOARD and self.out.mode != Mode.OFFBOARD:
            live = self.offboard_live_s()
            if live < OFFBOARD_ENTRY_S:
                why = f"live for {live:.1f} s" if live > 0 else "none received in the last 0.5 s"
                return Verdict(False, f"refusing OFFBOARD: needs a setpoint stream on guidance/offboard live for "
                                      f">= {OFFBOARD_ENTRY_S:g} s at >= 2 Hz ({why})", retry=True)
        if req.command in (Command.LAND, Command.HOLD, Command.GOTO, Command.RETURN_TO_LAUNCH) and not armed:
            return Verdict(False, "not armed")
        if req.command in (Command.GOTO, Command.RETURN_TO_LAUNCH) and landed == Landed.ON_GROUND:
            return Verdict(False, "on the ground: take off first")
        self.pending.append(req)
        return Verdict(True, "accepted: applies at the next tick")

    def latch(self) -> None:
        """Apply pending requests, in arrival order, at this tick boundary."""
        pending, self.pending = self.pending, []
        for req in pending:
            self._apply(req)
        if pending:  # the status published after a mode change names the new owner, not the last guidance step's
            if self.barrier is not None:
                self.barrier.reset()  # a new mode or target source: a detour or stall timer does not carry over
            self.out.source = self._steering_source(self.inputs.setpoints.latest(owner(self.out.mode, self.out.nav)))

    def _steering_source(self, setpoint: Setpoint | None) -> SetpointSource:
        """The owner of the stream when its newest `setpoint` is fresh, else CORE (the core's own targets)."""
        source = owner(self.out.mode, self.out.nav)
        if source == SetpointSource.CORE or setpoint is None or self.inputs.now - setpoint.stamp > SETPOINT_TIMEOUT_S:
            return SetpointSource.CORE
        return source

    def _capture_hold(self) -> None:
        """Hold here with the current heading. (Braking first with velocity control and holding where the
        vehicle stops was tried: the velocity loop alone brakes softer, a 5 m/s vehicle drifted 2.9 m
        instead of < 1.5 m; the position loop's overshoot of ~0.3 m and return is the better trade.)"""
        s = self.state or self.inputs.state
        if s is not None:
            self.hold = s.position
            self.hold_yaw = quat.yaw_of(s.orientation)

    def _apply(self, req: Request) -> None:
        out = self.out
        if req.command == Command.ARM and not out.armed:
            self._reset_controllers()
            self._capture_hold()
            out.armed, out.landed = True, Landed.ON_GROUND
            out.events.append("armed")
        elif req.command == Command.DISARM and out.armed:
            out.armed, out.nav = False, Nav.NONE
            out.events.append("disarmed")
        elif req.command == Command.SET_MODE:
            if req.mode == Mode.KILL:
                out.armed = False
                out.events.append("kill")
            if req.mode in (Mode.POSITION, Mode.AUTO, Mode.OFFBOARD):
                self._capture_hold()
            out.mode = req.mode
            out.nav = Nav.HOLD if req.mode == Mode.AUTO and out.armed else Nav.NONE
        elif req.command == Command.TAKEOFF:
            if not out.armed:
                self._reset_controllers()
                out.armed = True
                out.events.append("armed")
            self._capture_hold()
            s = self.state or self.inputs.state
            # altitude is above home (z = 0 of the local frame), not above a noisy ground sample
            self.takeoff_target = req.altitude if req.altitude > 0 else self.default_takeoff_altitude
            self.ramp_z = s.position[2] if s else 0.0
            out.mode, out.nav, out.landed = Mode.AUTO, Nav.TAKEOFF, Landed.TAKEOFF
        elif req.command == Command.LAND:
            self._capture_hold()
            out.mode, out.nav, out.landed = Mode.AUTO, Nav.LAND, Landed.LANDING
            self.landed_timer = 0.0
            s = self.state or self.inputs.state
            self.landing_velocity = s.velocity if s else (0.0, 0.0, 0.0)
        elif req.command == Command.HOLD:
            self._capture_hold()
            out.mode, out.nav = Mode.AUTO, Nav.HOLD
        elif req.command in (Command.GOTO, Command.RETURN_TO_LAUNCH):  # follow the external setpoints
            self._capture_hold()
            out.mode, out.nav = Mode.AUTO, Nav.GOTO if req.command == Command.GOTO else Nav.RTL

    def retune(self, airframe: Airframe) -> None:
        """Swap in `airframe`'s gains and limits (same vehicle, new tuning); called at the latch only, so
        every stage of a tick runs with one set. Integrators and filters keep their state (no bump); the
        mixer is rebuilt only when its limits changed."""
        old, self.af = self.af, airframe
        self.translation.af = self.rotation.af = airframe
        self.translation.velocity_pid.gains = airframe.velocity
        self.rotation.rate_pid.gains = airframe.rate
        self.rotation.rate_pid.d_cutoff_hz = airframe.rate_d_cutoff_hz
        if (old.idle_command, old.max_thrust) != (airframe.idle_command, airframe.max_thrust):
            self.mixer = Mixer(airframe)

    def _reset_controllers(self) -> None:
        self.translation.reset()
        self.rotation.reset()

    # ----------------------------------------------------------------- tasks
    def state_update(self, dt: float) -> None:
        """Estimation group: take the blackboard's state for this tick (read once, LET-like)."""
        self.state = self.inputs.state
        self.setpoint = self.inputs.setpoints.latest(owner(self.out.mode, self.out.nav))

    def guidance(self, dt: float) -> None:
        """Guidance group: turn the mode / navigation state into the cascade's setpoint."""
        out, s = self.out, self.state
        if s is None:
            return
        now = self.inputs.now
        mode = out.mode
        source = owner(mode, out.nav)
        out.source = self._steering_source(self.setpoint)
        external = self.setpoint if out.source != SetpointSource.CORE else None
        if mode in (Mode.RATE, Mode.ATTITUDE):
            level = Level.RATE if mode == Mode.RATE else Level.ATTITUDE
            if external is not None and external.level == level:
                self.active = external
            else:  # stale pilot input: level attitude, sink gently
                self.active = Setpoint(now, Level.ATTITUDE, orientation=quat.from_euler(0, 0, quat.yaw_of(s.orientation)),
                                       thrust=0.9 * self.af.hover_command / self.af.max_thrust_ratio)
            return
        if mode == Mode.AUTO and out.nav == Nav.TAKEOFF:
            self.ramp_z = min(self.takeoff_target, self.ramp_z + self.af.takeoff_speed * dt)
            climbing = self.ramp_z < self.takeoff_target
            self.active = Setpoint(now, Level.POSITION, (self.hold[0], self.hold[1], self.ramp_z),
                                   (0.0, 0.0, self.af.takeoff_speed if climbing else 0.0), yaw=self.hold_yaw)
            if s.position[2] > 0.3:
                out.landed = Landed.IN_AIR if not climbing else Landed.TAKEOFF
            if not climbing and abs(s.position[2] - self.takeoff_target) < 0.15:
                self.hold = (self.hold[0], self.hold[1], self.takeoff_target)
                out.nav, out.landed = Nav.HOLD, Landed.IN_AIR
                out.events.append("takeoff complete")
            return
        if mode == Mode.AUTO and out.nav == Nav.LAND:
            self.active = Setpoint(now, Level.POSITION, (self.hold[0], self.hold[1], NAN),
                                   (0.0, 0.0, -self._landing_speed(s)), yaw=self.hold_yaw)
            self._detect_landing(s, dt)
            return
        if mode == Mode.OFFBOARD and out.armed and out.landed == Landed.ON_GROUND:
            if external is None or not self._lifts_off(external, s):
                self.following = False
                self.active = Setpoint(now, Level.POSITION, self.hold, (0.0, 0.0, 0.0), yaw=self.hold_yaw)
                return
            out.landed = Landed.TAKEOFF
            out.events.append("offboard take-off")
        if source in (SetpointSource.MISSION, SetpointSource.OFFBOARD) and external is not None:
            if mode == Mode.OFFBOARD and out.landed == Landed.TAKEOFF and s.position[2] > 0.3:
                out.landed = Landed.IN_AIR
            self.following = True
            self.active = external
            return
        if self.following and source != SetpointSource.CORE:
            # the owner's stream went stale: hold where a brake from here ends, not where the mode began (a stream
            # lost at 3 m/s held at the point of loss overshot and flew back at > 1 m/s 1.5 s later)
            self._capture_hold()
            self.hold = _braking_point(s.position, s.velocity)
            out.events.append(f"{source.name.lower()} setpoints stale: holding")
        self.following = False
        self.active = Setpoint(now, Level.POSITION, self.hold, (0.0, 0.0, 0.0), yaw=self.hold_yaw)

    @staticmethod
    def _lifts_off(sp: Setpoint, s: StateSample) -> bool:
        """An OFFBOARD setpoint that asks a vehicle on the ground to climb: a position target above it, an upward
        velocity, or an attitude / rate setpoint with more than hover-idle thrust."""
        if sp.level == Level.POSITION:
            z = sp.position[2]
            return (math.isfinite(z) and z > s.position[2] + LIFTOFF_MARGIN_M) or (
                not math.isfinite(z) and math.isfinite(sp.velocity[2]) and sp.velocity[2] > 0.1)
        if sp.level == Level.VELOCITY:
            return math.isfinite(sp.velocity[2]) and sp.velocity[2] > 0.1
        if sp.level == Level.ACCELERATION:
            return math.isfinite(sp.acceleration[2]) and sp.acceleration[2] > 0.1
        return math.isfinite(sp.thrust) and sp.thrust > 0.1

    def _landing_speed(self, s: StateSample) -> float:
        """land_speed; blind (the horizontal position is not valid, so the vehicle stays level and drifts with
        whatever velocity it had) it descends at max_descent_speed down to BLIND_SLOW_BELOW_M over the ground
        (range finder, else the height over home), then at land_speed: less time in the air to drift (issue 19,
        GNSS spoofed without an alternative source: from 5 m, 5.3 s to the ground instead of 8.0 s in the closed-loop test)."""
        if s.valid_position:
            return self.af.land_speed
        height = s.terrain_distance if math.isfinite(s.terrain_distance) else s.position[2]
        return max(self.af.land_speed, self.af.max_descent_speed) if height > BLIND_SLOW_BELOW_M else self.af.land_speed

    def _detect_landing(self, s: StateSample, dt: float) -> None:
        """Touchdown = thrust well below hover while either the range finder sees the ground
        within 0.2 m (for 0.5 s), or, without a range reading, the estimated velocity
        (low-passed, τ 0.3 s, so estimator noise cannot reset the timer) is ~zero (for 1 s) —
        only its vertical part once the horizontal position is lost (GNSS loss → blind descent)."""
        hover_thrust = self.af.mass * GRAVITY
        alpha = min(1.0, dt / 0.3)
        self.landing_velocity = tuple(f + alpha * (v - f) for f, v in zip(self.landing_velocity, s.velocity, strict=True))
        vx, vy, vz = self.landing_velocity
        near_ground = math.isfinite(s.terrain_distance) and s.terrain_distance < 0.2
        still = abs(vz) < 0.2 and (math.hypot(vx, vy) < 0.5 or not s.valid_velocity)  # drifting xy says nothing
        if (near_ground or still) and self.thrust < 0.75 * hover_thrust:
            self.landed_timer += dt
        else:
            self.landed_timer = 0.0
        if self.landed_timer >= (LANDED_TIME_S / 2 if near_ground else LANDED_TIME_S):
            out = self.out
            out.armed, out.nav, out.landed = False, Nav.NONE, Landed.ON_GROUND
            out.events.append("landed")
            out.events.append("disarmed")

    def position_control(self, dt: float) -> None:
        """Control group (slow): position/velocity loops → thrust and attitude target."""
        s, sp = self.state, self.active
        if s is None or sp is None or sp.level in (Level.ATTITUDE, Level.RATE):
            if sp is not None and sp.level in (Level.ATTITUDE, Level.RATE):
                thrust = sp.thrust if math.isfinite(sp.thrust) else self.af.hover_command
                self.thrust = thrust * self.af.total_max_thrust
                if sp.level == Level.ATTITUDE:
                    self.attitude_target = sp.orientation
            return
        velocity_ff = sp.velocity
        if sp.level == Level.POSITION:
            target = tuple(p if math.isfinite(p) else s.position[k] for k, p in enumerate(sp.position))
            ff = tuple(v if math.isfinite(v) else 0.0 for v in velocity_ff)
            v_sp = list(self.translation.velocity_setpoint(s.position, target, ff))
            for k in range(3):  # NaN position axis: velocity control on that axis
                if not math.isfinite(sp.position[k]):
                    v_sp[k] = velocity_ff[k] if math.isfinite(velocity_ff[k]) else 0.0
        elif sp.level == Level.VELOCITY:
            v_sp = [v if math.isfinite(v) else 0.0 for v in velocity_ff]
        else:
            v_sp = None
        shield = self.barrier is not None and self._avoiding(s)
        if v_sp is not None:
            if shield:
                target = sp.position if sp.level == Level.POSITION and math.isfinite(sp.position[0]) and \
                    math.isfinite(sp.position[1]) else None
                v_sp = list(self._shield(s, (v_sp[0], v_sp[1], v_sp[2]), target, dt))
            if not s.valid_position and s.valid_velocity:  # no position to hold: brake and hold still horizontally
                for k in range(2):  # (a velocity setpoint is still followed)
                    v_sp[k] = velocity_ff[k] if sp.level == Level.VELOCITY and math.isfinite(velocity_ff[k]) else 0.0
            accel = self.translation.acceleration_setpoint(s.velocity, tuple(v_sp), sp.acceleration, dt)
            if not s.valid_position and not s.valid_velocity:  # inertial dead reckoning drifts: stay level
                accel = (0.0, 0.0, accel[2])  # horizontally, keep the baro-held height
        else:
            accel = tuple(a if math.isfinite(a) else 0.0 for a in sp.acceleration)
            if shield and self.barrier is not None:  # acceleration level: shield the velocity it leads to in tau
                tau = self.barrier.p.response_time
                wanted = tuple(v + a * tau for v, a in zip(s.velocity, accel, strict=True))
                safe = self._shield(s, (wanted[0], wanted[1], wanted[2]), None, dt)
                accel = tuple(a + (v - w) / tau for a, v, w in zip(accel, safe, wanted, strict=True))
        yaw = sp.yaw if math.isfinite(sp.yaw) else self.hold_yaw
        self.thrust, self.attitude_target = self.translation.thrust_and_attitude(accel, yaw, s.orientation)
        self.yaw_rate_ff = sp.yaw_rate if math.isfinite(sp.yaw_rate) else 0.0

    def _avoiding(self, s: StateSample) -> bool:
        """The barrier applies: armed in a guided mode (POSITION, AUTO, OFFBOARD) with a valid position, something
        to avoid, and not in the take-off / landing zone near the ground."""
        out, i = self.out, self.inputs
        if not out.armed or out.mode not in (Mode.POSITION, Mode.AUTO, Mode.OFFBOARD) or not s.valid_position:
            return False
        if out.landed == Landed.ON_GROUND:
            return False
        has_obstacles = bool(i.obstacles) and i.now - i.obstacles_stamp <= OBSTACLE_TIMEOUT_S
        if not has_obstacles and (i.fence is None or i.fence.empty):
            return False
        if out.landed != Landed.IN_AIR or out.nav in (Nav.TAKEOFF, Nav.LAND):
            height = s.terrain_distance if math.isfinite(s.terrain_distance) else s.position[2]
            return height > AVOID_MIN_HEIGHT_M
        return True

    def _shield(self, s: StateSample, v_sp: Vec, target: Vec | None, dt: float) -> Vec:
        """v_sp through the barrier (obstacles + fence; the floor only in the air outside take-off / landing)."""
        assert self.barrier is not None
        i, out = self.inputs, self.out
        obstacles = i.obstacles if i.now - i.obstacles_stamp <= OBSTACLE_TIMEOUT_S else ()
        floor = out.landed == Landed.IN_AIR and out.nav not in (Nav.TAKEOFF, Nav.LAND)
        before = self.barrier.state.side
        result = self.barrier.shield(i.now, dt, s.position, s.velocity, v_sp, target, obstacles, i.fence, floor)
        if result.detour != before:
            out.events.append(f"detour around obstacle {result.detour_obstacle} "
                              f"({'counter-clockwise' if result.detour > 0 else 'clockwise'})" if result.detour
                              else "detour ended")
        return result.velocity

    def attitude_control(self, dt: float) -> None:
        s, sp = self.state, self.active
        if s is None or sp is None:
            return
        if sp.level == Level.RATE:
            self.rate_target = sp.body_rate
            return
        self.rate_target = self.rotation.rate_setpoint(s.orientation, self.attitude_target, self.yaw_rate_ff)

    def rate_control(self, dt: float) -> None:
        """Control group (fast): rate PID on the freshest gyro sample."""
        gyro = self.inputs.gyro
        if gyro is None:
            return
        self.torque = self.rotation.torque(gyro, self.rate_target, dt)

    def mixer_task(self, dt: float) -> None:
        out = self.out
        if not out.armed or out.mode == Mode.KILL:
            out.commands = self.mixer.zero()
            out.mix = None
            self._reset_controllers()
            return
        if out.landed == Landed.ON_GROUND and out.mode in (Mode.POSITION, Mode.AUTO, Mode.OFFBOARD) and out.nav != Nav.TAKEOFF:
            # armed on the ground: spin at idle; only a take-off (or a pilot mode) lifts off
            out.commands = tuple(self.af.idle_command for _ in self.af.motors)
            self._reset_controllers()
            return
        mix = self.mixer.mix(self.thrust, self.torque)
        sat = mix.roll_pitch_scale < 1.0 or mix.thrust_achieved < self.thrust - 1e-6
        self.rotation.saturated = (sat, sat, mix.yaw_scale < 1.0)
        out.commands, out.mix = mix.commands, mix
        if self.state is not None:
            out.input_stamp = max(self.state.stamp, self.inputs.gyro_stamp)

    def task_functions(self) -> dict[str, object]:
        """name → f(dt) for the executive (the mixer's entry is `mixer`)."""
        return {"state_update": self.state_update, "guidance": self.guidance, "position_control": self.position_control,
                "attitude_control": self.attitude_control, "rate_control": self.rate_control, "mixer": self.mixer_task}


def _braking_point(position: Vec, velocity: Vec) -> Vec:
    """Where a vehicle at `position` moving at `velocity` stops when it brakes at BRAKE_ACCEL (per axis)."""
    x, y, z = (p + v * abs(v) / (2 * BRAKE_ACCEL) for p, v in zip(position, velocity, strict=True))
    return (x, y, z)
