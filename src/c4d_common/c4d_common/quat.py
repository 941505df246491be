"""Unit-quaternion helpers on plain tuples (w, x, y, z), rotation body (FLU) → world (ENU).

Why hand-written: the controller and the plant call these thousands of times per simulated
second; on 3- and 4-element values plain float arithmetic is ~10× faster than numpy arrays or
scipy Rotation objects (the tests cross-check these functions against scipy).
"""

from __future__ import annotations

import math

Quat = tuple[float, float, float, float]
Vec = tuple[float, float, float]

IDENTITY: Quat = (1.0, 0.0, 0.0, 0.0)


def mul(a: Quat, b: Quat) -> Quat:
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


def conj(q: Quat) -> Quat:
    return (q[0], -q[1], -q[2], -q[3])


def normalize(q: Quat) -> Quat:
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


def rotate(q: Quat, v: Vec) -> Vec:
    """q ⊗ v ⊗ q*: a body vector expressed in the world frame."""
    w, x, y, z = q
    vx, vy, vz = v
    # t = 2 q_vec × v ; v' = v + w t + q_vec × t
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (vx + w * tx + (y * tz - z * ty), vy + w * ty + (z * tx - x * tz), vz + w * tz + (x * ty - y * tx))


def rotate_inverse(q: Quat, v: Vec) -> Vec:
    """A world vector expressed in the body frame."""
    return rotate(conj(q), v)


def body_z(q: Quat) -> Vec:
    """Third column of the rotation matrix: the body z axis in the world frame."""
    w, x, y, z = q
    return (2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y))


def from_axes(xb: Vec, yb: Vec, zb: Vec) -> Quat:
    """Quaternion of the rotation matrix with columns xb, yb, zb (orthonormal)."""
    m00, m10, m20 = xb
    m01, m11, m21 = yb
    m02, m12, m22 = zb
    trace = m00 + m11 + m22
    if trace > 0.0:
        s = 0.5 / math.sqrt(trace + 1.0)
        q = (0.25 / s, (m21 - m12) * s, (m02 - m20) * s, (m10 - m01) * s)
    elif m00 > m11 and m00 > m22:
        s = 2.0 * math.sqrt(1.0 + m00 - m11 - m22)
        q = ((m21 - m12) / s, 0.25 * s, (m01 + m10) / s, (m02 + m20) / s)
    elif m11 > m22:
        s = 2.0 * math.sqrt(1.0 + m11 - m00 - m22)
        q = ((m02 - m20) / s, (m01 + m10) / s, 0.25 * s, (m12 + m21) / s)
    else:
        s = 2.0 * math.sqrt(1.0 + m22 - m00 - m11)
        q = ((m10 - m01) / s, (m02 + m20) / s, (m12 + m21) / s, 0.25 * s)
    return normalize(q)


def from_euler(roll: float, pitch: float, yaw: float) -> Quat:
    """Z-Y-X (yaw, pitch, roll) intrinsic rotation; yaw ENU (0 = east, CCW)."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)


def to_euler(q: Quat) -> Vec:
    w, x, y, z = q
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return roll, pitch, yaw


def yaw_of(q: Quat) -> float:
    return to_euler(q)[2]


def integrate(q: Quat, omega_body: Vec, dt: float) -> Quat:
    """q ⊗ exp(ω dt / 2): propagate an attitude by a constant body rate for dt."""
    wx, wy, wz = omega_body
    angle = math.sqrt(wx * wx + wy * wy + wz * wz) * dt
    if angle < 1e-12:
        return q
    half = 0.5 * angle
    s = math.sin(half) / (angle / dt)
    return normalize(mul(q, (math.cos(half), wx * s, wy * s, wz * s)))


def angle_between(a: Quat, b: Quat) -> float:
    """Smallest rotation angle (rad) taking a to b."""
    d = abs(a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3])
    return 2.0 * math.acos(min(1.0, d))
