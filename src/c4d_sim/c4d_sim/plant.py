"""Rigid-body multirotor plant: 6-DOF dynamics, motor lag, drag, wind, ground contact.

State: position p and velocity v in the world frame (ENU), attitude q (body FLU → world),
body rates ω (FLU), per-motor thrusts f_i. Each motor follows its command u_i ∈ [0, 1] as a
first-order lag (exact discretisation), f_cmd = u_i·f_max·health_i (health 1 = nominal,
0 = failed: fault injection). Forces: thrust along body z, gravity, linear drag against the
air-relative velocity (wind). Torques: r_i × f_i ẑ, propeller reaction ±k_m f_i, angular drag;
Euler's equation I ω̇ = τ − ω × Iω. Semi-implicit Euler with the quaternion integrated by the
exponential map; step sizes of 0.5–2 ms are accurate for these time constants.
Ground (z = 0): a descent reaching it is braked by the landing gear at TOUCHDOWN_DECELERATION
(the gear compresses a few millimetres, then the vehicle stands at z = 0); while the thrust
cannot lift the weight the vehicle rests level, motionless, keeping its heading; that is how
take-off and landing behave in tests.
The accelerometer's specific force (what an IMU measures) is kept for the sensor models.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from c4d_common import quat
from c4d_common.airframe import GRAVITY, Airframe

GROUND_LEVELING_TAU_S = 0.05  # [s] how fast the ground levels a vehicle that touched down tilted
# [m/s²] deceleration of a descent by the compressing landing gear: a 0.7 m/s touchdown stops in
# ~18 ms (6 mm of travel), well inside a 16 g accelerometer's range, as on a real airframe; a rigid
# stop within one 1 ms physics step would read ~70 g and be clipped or rejected as implausible
TOUCHDOWN_DECELERATION = 40.0

Vec = tuple[float, float, float]


@dataclass
class PlantState:
    t: float = 0.0
    position: Vec = (0.0, 0.0, 0.0)
    velocity: Vec = (0.0, 0.0, 0.0)
    orientation: quat.Quat = quat.IDENTITY
    angular_velocity: Vec = (0.0, 0.0, 0.0)
    acceleration: Vec = (0.0, 0.0, 0.0)  # world, gravity removed (kinematic)
    angular_acceleration: Vec = (0.0, 0.0, 0.0)
    specific_force: Vec = (0.0, 0.0, GRAVITY)  # body frame, what an accelerometer reads
    thrusts: list[float] = field(default_factory=list)
    on_ground: bool = True
    # ∫ specific force dt (3), ∫ angular velocity dt (3), ∫ dt since the IMU last read them
    imu_integrals: list[float] = field(default_factory=lambda: [0.0] * 7)

    def take_imu_means(self) -> tuple[Vec, Vec]:
        """Mean specific force and angular velocity since the previous call, and restart the means.

        Why: a real IMU samples at kHz and low-pass filters/decimates to its output rate, so a
        short impulse (the ground stopping a touchdown within one physics step) is in its output.
        Sampling only the instant of the output would miss it whenever the impulse falls between
        two samples — and always when several physics steps run at once after a stall — and an
        inertial estimator would then believe the vehicle keeps descending on the ground."""
        acc = self.imu_integrals
        if acc[6] <= 0.0:
            return self.specific_force, self.angular_velocity
        means = ((acc[0] / acc[6], acc[1] / acc[6], acc[2] / acc[6]), (acc[3] / acc[6], acc[4] / acc[6], acc[5] / acc[6]))
        acc[:] = [0.0] * 7
        return means

    def _accumulate_imu(self, dt: float) -> None:
        acc, f, w = self.imu_integrals, self.specific_force, self.angular_velocity
        acc[0] += f[0] * dt
        acc[1] += f[1] * dt
        acc[2] += f[2] * dt
        acc[3] += w[0] * dt
        acc[4] += w[1] * dt
        acc[5] += w[2] * dt
        acc[6] += dt


class MultirotorPlant:
    def __init__(self, airframe: Airframe, position: Vec = (0.0, 0.0, 0.0), yaw: float = 0.0) -> None:
        self.af = airframe
        self.state = PlantState(position=position, orientation=quat.from_euler(0.0, 0.0, yaw),
                                thrusts=[0.0] * len(airframe.motors), on_ground=position[2] <= 0.0)
        self.motor_health = [1.0] * len(airframe.motors)
        self.wind: Vec = (0.0, 0.0, 0.0)

    def step(self, dt: float, commands: list[float] | tuple[float, ...], armed: bool = True) -> PlantState:
        af, s = self.af, self.state
        alpha = 1.0 - math.exp(-dt / af.motor_time_constant)
        thrusts = s.thrusts
        for i, motor_cmd in enumerate(commands):
            u = max(0.0, min(1.0, motor_cmd)) if armed else 0.0
            thrusts[i] += alpha * (u * af.max_thrust * self.motor_health[i] - thrusts[i])
        total = sum(thrusts)
        tx = ty = tz = 0.0
        for motor, f in zip(af.motors, thrusts, strict=True):
            tx += motor.y * f
            ty -= motor.x * f
            tz += motor.yaw_sign * af.torque_coefficient * f
        wx, wy, wz = s.angular_velocity
        d = af.drag_angular
        tx, ty, tz = tx - d * wx, ty - d * wy, tz - d * wz
        ixx, iyy, izz = af.inertia
        ax_ = (tx - (wy * izz * wz - wz * iyy * wy)) / ixx
        ay_ = (ty - (wz * ixx * wx - wx * izz * wz)) / iyy
        az_ = (tz - (wx * iyy * wy - wy * ixx * wx)) / izz
        zb = quat.body_z(s.orientation)
        vx, vy, vz = s.velocity
        rel = (vx - self.wind[0], vy - self.wind[1], vz - self.wind[2])
        cx, cy, cz = af.drag_linear
        m = af.mass
        acc = (
            (total * zb[0] - cx * rel[0]) / m,
            (total * zb[1] - cy * rel[1]) / m,
            (total * zb[2] - cz * rel[2]) / m - GRAVITY,
        )
        px, py, pz = s.position
        if s.on_ground and acc[2] <= 0.0:
            # resting on the ground: still, heading kept, and the ground torque levels a tilted
            # touchdown within ~GROUND_LEVELING_TAU_S at a rate the gyro reports (an instant snap
            # would be invisible to the gyro and corrupt an inertial estimator's attitude). The
            # accelerometer sees the velocity lost in this step (the contact impulse), so an
            # estimator integrating it stays consistent with the stop.
            w = _leveling_rate(s.orientation, max(GROUND_LEVELING_TAU_S, dt))
            s.orientation = quat.integrate(s.orientation, w, dt)
            stop = (-vx / dt, -vy / dt, -vz / dt)
            s.velocity = (0.0, 0.0, 0.0)
            s.angular_velocity = w
            s.position = (px, py, 0.0)
            s.acceleration = stop
            s.angular_acceleration = (0.0, 0.0, 0.0)
            s.specific_force = quat.rotate_inverse(s.orientation, (stop[0], stop[1], stop[2] + GRAVITY))
            s.t += dt
            s._accumulate_imu(dt)
            return s
        v = (vx + acc[0] * dt, vy + acc[1] * dt, vz + acc[2] * dt)
        p = (px + v[0] * dt, py + v[1] * dt, pz + v[2] * dt)
        w = (wx + ax_ * dt, wy + ay_ * dt, wz + az_ * dt)
        q = quat.integrate(s.orientation, w, dt)
        on_ground = False
        if p[2] <= 0.0 and v[2] < 0.0:  # touchdown: the landing gear brakes the descent
            braked = min(0.0, vz + TOUCHDOWN_DECELERATION * dt) if vz < 0.0 else 0.0
            p = (p[0], p[1], pz + braked * dt)
            v = (v[0], v[1], braked)
            on_ground = braked == 0.0
        if p[2] <= 0.0 and v[2] >= 0.0:  # at rest on (or pushed off) the extended gear
            p = (p[0], p[1], 0.0)
            on_ground = on_ground or v[2] == 0.0
        # what an accelerometer measures is the actual velocity change (contact impulse included)
        acc = ((v[0] - vx) / dt, (v[1] - vy) / dt, (v[2] - vz) / dt)
        s.position, s.velocity, s.orientation, s.angular_velocity = p, v, q, w
        s.acceleration = acc
        s.angular_acceleration = (ax_, ay_, az_)
        s.specific_force = quat.rotate_inverse(q, (acc[0], acc[1], acc[2] + GRAVITY))
        s.on_ground = on_ground
        s.t += dt
        s._accumulate_imu(dt)
        return s


def _leveling_rate(q: quat.Quat, tau: float) -> Vec:
    """Body angular velocity that rotates `q` towards level (same yaw) with time constant tau."""
    level = quat.from_euler(0.0, 0.0, quat.yaw_of(q))
    w, x, y, z = quat.mul(quat.conj(q), level)  # body-frame rotation from q to level
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    half = math.acos(min(1.0, w))
    if half < 1e-9:
        return (0.0, 0.0, 0.0)
    k = 2.0 * half / math.sin(half) / tau
    return (x * k, y * k, z * k)
