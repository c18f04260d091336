"""The covariance arithmetic of the foot's Kalman filter (:mod:`.kalman`), numba-able.

One sample's propagation (Suh Eq 10-12 and the second-order process noise of the module docstring of
:mod:`.kalman`) and zero-velocity update (Eq 13-14, Joseph form) on the 15 x 15 covariance, written as
loops over the matrices' entries: numpy spent about 60 us per sample on some twenty calls on 3 x 3 to
15 x 15 arrays (a tenth of ``analyze``), compiled this takes a few. Compiled by
:func:`gait_biofeedback.core.jit.fast`; plain Python gives the same numbers (only +, -, *, / in a fixed
order), much more slowly.

The whole per-sample step (issue 46) is here too: :func:`foot_step` (strap-down propagation, shock
gain, covariance, measurements and injection over a state array) and :func:`foot_run`, the same over
whole arrays. They repeat :mod:`gait_biofeedback.core.orientation.filters._scalar`'s quaternion
arithmetic term for term, so that the numbers are those of the numpy code before them, but for the
shock gain's norm: ``sqrt(x² + y² + z²)`` here, numpy's a BLAS dot that may fuse multiply-adds
(the machine's; ~1e-15 relative).
"""

from __future__ import annotations

import math

import numpy as np

from gait_biofeedback.core.orientation.filters._scalar import half_turn

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


# ---- the whole per-sample step (issue 46) ------------------------------------------------------
# nominal state ``s`` (float64): q (w, x, y, z), r, v, b (gyro, accelerometer), the stance so far and
# the last stance's duration (s; NaN so far: in a swing), the previous sample's gyro and acceleration
Q, R, V, B, RUN, STANCE, INPUT = 0, 4, 7, 10, 16, 17, 18
N_STATE = 24
# parameters ``kp``: Q_c's diagonal (9), the shock threshold, shock_stance_s, flat floor (1.0 / 0.0)
K_DENSITY, K_SHOCK, K_SHOCK_STANCE, K_FLAT = 0, 9, 10, 11
N_KP = 12
GRAVITY = 9.8  # m/s², :data:`.kalman.GRAVITY`
SHOCK_SCALE = 2.0  # m/s², :data:`.kalman.SHOCK_SCALE`


def _turn(s: np.ndarray, wx: float, wy: float, wz: float, dt: float) -> tuple:
    """``q ⊗ exp(½ ω dt)`` of the state's ``q``
    (:func:`gait_biofeedback.core.orientation.filters._scalar.gyro_step`)."""
    c, k = half_turn(wx, wy, wz, dt)
    pw, px, py, pz = s[Q], s[Q + 1], s[Q + 2], s[Q + 3]
    qx, qy, qz = wx * k, wy * k, wz * k
    return (pw * c - px * qx - py * qy - pz * qz, pw * qx + px * c + py * qz - pz * qy,
            pw * qy - px * qz + py * c + pz * qx, pw * qz + px * qy - py * qx + pz * c)


def _set_q(s: np.ndarray, w: float, x: float, y: float, z: float) -> None:
    """The state's ``q`` = the unit quaternion along (w, x, y, z)
    (:func:`gait_biofeedback.core.orientation.filters._scalar.normalized`)."""
    n = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
    s[Q], s[Q + 1], s[Q + 2], s[Q + 3] = w * n, x * n, y * n, z * n


def shock_gain(fx: float, fy: float, fz: float, shock: float) -> float:
    """The factor of ``R_a`` for the specific force ``f`` (:func:`.kalman.shock_gain`)."""
    excess = abs(math.sqrt(fx * fx + fy * fy + fz * fz) - GRAVITY) - shock
    return 1.0 + (excess / SHOCK_SCALE) ** 2 if excess > 0.0 else 1.0


def foot_measure(s: np.ndarray, p_prior: np.ndarray, kp: np.ndarray, rows: np.ndarray, variance: np.ndarray,
                 zero_velocity: bool, p_post: np.ndarray, dx: np.ndarray) -> int:
    """The measurements of a sample (as :meth:`.kalman.FootKalman.start` and
    :meth:`~.kalman.FootKalman.update` measure): at zero velocity ``v = 0`` and with a flat floor
    ``r_z = 0`` (Suh Eq 13-14, Joseph form) into ``p_post`` and ``dx``, injected into ``s``; else
    ``p_post`` = ``p_prior`` and ``dx`` = 0."""
    if not zero_velocity:
        for i in range(N):
            dx[i] = 0.0
            for j in range(N):
                p_post[i, j] = p_prior[i, j]
        return 0
    residual = np.empty(rows.shape[0])
    for i in range(3):
        residual[i] = -s[V + i]
    if kp[K_FLAT]:
        residual[3] = -s[R + 2]
    measure(p_prior, rows, residual, variance, dx, p_post)
    w, x, y, z = _turn(s, dx[0], dx[1], dx[2], 1.0)
    _set_q(s, w, x, y, z)
    for i in range(3):
        s[R + i] = s[R + i] + dx[3 + i]
        s[V + i] = s[V + i] + dx[6 + i]
    for i in range(6):
        s[B + i] = s[B + i] + dx[9 + i]
    return 0


def foot_step(s: np.ndarray, p: np.ndarray, kp: np.ndarray, rows: np.ndarray, variance: np.ndarray, gx: float,
              gy: float, gz: float, ax: float, ay: float, az: float, dt: float, zero_velocity: bool,
              phi: np.ndarray, q_noise: np.ndarray, p_prior: np.ndarray, p_post: np.ndarray,
              dx: np.ndarray) -> int:
    """One sample of the foot's filter (:meth:`.kalman.FootKalman.update`): the strap-down step of q, r,
    v over ``dt`` with the previous sample's bias-corrected gyro and acceleration (the specific force
    turned to the world at the half step), the covariance ``p`` → ``p_prior`` (``phi``, ``q_noise``:
    the transition; the accelerometer's density times the shock gain after a stance of at least
    ``shock_stance_s``), then this sample's measurements (:func:`foot_measure`); its ``gyr``/``acc``
    act over the next interval."""
    wx, wy, wz = s[INPUT] - s[B], s[INPUT + 1] - s[B + 1], s[INPUT + 2] - s[B + 2]
    fx, fy, fz = s[INPUT + 3] - s[B + 3], s[INPUT + 4] - s[B + 4], s[INPUT + 5] - s[B + 5]
    gain = shock_gain(fx, fy, fz, kp[K_SHOCK]) if s[STANCE] >= kp[K_SHOCK_STANCE] else 1.0
    density = np.empty(NAV)
    for i in range(NAV):
        density[i] = kp[K_DENSITY + i]
    if gain != 1.0:
        for i in range(6, 9):
            density[i] *= gain
    w, x, y, z = s[Q], s[Q + 1], s[Q + 2], s[Q + 3]
    rot = np.empty((3, 3))
    rot[0, 0], rot[0, 1] = 1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z)
    rot[0, 2], rot[1, 0] = 2.0 * (x * z + w * y), 2.0 * (x * y + w * z)
    rot[1, 1], rot[1, 2] = 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)
    rot[2, 0], rot[2, 1] = 2.0 * (x * z - w * y), 2.0 * (y * z + w * x)
    rot[2, 2] = 1.0 - 2.0 * (x * x + y * y)
    omega = np.empty(3)
    omega[0], omega[1], omega[2] = wx, wy, wz
    f = np.empty(3)
    f[0], f[1], f[2] = fx, fy, fz
    propagate(p, omega, f, rot, dt, density, phi, q_noise, p_prior)
    w, x, y, z = _turn(s, wx, wy, wz, dt / 2.0)
    acc_world = (
        (1.0 - 2.0 * (y * y + z * z)) * fx + 2.0 * (x * y - w * z) * fy + 2.0 * (x * z + w * y) * fz,
        2.0 * (x * y + w * z) * fx + (1.0 - 2.0 * (x * x + z * z)) * fy + 2.0 * (y * z - w * x) * fz,
        2.0 * (x * z - w * y) * fx + 2.0 * (y * z + w * x) * fy + (1.0 - 2.0 * (x * x + y * y)) * fz
        - GRAVITY)
    w, x, y, z = _turn(s, wx, wy, wz, dt)
    _set_q(s, w, x, y, z)
    for i in range(3):
        s[R + i] = s[R + i] + s[V + i] * dt + 0.5 * acc_world[i] * dt ** 2
        s[V + i] = s[V + i] + acc_world[i] * dt
    s[INPUT], s[INPUT + 1], s[INPUT + 2], s[INPUT + 3], s[INPUT + 4], s[INPUT + 5] = gx, gy, gz, ax, ay, az
    if zero_velocity:
        s[RUN] = (0.0 if math.isnan(s[RUN]) else s[RUN]) + dt  # each zero-velocity sample stands for dt
    elif not math.isnan(s[RUN]):  # a stance ended at the previous sample
        s[STANCE], s[RUN] = s[RUN], math.nan
    return foot_measure(s, p_prior, kp, rows, variance, zero_velocity, p_post, dx)


def foot_run(s: np.ndarray, p: np.ndarray, kp: np.ndarray, rows: np.ndarray, variance: np.ndarray,
             gyr: np.ndarray, acc: np.ndarray, dt: np.ndarray, zero_velocity: np.ndarray, phi: np.ndarray,
             q_noise: np.ndarray, p_prior: np.ndarray, p_post: np.ndarray, dx: np.ndarray,
             states: np.ndarray) -> int:
    """:func:`foot_step` of each row (gyro, acc (n, 3), dt, zero_velocity (n,)) from the covariance
    ``p``: each row's transition into it, covariances, update and state (``states`` (n, 16): q, r, v,
    b) in the row of the (n, ...) outputs."""
    for j in range(gyr.shape[0]):
        foot_step(s, p if j == 0 else p_post[j - 1], kp, rows, variance, gyr[j, 0], gyr[j, 1], gyr[j, 2],
                  acc[j, 0], acc[j, 1], acc[j, 2], dt[j], zero_velocity[j], phi[j], q_noise[j], p_prior[j],
                  p_post[j], dx[j])
        for i in range(16):
            states[j, i] = s[i]
    return 0
