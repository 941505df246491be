"""Rotational loops: quaternion attitude P → body-rate PID → body torques.

Attitude: q_err = q⁻¹ ⊗ q_sp (shortest way, w ≥ 0); rate setpoint = 2·K_att ∘ q_err.xyz in
the body frame, plus a yaw-rate feed-forward, limited to the airframe's max rates. Rates: PID
on the gyro (D on measurement, low-pass filtered) producing angular accelerations, turned
into torques through the inertia, with the gyroscopic term ω × Iω compensated.
"""

from __future__ import annotations

from c4d_common import quat
from c4d_common.airframe import Airframe

from .pid import VectorPid

Vec = tuple[float, float, float]


class RotationController:
    def __init__(self, airframe: Airframe) -> None:
        self.af = airframe
        self.rate_pid = VectorPid(airframe.rate, airframe.rate_d_cutoff_hz)
        self.saturated = (False, False, False)

    def reset(self) -> None:
        self.rate_pid.reset()

    def rate_setpoint(self, orientation: quat.Quat, target: quat.Quat, yaw_rate_ff: float = 0.0) -> Vec:
        err = quat.mul(quat.conj(orientation), target)
        if err[0] < 0:
            err = (-err[0], -err[1], -err[2], -err[3])
        k = self.af.attitude_p
        rates = [2.0 * k[0] * err[1], 2.0 * k[1] * err[2], 2.0 * k[2] * err[3]]
        if yaw_rate_ff:
            # world-z yaw rate expressed in the body frame
            z_body = quat.rotate_inverse(orientation, (0.0, 0.0, 1.0))
            rates = [rates[i] + yaw_rate_ff * z_body[i] for i in range(3)]
        limits = self.af.max_rates
        return tuple(max(-limits[i], min(limits[i], rates[i])) for i in range(3))  # type: ignore[return-value]

    def torque(self, gyro: Vec, target: Vec, dt: float) -> Vec:
        error = (target[0] - gyro[0], target[1] - gyro[1], target[2] - gyro[2])
        alpha = self.rate_pid.update(error, gyro, dt, self.saturated)
        ixx, iyy, izz = self.af.inertia
        wx, wy, wz = gyro
        # τ = I·α + ω × Iω
        return (
            ixx * alpha[0] + (wy * izz * wz - wz * iyy * wy),
            iyy * alpha[1] + (wz * ixx * wx - wx * izz * wz),
            izz * alpha[2] + (wx * iyy * wy - wy * ixx * wx),
        )
