"""The covariance arithmetic of the foot's Kalman filter (:mod:`.kalman`), numba-able.

One sample's propagation (Suh Eq 10-12 and the second-order process noise of the module docstring of
:mod:`.kalman`) and zero-velocity update (Eq 13-14, Joseph form) on the 15 x 15 covariance, written as
loops over the matrices' entries: numpy spent about 60 us per sample on some twenty calls on 3 x 3 to
15 x 15 arrays (a tenth of ``analyze``), compiled this takes a few. Compiled by
:func:`gait_biofeedback.core.jit.fast`; plain Python gives the same numbers (only +, -, *, / in a fixed
order), much more slowly.
"""

from __future__ import annotations

import numpy as np

N = 15  # error state: attitude, position, velocity, gyro bias, accelerometer bias
NAV = 9  # the states the process noise drives


def _product(a: np.ndarray, b: np.ndarray, out: np.ndarray, b_transposed: bool) -> None:
    """``out = a @ b`` (or ``a @ b.T``), square matrices, summed over k in order."""
    n = a.shape[0]
    for i in range(n):
        for j in range(n):
            s = 0.0
            for k in range(n):
                s += a[i, k] * (b[j, k] if b_transposed else b[k, j])
            out[i, j] = s


def propagate(p: np.ndarray, omega: np.ndarray, f: np.ndarray, rot: np.ndarray, dt: float,
              density: np.ndarray, phi: np.ndarray, q_noise: np.ndarray, p_next: np.ndarray) -> int:
    """``phi = I + A T + (A T)² / 2``, ``q_noise`` (its 9 x 9 block ``Q_c T + (A₁Q_c + Q_cA₁') T²/2 +
    A₁Q_cA₁' T³/3``, the rest 0) and ``p_next = phi p phi' + q_noise`` for the bias-corrected rate
    ``omega``, specific force ``f`` and attitude matrix ``rot`` (sensor → world) over ``dt``;
    ``density``: the 9 diagonal entries of ``Q_c`` (gyro, position, accelerometer noise densities)."""
    a = np.zeros((N, N))
    wx, wy, wz = omega[0], omega[1], omega[2]
    a[0, 1], a[0, 2], a[1, 0], a[1, 2], a[2, 0], a[2, 1] = wz, -wy, -wz, wx, wy, -wx  # -[ω×]
    for i in range(3):
        a[i, 9 + i] = -1.0
        a[3 + i, 6 + i] = 1.0
        # -R [f×]: row i of R times the columns of [f×]
        r0, r1, r2 = rot[i, 0], rot[i, 1], rot[i, 2]
        a[6 + i, 0] = -(r1 * f[2] - r2 * f[1])
        a[6 + i, 1] = -(r2 * f[0] - r0 * f[2])
        a[6 + i, 2] = -(r0 * f[1] - r1 * f[0])
        for j in range(3):
            a[6 + i, 12 + j] = -rot[i, j]
    at = a * dt
    half = at * 0.5
    _product(half, at, phi, False)
    for i in range(N):
        for j in range(N):
            phi[i, j] += at[i, j]
        phi[i, i] += 1.0
    # A₁Q_c with Q_c diagonal: column j scaled
    aq = np.zeros((NAV, NAV))
    for i in range(NAV):
        for j in range(NAV):
            aq[i, j] = a[i, j] * density[j]
    dt2, dt3 = dt * dt / 2.0, dt * dt * dt / 3.0
    q_noise[:, :] = 0.0
    for i in range(NAV):
        for j in range(NAV):
            s = 0.0
            for k in range(NAV):
                s += aq[i, k] * a[j, k]
            q_noise[i, j] = (aq[i, j] + aq[j, i]) * dt2 + s * dt3
        q_noise[i, i] += density[i] * dt
    phi_p = np.empty((N, N))
    _product(phi, p, phi_p, False)
    _product(phi_p, phi, p_next, True)
    for i in range(N):
        for j in range(N):
            p_next[i, j] += q_noise[i, j]
    return 0


def measure(p: np.ndarray, rows: np.ndarray, residual: np.ndarray, variance: np.ndarray, dx: np.ndarray,
            p_post: np.ndarray) -> int:
    """The update of measurements that each read one error state (``rows``: its index per measurement,
    velocity x, y, z and with a flat floor the height), ``residual`` their innovations and
    ``variance`` their noise: ``K = P H' (H P H' + R)⁻¹``, ``dx = K residual`` and the Joseph form
    ``p_post = (I - K H) P (I - K H)' + K R K'``. ``H P H' + R`` is solved by Gaussian elimination
    with partial pivoting."""
    m = rows.shape[0]
    s = np.empty((m, m))
    hp = np.empty((m, N))  # H P, then S⁻¹ H P
    for i in range(m):
        for j in range(m):
            s[i, j] = p[rows[i], rows[j]]
        s[i, i] += variance[i]
        for j in range(N):
            hp[i, j] = p[rows[i], j]
    for col in range(m):
        pivot = col
        for i in range(col + 1, m):
            if abs(s[i, col]) > abs(s[pivot, col]):
                pivot = i
        if pivot != col:
            for j in range(m):
                s[col, j], s[pivot, j] = s[pivot, j], s[col, j]
            for j in range(N):
                hp[col, j], hp[pivot, j] = hp[pivot, j], hp[col, j]
        for i in range(col + 1, m):
            factor = s[i, col] / s[col, col]
            for j in range(col, m):
                s[i, j] -= factor * s[col, j]
            for j in range(N):
                hp[i, j] -= factor * hp[col, j]
    for i in range(m - 1, -1, -1):
        for j in range(N):
            t = hp[i, j]
            for k in range(i + 1, m):
                t -= s[i, k] * hp[k, j]
            hp[i, j] = t / s[i, i]
    # K = (S⁻¹ H P)' (P symmetric); I - K H subtracts K's columns at the measured states
    ikh = np.zeros((N, N))
    for i in range(N):
        ikh[i, i] = 1.0
    for i in range(N):
        t = 0.0
        for j in range(m):
            t += hp[j, i] * residual[j]
            ikh[i, rows[j]] -= hp[j, i]
        dx[i] = t
    tmp = np.empty((N, N))
    _product(ikh, p, tmp, False)
    _product(tmp, ikh, p_post, True)
    for i in range(N):
        for j in range(N):
            t = 0.0
            for k in range(m):
                t += hp[k, i] * variance[k] * hp[k, j]
            p_post[i, j] += t
    return 0
