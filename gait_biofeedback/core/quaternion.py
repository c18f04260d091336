"""Unit quaternions, the project's one convention.

Quaternions are numpy arrays ``(..., 4)`` ordered ``(w, x, y, z)``, Hamilton product, and an
orientation ``q`` rotates sensor-frame vectors into the world frame (ENU, z up):
``v_world = q ⊗ [0, v_sensor] ⊗ q*`` = ``as_matrix(q) @ v_sensor`` (orientation.md §1.1, thesis
Eq 10/31). Strap-down kinematics are ``q̇ = ½ q ⊗ [0, ω]`` with ω in the sensor frame (thesis Eq 7–8).
All functions broadcast over leading dimensions. One quaternion (or vector) at a time, as the streams
call them per sample, takes a path on Python floats: the same IEEE operations in the same order,
without numpy's per-call overhead (:func:`_single`).
"""

from __future__ import annotations

import math

import numpy as np

IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


_F64 = np.dtype(np.float64)


def _single(*arrays: object) -> bool:
    """All are 1-D float64 arrays (one quaternion or vector each)."""
    for a in arrays:
        if type(a) is not np.ndarray or a.ndim != 1 or (a.dtype is not _F64 and a.dtype != _F64):
            return False
    return True


def normalize(q: np.ndarray) -> np.ndarray:
    """Unit-norm copy of ``q`` (any leading shape)."""
    if _single(q):
        w, x, y, z = q.tolist()
        n = math.sqrt(w * w + x * x + y * y + z * z)
        return np.array((w / n, x / n, y / n, z / n))
    q = np.asarray(q, dtype=float)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def canonical(q: np.ndarray) -> np.ndarray:
    """The same rotation with ``w >= 0`` (q and -q are one rotation)."""
    q = np.asarray(q, dtype=float)
    return np.where(q[..., :1] < 0.0, -q, q)


def conjugate(q: np.ndarray) -> np.ndarray:
    """Conjugate ``q*``: the inverse rotation of a unit quaternion."""
    if _single(q):
        w, x, y, z = q.tolist()
        return np.array((w, -x, -y, -z))
    q = np.asarray(q, dtype=float)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product ``p ⊗ q`` (apply q first, then p)."""
    if _single(p, q):
        pw, px, py, pz = p.tolist()
        qw, qx, qy, qz = q.tolist()
        return np.array((pw * qw - px * qx - py * qy - pz * qz, pw * qx + px * qw + py * qz - pz * qy,
                         pw * qy - px * qz + py * qw + pz * qx, pw * qz + px * qy - py * qx + pz * qw))
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    pw, px, py, pz = np.moveaxis(p, -1, 0)
    qw, qx, qy, qz = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ],
        axis=-1,
    )


def skew(v: np.ndarray) -> np.ndarray:
    """``[v×]`` of one 3-vector: ``skew(a) @ b == cross(a, b)``."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors ``v`` (..., 3) by ``q``: ``q ⊗ [0, v] ⊗ q*``."""
    if _single(q, v):
        w, x, y, z = q.tolist()
        a, b, c = v.tolist()
        tx, ty, tz = 2.0 * (y * c - z * b), 2.0 * (z * a - x * c), 2.0 * (x * b - y * a)
        return np.array((a + w * tx + (y * tz - z * ty), b + w * ty + (z * tx - x * tz),
                         c + w * tz + (x * ty - y * tx)))
    q = np.asarray(q, dtype=float)
    v = np.asarray(v, dtype=float)
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def rotate_inverse(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate ``v`` by ``q*`` (world → sensor for an orientation ``q``)."""
    return rotate(conjugate(q), v)


def as_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix ``R(q)`` (..., 3, 3) with ``R @ v_sensor = v_world`` (orientation.md §1.1)."""
    if _single(q):
        w, x, y, z = normalize(q).tolist()
        return np.array(((1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
                         (2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
                         (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y))))
    w, x, y, z = np.moveaxis(normalize(q), -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=-2,
    )


def from_matrix(m: np.ndarray) -> np.ndarray:
    """Quaternion (w >= 0) of rotation matrices (..., 3, 3), robust for every angle."""
    m = np.asarray(m, dtype=float)
    trace = m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]
    # Four candidate forms; take the one with the largest (best-conditioned) pivot per matrix.
    cand = np.stack(
        [
            np.stack([1 + trace, m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0],
                      m[..., 1, 0] - m[..., 0, 1]], -1),
            np.stack([m[..., 2, 1] - m[..., 1, 2], 1 + 2 * m[..., 0, 0] - trace,
                      m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0]], -1),
            np.stack([m[..., 0, 2] - m[..., 2, 0], m[..., 0, 1] + m[..., 1, 0],
                      1 + 2 * m[..., 1, 1] - trace, m[..., 1, 2] + m[..., 2, 1]], -1),
            np.stack([m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0],
                      m[..., 1, 2] + m[..., 2, 1], 1 + 2 * m[..., 2, 2] - trace], -1),
        ],
        axis=-2,
    )
    pivots = np.stack([1 + trace, 1 + 2 * m[..., 0, 0] - trace, 1 + 2 * m[..., 1, 1] - trace,
                       1 + 2 * m[..., 2, 2] - trace], -1)
    best = np.argmax(pivots, axis=-1)
    q = np.take_along_axis(cand, best[..., None, None], axis=-2)[..., 0, :]
    return canonical(normalize(q))


def from_rotvec(rv: np.ndarray) -> np.ndarray:
    """Quaternion of rotation vectors (..., 3): axis × angle in rad (exponential map)."""
    rv = np.asarray(rv, dtype=float)
    angle = np.linalg.norm(rv, axis=-1, keepdims=True)
    half = 0.5 * angle
    # sin(half)/angle → 0.5 as angle → 0 (Taylor: 0.5 - angle²/48)
    small = angle < 1e-8
    scale = np.where(small, 0.5 - angle**2 / 48.0, np.sin(half) / np.where(small, 1.0, angle))
    return np.concatenate([np.cos(half), rv * scale], axis=-1)


def as_rotvec(q: np.ndarray) -> np.ndarray:
    """Rotation vector (..., 3) of ``q`` (logarithmic map), angle in [0, π]."""
    q = canonical(normalize(q))
    s = np.linalg.norm(q[..., 1:], axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(s, q[..., :1])
    small = s < 1e-12
    scale = np.where(small, 2.0, angle / np.where(small, 1.0, s))
    return q[..., 1:] * scale


def from_axis_angle(axis: np.ndarray, angle: np.ndarray | float) -> np.ndarray:
    """Quaternion of a rotation by ``angle`` (rad) about ``axis`` (normalised here)."""
    axis = np.asarray(axis, dtype=float)
    axis = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    return from_rotvec(axis * np.asarray(angle, dtype=float)[..., None])


def angle_between(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Rotation angle (rad) of ``p* ⊗ q`` (thesis Eq 51 / orientation.md §13.4)."""
    d = np.abs(np.sum(normalize(p) * normalize(q), axis=-1))
    return 2.0 * np.arccos(np.clip(d, -1.0, 1.0))


def integrate_gyro(q: np.ndarray, gyr: np.ndarray, dt: float | np.ndarray) -> np.ndarray:
    """One strap-down step ``q ⊗ exp(½ ω dt)`` (thesis Eq 7–8, closed form), ω in sensor frame."""
    return normalize(multiply(q, from_rotvec(np.asarray(gyr) * np.asarray(dt, dtype=float)[..., None])))


def from_two_vectors(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Shortest rotation taking direction ``a`` onto direction ``b`` (both (..., 3))."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    w = 1.0 + np.sum(a * b, axis=-1, keepdims=True)
    xyz = np.cross(a, b)
    # antiparallel: rotate π about any axis orthogonal to a
    anti = w[..., 0] < 1e-9
    if np.any(anti):
        helper = np.where(np.abs(a[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
        ortho = np.cross(a, helper)
        ortho = ortho / np.linalg.norm(ortho, axis=-1, keepdims=True)
        xyz = np.where(anti[..., None], ortho, xyz)
        w = np.where(anti[..., None], 0.0, w)
    return normalize(np.concatenate([w, xyz], axis=-1))


def slerp(p: np.ndarray, q: np.ndarray, f: np.ndarray | float) -> np.ndarray:
    """Spherical interpolation from ``p`` (f=0) to ``q`` (f=1) along the shorter arc."""
    p = normalize(p)
    q = normalize(q)
    q = np.where(np.sum(p * q, axis=-1, keepdims=True) < 0, -q, q)
    delta = as_rotvec(multiply(conjugate(p), q))
    return multiply(p, from_rotvec(delta * np.asarray(f, dtype=float)[..., None]))


def from_euler_zyx(yaw: np.ndarray, pitch: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """``R = R_z(yaw) R_y(pitch) R_x(roll)`` as a quaternion (thesis Eq 52 order)."""
    qz = from_axis_angle([0.0, 0.0, 1.0], yaw)
    qy = from_axis_angle([0.0, 1.0, 0.0], pitch)
    qx = from_axis_angle([1.0, 0.0, 0.0], roll)
    return multiply(multiply(qz, qy), qx)


def to_euler_zyx(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(yaw, pitch, roll) with ``R = R_z(yaw) R_y(pitch) R_x(roll)``; pitch = -asin(R[2,0])."""
    m = as_matrix(q)
    pitch = -np.arcsin(np.clip(m[..., 2, 0], -1.0, 1.0))
    roll = np.arctan2(m[..., 2, 1], m[..., 2, 2])
    yaw = np.arctan2(m[..., 1, 0], m[..., 0, 0])
    return yaw, pitch, roll
