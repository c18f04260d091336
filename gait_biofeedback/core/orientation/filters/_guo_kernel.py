"""Per-sample kernel of Guo(2017)'s fast Kalman filter (``guo_fkf``), numba-able plain Python.

State: the quaternion ``q`` (w, x, y, z, sensor → world ENU) and its 4×4 covariance ``P``; inputs are
bias-corrected gyro (rad/s) and accelerometer / magnetometer already divided by their reference
norms. The algorithm and its READINGs are in :mod:`~gait_biofeedback.core.orientation.filters.guo_fkf`.
Compiled by :func:`gait_biofeedback.core.jit.fast`; both runtimes give the same numbers.
"""

from __future__ import annotations

import math

import numpy as np

_FD_STEP = 1e-6  # central-difference step of the measurement Jacobian (unit-vector components)
_S_FLOOR = 1e-12  # isotropic floor of the innovation covariance
_NORM_VARIANCE = 1.0  # variance of the measurement quaternion along itself: its norm carries no information
# layout of the state vector ``st`` passed to :func:`step`
Q, P0, MREF, SG, INNOV, SDIAG, N_STATE = 0, 4, 20, 23, 26, 30, 34
HELPERS = ("_cross", "_unit", "matrix_to_quaternion", "_wahba", "measurement")


def _cross(a0, a1, a2, b0, b1, b2):
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


def _unit(a0, a1, a2):
    n = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    return a0 / n, a1 / n, a2 / n


def matrix_to_quaternion(r00, r01, r02, r10, r11, r12, r20, r21, r22):
    """Unit quaternion (w, x, y, z) of a rotation matrix (Shepperd's largest-component method)."""
    tr = r00 + r11 + r22
    if tr > r00 and tr > r11 and tr > r22:
        s = 2.0 * math.sqrt(1.0 + tr)
        w, x, y, z = 0.25 * s, (r21 - r12) / s, (r02 - r20) / s, (r10 - r01) / s
    elif r00 > r11 and r00 > r22:
        s = 2.0 * math.sqrt(max(1e-300, 1.0 + r00 - r11 - r22))
        w, x, y, z = (r21 - r12) / s, 0.25 * s, (r01 + r10) / s, (r02 + r20) / s
    elif r11 > r22:
        s = 2.0 * math.sqrt(max(1e-300, 1.0 + r11 - r00 - r22))
        w, x, y, z = (r02 - r20) / s, (r01 + r10) / s, 0.25 * s, (r12 + r21) / s
    else:
        s = 2.0 * math.sqrt(max(1e-300, 1.0 + r22 - r00 - r11))
        w, x, y, z = (r10 - r01) / s, (r02 + r20) / s, (r12 + r21) / s, 0.25 * s
    n = math.sqrt(w * w + x * x + y * y + z * z)
    return w / n, x / n, y / n, z / n


def wahba_two_vectors(
    b1: np.ndarray, b2: np.ndarray, r1: np.ndarray, r2: np.ndarray, w1: float, w2: float
) -> np.ndarray:
    """Wahba-optimal rotation for two weighted observation pairs (Markley 2008, JGCD 31(3), closed form):
    the 3×3 R (world ← sensor) minimising w1‖b1 − Rᵀr1‖² + w2‖b2 − Rᵀr2‖² (b sensor, r world, unit)."""
    rot = np.empty((3, 3))
    _wahba(b1[0], b1[1], b1[2], b2[0], b2[1], b2[2], r1[0], r1[1], r1[2], r2[0], r2[1], r2[2], w1, w2, rot)
    return rot


def _wahba(b10, b11, b12, b20, b21, b22, r10, r11, r12, r20, r21, r22, w1, w2, rot):
    cb0, cb1, cb2 = _cross(b10, b11, b12, b20, b21, b22)
    cr0, cr1, cr2 = _cross(r10, r11, r12, r20, r21, r22)
    ncb = math.sqrt(cb0 * cb0 + cb1 * cb1 + cb2 * cb2)
    ncr = math.sqrt(cr0 * cr0 + cr1 * cr1 + cr2 * cr2)
    b30, b31, b32 = cb0 / ncb, cb1 / ncb, cb2 / ncb
    r30, r31, r32 = cr0 / ncr, cr1 / ncr, cr2 / ncr
    cos_diff = (b10 * b20 + b11 * b21 + b12 * b22) * (r10 * r20 + r11 * r21 + r12 * r22) + ncb * ncr
    lam = math.sqrt(max(1e-300, w1 * w1 + w2 * w2 + 2.0 * w1 * w2 * cos_diff))
    k1 = w1 / lam
    k2 = w2 / lam
    p0, p1, p2 = _cross(b10, b11, b12, b30, b31, b32)
    s0, s1, s2 = _cross(r10, r11, r12, r30, r31, r32)
    u0, u1, u2 = _cross(b20, b21, b22, b30, b31, b32)
    t0, t1, t2 = _cross(r20, r21, r22, r30, r31, r32)
    b = (b10, b11, b12, b20, b21, b22, b30, b31, b32, p0, p1, p2, u0, u1, u2)
    r = (r10, r11, r12, r20, r21, r22, r30, r31, r32, s0, s1, s2, t0, t1, t2)
    for i in range(3):  # rot = Aᵀ, A (world → sensor) of Markley's two-vector solution
        for j in range(3):
            rot[j, i] = (
                b[6 + i] * r[6 + j]
                + k1 * (b[i] * r[j] + b[9 + i] * r[9 + j])
                + k2 * (b[3 + i] * r[3 + j] + b[12 + i] * r[12 + j])
            )


def measurement(v0, v1, v2, v3, v4, v5, has_mag, m0, m1, m2, w_acc, w_mag, w, x, y, z, rot):
    """Measurement quaternion from (acc, mag) readings (sensor frame, any length), on the hemisphere
    of the prior (w, x, y, z). 9D: Wahba's problem on (up, acc) and (field m, mag); 6D: the prior tilted
    the least way that puts the accelerometer on world up (its heading kept)."""
    a0, a1, a2 = _unit(v0, v1, v2)
    if has_mag:
        h0, h1, h2 = _unit(v3, v4, v5)
        _wahba(a0, a1, a2, h0, h1, h2, 0.0, 0.0, 1.0, m0, m1, m2, w_acc, w_mag, rot)
        ow, ox, oy, oz = matrix_to_quaternion(
            rot[0, 0], rot[0, 1], rot[0, 2], rot[1, 0], rot[1, 1], rot[1, 2], rot[2, 0], rot[2, 1], rot[2, 2]
        )
    else:
        # u = R(prior) a: the measured up direction in the world
        ux = (1 - 2 * (y * y + z * z)) * a0 + 2 * (x * y - w * z) * a1 + 2 * (x * z + w * y) * a2
        uy = 2 * (x * y + w * z) * a0 + (1 - 2 * (x * x + z * z)) * a1 + 2 * (y * z - w * x) * a2
        uz = 2 * (x * z - w * y) * a0 + 2 * (y * z + w * x) * a1 + (1 - 2 * (x * x + y * y)) * a2
        dw, dx, dy = 1.0 + uz, uy, -ux  # shortest rotation u → e_z: [1 + u·e_z, u × e_z], normalised
        n = math.sqrt(dw * dw + dx * dx + dy * dy)
        if n < 1e-9:
            dw, dx, dy, n = 0.0, 1.0, 0.0, 1.0
        dw, dx, dy = dw / n, dx / n, dy / n
        ow = dw * w - dx * x - dy * y
        ox = dw * x + dx * w + dy * z
        oy = dw * y - dx * z + dy * w
        oz = dw * z + dx * y - dy * x
    if ow * w + ox * x + oy * y + oz * z < 0.0:
        return -ow, -ox, -oy, -oz
    return ow, ox, oy, oz


def step(
    st: np.ndarray,
    gx: float,
    gy: float,
    gz: float,
    v0: float,
    v1: float,
    v2: float,
    v3: float,
    v4: float,
    v5: float,
    has_mag: bool,
    dt: float,
    sa: float,
    sm: float,
) -> None:
    """One predict + update of the state ``st`` in place (layout above: q, P (4×4, row-major), the unit
    world field, σ_G per axis; out: the innovation z − q⁻ and the diagonal of its predicted covariance,
    for IAE). ``v``: accelerometer and magnetometer readings."""
    q = st[Q : Q + 4]
    P = st[P0 : P0 + 16].reshape(4, 4)
    mref = st[MREF : MREF + 3]
    sg = st[SG : SG + 3]
    innov = st[INNOV : INNOV + 4]
    s_diag = st[SDIAG : SDIAG + 4]
    v = np.empty(6)
    v[0], v[1], v[2], v[3], v[4], v[5] = v0, v1, v2, v3, v4, v5
    n = math.sqrt(gx * gx + gy * gy + gz * gz)
    half = 0.5 * n * dt
    c = math.cos(half)
    s = math.sin(half) / n if n > 1e-12 else 0.5 * dt
    pw, px, py, pz = c, gx * s, gy * s, gz * s
    # q⁻ = q ⊗ p = M q, M the right-multiplication matrix of p (thesis Eq 7-8, closed form)
    M = np.empty((4, 4))
    M[0, 0], M[0, 1], M[0, 2], M[0, 3] = pw, -px, -py, -pz
    M[1, 0], M[1, 1], M[1, 2], M[1, 3] = px, pw, pz, -py
    M[2, 0], M[2, 1], M[2, 2], M[2, 3] = py, -pz, pw, px
    M[3, 0], M[3, 1], M[3, 2], M[3, 3] = pz, py, -px, pw
    qp = np.zeros(4)
    for i in range(4):
        for k in range(4):
            qp[i] += M[i, k] * q[k]
    nq = math.sqrt(qp[0] * qp[0] + qp[1] * qp[1] + qp[2] * qp[2] + qp[3] * qp[3])
    w, x, y, z = qp[0] / nq, qp[1] / nq, qp[2] / nq, qp[3] / nq
    qp[0], qp[1], qp[2], qp[3] = w, x, y, z
    xi = np.empty((4, 3))  # q̇ = ½ Ξ ω
    xi[0, 0], xi[0, 1], xi[0, 2] = -x, -y, -z
    xi[1, 0], xi[1, 1], xi[1, 2] = w, -z, y
    xi[2, 0], xi[2, 1], xi[2, 2] = z, w, -x
    xi[3, 0], xi[3, 1], xi[3, 2] = -y, x, w
    MP = np.zeros((4, 4))
    for i in range(4):
        for j in range(4):
            for k in range(4):
                MP[i, j] += M[i, k] * P[k, j]
    Pp = np.zeros((4, 4))
    qs = 0.25 * dt * dt
    for i in range(4):
        for j in range(i, 4):
            acc = 0.0
            for k in range(4):
                acc += MP[i, k] * M[j, k]
            for k in range(3):  # 𝒬 = T²/4 Ξ Σ_G Ξᵀ (orientation.md §4.3)
                acc += qs * xi[i, k] * xi[j, k] * sg[k] * sg[k]
            Pp[i, j] = acc
            Pp[j, i] = acc
    rot = np.empty((3, 3))
    w_acc = 1.0 / (sa * sa)
    w_mag = 1.0 / (sm * sm)
    m0, m1, m2 = mref[0], mref[1], mref[2]
    zw, zx, zy, zz = measurement(
        v[0], v[1], v[2], v[3], v[4], v[5], has_mag, m0, m1, m2, w_acc, w_mag, w, x, y, z, rot
    )
    zq = (zw, zx, zy, zz)
    nin = 6 if has_mag else 3
    J = np.empty((4, 6))
    vp = v.copy()
    for k in range(nin):
        vp[k] = v[k] + _FD_STEP
        aw, ax, ay, az = measurement(
            vp[0], vp[1], vp[2], vp[3], vp[4], vp[5], has_mag, m0, m1, m2, w_acc, w_mag, w, x, y, z, rot
        )
        vp[k] = v[k] - _FD_STEP
        bw, bx, by, bz = measurement(
            vp[0], vp[1], vp[2], vp[3], vp[4], vp[5], has_mag, m0, m1, m2, w_acc, w_mag, w, x, y, z, rot
        )
        vp[k] = v[k]
        k2 = 0.5 / _FD_STEP
        J[0, k], J[1, k], J[2, k], J[3, k] = (aw - bw) * k2, (ax - bx) * k2, (ay - by) * k2, (az - bz) * k2
    S = np.empty((4, 4))
    hv = (-0.5 * z, -0.5 * y, 0.5 * x, 0.5 * w)  # ∂q/∂(heading about world z)
    for i in range(4):
        for j in range(i, 4):
            acc = Pp[i, j]
            for k in range(nin):  # ℛ_q = J diag(σ_A² I, σ_M² I) Jᵀ
                acc += J[i, k] * J[j, k] * (sa * sa if k < 3 else sm * sm)
            if not has_mag:  # the heading is not measured: a 1 rad² pseudo-variance about world z
                acc += hv[i] * hv[j]
            acc += _NORM_VARIANCE * zq[i] * zq[j]
            S[i, j] = acc
            S[j, i] = acc
        S[i, i] += _S_FLOOR
    K = np.linalg.solve(S, Pp).T  # P⁻ S⁻¹ (both symmetric)
    r0, r1, r2, r3 = zw - w, zx - x, zy - y, zz - z
    qn = np.empty(4)
    for i in range(4):
        qn[i] = qp[i] + K[i, 0] * r0 + K[i, 1] * r1 + K[i, 2] * r2 + K[i, 3] * r3
    Pn = np.empty((4, 4))
    for i in range(4):
        for j in range(i, 4):
            acc = Pp[i, j]
            for k in range(4):
                acc -= 0.5 * (K[i, k] * Pp[k, j] + K[j, k] * Pp[k, i])
            Pn[i, j] = acc
            Pn[j, i] = acc
    nq = math.sqrt(qn[0] * qn[0] + qn[1] * qn[1] + qn[2] * qn[2] + qn[3] * qn[3])
    for i in range(4):
        q[i] = qn[i] / nq
    # P⁺ projected on the tangent space of the unit sphere at q⁺ (T P T, T = I − q qᵀ): the norm is
    # fixed by normalising, so no variance is left along q itself
    Pq = np.zeros(4)
    for i in range(4):
        for k in range(4):
            Pq[i] += Pn[i, k] * q[k]
    qPq = q[0] * Pq[0] + q[1] * Pq[1] + q[2] * Pq[2] + q[3] * Pq[3]
    for i in range(4):
        for j in range(4):
            P[i, j] = Pn[i, j] - q[i] * Pq[j] - Pq[i] * q[j] + q[i] * q[j] * qPq
    for i in range(4):
        # Ŝ for IAE: P⁻ + ℛ of the sensors, without the pseudo-variances (norm, unmeasured heading)
        s_diag[i] = S[i, i] - _S_FLOOR - _NORM_VARIANCE * zq[i] * zq[i] - (0.0 if has_mag else hv[i] * hv[i])
    innov[0], innov[1], innov[2], innov[3] = r0, r1, r2, r3
