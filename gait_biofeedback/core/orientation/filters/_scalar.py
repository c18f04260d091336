"""Scalar (pure-Python float) quaternion steps for the per-sample hot loops.

A filter update touches 4-element quaternions and 3-vectors; numpy costs about 1 µs per call on such
tiny arrays, plain ``math`` floats about 20-50 ns per operation. These helpers are the scalar fast
paths of operations that :mod:`gait_biofeedback.core.quaternion` provides vectorised; same convention:
(w, x, y, z), Hamilton, sensor → world (ENU).
"""

from __future__ import annotations

import math

Quat = tuple[float, float, float, float]
Vec = tuple[float, float, float]


def half_turn(gx: float, gy: float, gz: float, dt: float) -> tuple[float, float]:
    """``(c, s)`` with ``exp(½ ω dt) = (c, ω s)`` (orientation.md §2.2, thesis Eq 7–8); plain math, so
    numba compiles it as a helper of a kernel (``core/joints/_heading_kernel.py``)."""
    n = math.sqrt(gx * gx + gy * gy + gz * gz)
    half = 0.5 * n * dt
    if half < 1e-8:
        return 1.0, 0.5 * dt
    return math.cos(half), math.sin(half) / n


def gyro_step(q: Quat, gx: float, gy: float, gz: float, dt: float) -> Quat:
    """``q ⊗ exp(½ ω dt)``: exact closed-form strap-down step (orientation.md §2.2, thesis Eq 7–8)."""
    c, s = half_turn(gx, gy, gz, dt)
    return multiply(q, (c, gx * s, gy * s, gz * s))


def normalized(q: Quat) -> Quat:
    """Unit-norm copy of a scalar quaternion."""
    w, x, y, z = q
    n = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
    return (w * n, x * n, y * n, z * n)


def multiply(p: Quat, q: Quat) -> Quat:
    """Hamilton product ``p ⊗ q``."""
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return (
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    )


def up_in_sensor(q: Quat) -> Vec:
    """World up (0, 0, 1) seen in the sensor frame: third row of R(q) (= ``R(q)ᵀ e_z``)."""
    w, x, y, z = q
    return (2.0 * (x * z - w * y), 2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))


def matrix(q: Quat) -> tuple[Vec, Vec, Vec]:
    """Rows of ``R(q)`` (sensor → world) of a unit quaternion."""
    w, x, y, z = q
    return ((1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)),
            (2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)),
            (2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)))


def to_world(q: Quat, vx: float, vy: float, vz: float) -> Vec:
    """``R(q) v``: a sensor-frame vector in the world frame."""
    w, x, y, z = q
    return (
        (1.0 - 2.0 * (y * y + z * z)) * vx + 2.0 * (x * y - w * z) * vy + 2.0 * (x * z + w * y) * vz,
        2.0 * (x * y + w * z) * vx + (1.0 - 2.0 * (x * x + z * z)) * vy + 2.0 * (y * z - w * x) * vz,
        2.0 * (x * z - w * y) * vx + 2.0 * (y * z + w * x) * vy + (1.0 - 2.0 * (x * x + y * y)) * vz,
    )


def to_sensor(q: Quat, vx: float, vy: float, vz: float) -> Vec:
    """``R(q)ᵀ v``: a world-frame vector in the sensor frame."""
    w, x, y, z = q
    return (
        (1.0 - 2.0 * (y * y + z * z)) * vx + 2.0 * (x * y + w * z) * vy + 2.0 * (x * z - w * y) * vz,
        2.0 * (x * y - w * z) * vx + (1.0 - 2.0 * (x * x + z * z)) * vy + 2.0 * (y * z + w * x) * vz,
        2.0 * (x * z + w * y) * vx + 2.0 * (y * z - w * x) * vy + (1.0 - 2.0 * (x * x + y * y)) * vz,
    )


def from_rows(r0: Vec, r1: Vec, r2: Vec) -> Quat:
    """Quaternion (w >= 0) of the rotation matrix with rows r0, r1, r2 (largest-pivot branch)."""
    m00, m01, m02 = r0
    m10, m11, m12 = r1
    m20, m21, m22 = r2
    tr = m00 + m11 + m22
    if tr > 0.0:
        s = 2.0 * math.sqrt(1.0 + tr)
        q = (0.25 * s, (m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s)
    elif m00 > m11 and m00 > m22:
        s = 2.0 * math.sqrt(1.0 + m00 - m11 - m22)
        q = ((m21 - m12) / s, 0.25 * s, (m01 + m10) / s, (m02 + m20) / s)
    elif m11 > m22:
        s = 2.0 * math.sqrt(1.0 + m11 - m00 - m22)
        q = ((m02 - m20) / s, (m01 + m10) / s, 0.25 * s, (m12 + m21) / s)
    else:
        s = 2.0 * math.sqrt(1.0 + m22 - m00 - m11)
        q = ((m10 - m01) / s, (m02 + m20) / s, (m12 + m21) / s, 0.25 * s)
    q = normalized(q)
    return q if q[0] >= 0.0 else (-q[0], -q[1], -q[2], -q[3])


def yaw(q: Quat) -> float:
    """ZYX yaw (rad) of ``q``: heading of the sensor x axis about world z."""
    w, x, y, z = q
    return math.atan2(2.0 * (x * y + w * z), 1.0 - 2.0 * (y * y + z * z))


def with_yaw(q: Quat, psi: float) -> Quat:
    """``q`` with its ZYX yaw replaced by ``psi`` (tilt kept): ``R_z(psi - yaw(q)) ⊗ q``."""
    half = 0.5 * (psi - yaw(q))
    return multiply((math.cos(half), 0.0, 0.0, math.sin(half)), q)
