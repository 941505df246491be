"""Control allocation: collective thrust + body torques → per-motor commands in [0, 1].

f = P·[T, τx, τy, τz] with P the pseudo-inverse of the airframe's allocation matrix
(rows: Σf, Σ y_i f_i, Σ −x_i f_i, Σ s_i k_m f_i). Saturation is resolved by priority:
roll/pitch first (scaled down only if their spread alone exceeds the motor range, and the
collective is shifted to make room — attitude is what keeps the vehicle upright), then yaw
(scaled down as much as needed to fit). The returned flags feed the rate PID's anti-windup.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from c4d_common.airframe import Airframe


@dataclass(frozen=True)
class MixResult:
    commands: tuple[float, ...]
    roll_pitch_scale: float  # 1 = fully achieved
    yaw_scale: float
    thrust_achieved: float  # [N]
    saturated: bool


class Mixer:
    def __init__(self, airframe: Airframe) -> None:
        self.f_max = airframe.max_thrust
        self.f_idle = airframe.idle_command * airframe.max_thrust
        b = np.array([
            [1.0 for _ in airframe.motors],
            [m.y for m in airframe.motors],
            [-m.x for m in airframe.motors],
            [m.yaw_sign * airframe.torque_coefficient for m in airframe.motors],
        ])
        self.allocation = b
        self.pinv = np.linalg.pinv(b)
        self.n = len(airframe.motors)

    def mix(self, thrust: float, torque: tuple[float, float, float]) -> MixResult:
        p = self.pinv
        lo, hi = self.f_idle, self.f_max
        base = p[:, 0] * thrust
        rp = p[:, 1] * torque[0] + p[:, 2] * torque[1]
        yaw = p[:, 3] * torque[2]
        spread = float(rp.max() - rp.min())
        s_rp = 1.0 if spread <= hi - lo else (hi - lo) / spread
        f = base + s_rp * rp
        # shift the collective (uniform for symmetric frames) so roll/pitch fit
        shift = 0.0
        if f.min() < lo:
            shift = lo - float(f.min())
        elif f.max() > hi:
            shift = hi - float(f.max())
        f = f + shift
        s_yaw = 1.0
        for fi, yi in zip(f, yaw, strict=True):
            if yi > 1e-12:
                s_yaw = min(s_yaw, max(0.0, (hi - fi) / yi))
            elif yi < -1e-12:
                s_yaw = min(s_yaw, max(0.0, (lo - fi) / yi))
        f = np.clip(f + s_yaw * yaw, lo, hi)
        commands = tuple(float(x) / self.f_max for x in f)
        saturated = s_rp < 1.0 or s_yaw < 1.0 or abs(shift) > 1e-9
        return MixResult(commands, s_rp, s_yaw, float(f.sum()), saturated)

    def zero(self) -> tuple[float, ...]:
        return tuple(0.0 for _ in range(self.n))
