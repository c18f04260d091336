"""Per-sample kernel of Roetenberg(2005)'s indirect Kalman filter (``roetenberg_ikf``), numba-able.

The model and its READINGs are in :mod:`~gait_biofeedback.core.orientation.filters.roetenberg_ikf`.
Compiled by :func:`gait_biofeedback.core.jit.fast`; plain Python gives the same numbers.
"""

from __future__ import annotations

import math

import numpy as np

# layout of the state vector ``st``: quaternion, online gyro bias, linear acceleration (sensor frame,
# g), world magnetic field (units of ‖y_M,stat‖), a-priori error covariance P⁻ (12×12, row-major)
Q, BIAS, LIN, FIELD, PM, N_STATE = 0, 4, 7, 10, 13, 13 + 144
# noise and model constants ``c``
SG, SA, SM, ZETA, XI, GAMMA, NU, DECAY, M_EXP = range(9)


def step(
    st: np.ndarray,
    c: np.ndarray,
    gx: float,
    gy: float,
    gz: float,
    ax: float,
    ay: float,
    az: float,
    mx: float,
    my: float,
    mz: float,
    use_mag: bool,
    dt: float,
) -> bool:
    """One predict + correct of ``st`` in place; returns whether the magnetometer was used (not jammed)."""
    q = st[Q : Q + 4]
    b = st[BIAS : BIAS + 3]
    lin = st[LIN : LIN + 3]
    field = st[FIELD : FIELD + 3]
    pm = st[PM : PM + 144].reshape(12, 12)
    # 1. orientation from the gyro: q⁻ = q ⊗ exp(½ (ω − b) T)
    wx, wy, wz = gx - b[0], gy - b[1], gz - b[2]
    n = math.sqrt(wx * wx + wy * wy + wz * wz)
    half = 0.5 * n * dt
    cs = math.cos(half)
    sn = math.sin(half) / n if n > 1e-12 else 0.5 * dt
    pw, px, py, pz = cs, wx * sn, wy * sn, wz * sn
    w = q[0] * pw - q[1] * px - q[2] * py - q[3] * pz
    x = q[0] * px + q[1] * pw + q[2] * pz - q[3] * py
    y = q[0] * py - q[1] * pz + q[2] * pw + q[3] * px
    z = q[0] * pz + q[1] * py - q[2] * px + q[3] * pw
    nq = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / nq, x / nq, y / nq, z / nq
    r = np.empty((3, 3))  # R(q⁻), sensor → world
    r[0, 0], r[0, 1], r[0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)
    r[1, 0], r[1, 1], r[1, 2] = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
    r[2, 0], r[2, 1], r[2, 2] = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
    # 2. linear acceleration prior decays; gravity and field predicted from q⁻ (sensor frame)
    nu = c[NU]
    for i in range(3):
        lin[i] *= nu
    g = np.empty(3)
    h = np.empty(3)
    for i in range(3):
        g[i] = r[2, i]
        h[i] = r[0, i] * field[0] + r[1, i] * field[1] + r[2, i] * field[2]
    jammed = mx * mx + my * my + mz * mz > 4.0 * c[M_EXP] * c[M_EXP]
    nz = 6 if use_mag and not jammed else 3
    zv = np.empty(6)
    zv[0], zv[1], zv[2] = ax - lin[0] - g[0], ay - lin[1] - g[1], az - lin[2] - g[2]
    zv[3], zv[4], zv[5] = mx - h[0], my - h[1], mz - h[2]
    # 3. H = [[v]×, −κ[v]×, I, 0] (gravity rows), [[v]×, −κ[v]×, 0, I] (field rows), κ = T
    H = np.zeros((6, 12))
    for blk in range(2):
        v = g if blk == 0 else h
        o = 3 * blk
        H[o, 1], H[o, 2] = -v[2], v[1]
        H[o + 1, 0], H[o + 1, 2] = v[2], -v[0]
        H[o + 2, 0], H[o + 2, 1] = -v[1], v[0]
        for i in range(3):
            for j in range(3):
                H[o + i, 3 + j] = -dt * H[o + i, j]
            H[o + i, 6 + 3 * blk + i] = 1.0
    gyro_term = dt * dt * (c[ZETA] + c[SG] * c[SG])
    HP = np.zeros((nz, 12))
    for i in range(nz):
        for j in range(12):
            acc = 0.0
            for k in range(12):
                acc += H[i, k] * pm[k, j]
            HP[i, j] = acc
    S = np.empty((nz, nz))
    for i in range(nz):
        for j in range(nz):
            acc = 0.0
            for k in range(12):
                acc += HP[i, k] * H[j, k]
            S[i, j] = acc
        S[i, i] += (c[SA] * c[SA] if i < 3 else c[SM] * c[SM]) + gyro_term
    K = np.linalg.solve(S, HP).T  # P⁻Hᵀ S⁻¹ (12 × nz)
    e = np.zeros(12)
    for i in range(12):
        for k in range(nz):
            e[i] += K[i, k] * zv[k]
    pp = pm.copy()  # P⁺ = P⁻ − K H P⁻
    for i in range(12):
        for j in range(12):
            acc = 0.0
            for k in range(nz):
                acc += K[i, k] * HP[k, j]
            pp[i, j] -= acc
    # 4. corrections: q⁺ = q⁻ ⊗ [1, θ/2], b⁺ = b + δb, a⁺ = a⁻ + δa, field ← field + R(q⁺) δd
    tw, tx, ty, tz = 1.0, 0.5 * e[0], 0.5 * e[1], 0.5 * e[2]
    qw = w * tw - x * tx - y * ty - z * tz
    qx = w * tx + x * tw + y * tz - z * ty
    qy = w * ty - x * tz + y * tw + z * tx
    qz = w * tz + x * ty - y * tx + z * tw
    nq = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    q[0], q[1], q[2], q[3] = qw / nq, qx / nq, qy / nq, qz / nq
    for i in range(3):
        b[i] += e[3 + i]
        lin[i] += e[6 + i]
    if nz == 6:
        for i in range(3):
            field[i] += r[i, 0] * e[9] + r[i, 1] * e[10] + r[i, 2] * e[11]
        # the field keeps its inclination and the expected strength, horizontal part along north (+y)
        incl = math.atan2(field[2], math.hypot(field[0], field[1]))
        field[0], field[1], field[2] = 0.0, c[M_EXP] * math.cos(incl), c[M_EXP] * math.sin(incl)
    # 5. next a-priori covariance from the P⁺ blocks (the error state is reset after each correction)
    pm[:, :] = 0.0
    decay = c[DECAY]
    for i in range(3):
        for j in range(3):
            pbb = pp[3 + i, 3 + j] + (c[ZETA] if i == j else 0.0)
            pm[i, j] = pp[i, j] + dt * dt * pbb + (dt * dt * c[SG] * c[SG] if i == j else 0.0)
            pm[i, 3 + j] = -dt * pbb
            pm[3 + i, j] = -dt * pbb
            pm[3 + i, 3 + j] = pbb
            pm[6 + i, 6 + j] = nu * nu * pp[6 + i, 6 + j] + (c[XI] if i == j else 0.0)
            pm[9 + i, 9 + j] = decay * decay * pp[9 + i, 9 + j] + (c[GAMMA] if i == j else 0.0)
    return nz == 6
