"""Zero-velocity-aided error-state Kalman filter of one foot IMU, Suh 2014 §3 (gait.md §4.3).

Nominal state: orientation ``q`` (sensor → world, world z up, heading arbitrary), position ``r`` and
velocity ``v`` (world, m, m/s), gyro and accelerometer biases ``b_g``, ``b_a`` (sensor frame, constant).
The error state is 15 × 1, ``[δθ, δr, δv, δb_g, δb_a]``.

- ``δθ`` is the rotation vector of the local error, ``q = q̂ ⊗ exp(δθ)``. Suh's ``q̄`` is
  ``δθ / 2`` (Eq 8): the same model with the attitude rows scaled by 2, which is why the ``½`` and
  ``2`` of Suh's ``A_k`` (Eq 11) are absent here.
- Convention: Suh's ``C(q)`` maps navigation → body, the project's orientation sensor → world; the
  ``C'`` of Eq 11 is :func:`~gait_biofeedback.core.quaternion.as_matrix` here.

Propagation (Suh Eq 6-7 and 10-12): the strap-down step with the bias-corrected gyro and
accelerometer, and the transition ``Φ = I + A T + ½ (A T)²`` of

    A = [[-[ω×], 0, 0, -I, 0], [0, 0, I, 0, 0], [-R [f×], 0, 0, 0, -R], 0, 0]

with ``ω = y_g - b̂_g`` and ``f = y_a - b̂_a``.

Process noise: ``Q = ∫ e^{A₁τ} diag(R_g, R_r, R_a) e^{A₁'τ} dτ``, taken to second order in T (the
EXT of gait.md §4.3). ``R_g`` and ``R_a`` are the white-noise densities of Suh Table 1, and
``R_r = 10⁻⁶`` keeps Q invertible for the smoother.

Measurements at zero-velocity samples only: ``v = 0`` (Eq 13) and, with ``flat_floor``, ``r_z = 0``
(Eq 14). The update is injected into the nominal state and the error mean reset (§3.3).

Initialisation (§3.1), READING: Suh's TRIAD from the first sample (vertical from the accelerometer,
heading zero) is taken over the first zero-velocity samples when the recording starts at rest, else
the first sample. ``P_q,init`` is given as the tilt error the accelerometer noise leaves
(``R_a / g²`` per tilt axis) and 10⁻¹¹ for the heading Suh sets to zero: an approximation of Shuster
& Oh's covariance.

Every step is kept as a :class:`KalmanStep` for the smoothers (:mod:`.smoother`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gait_biofeedback.core import quaternion as quat

GRAVITY = 9.8  # m/s², Suh's g̃ = [0, 0, 9.8]
STATES = 15
NAV = 9  # attitude, position, velocity: the smoother's X_SM (Suh Eq 17)


@dataclass(frozen=True)
class KalmanNoise:
    """Suh Table 1 (units: white-noise densities, (rad/s)²·s and (m/s²)²·s; variances in m², ...)."""

    gyro: float = 1e-3  # R_g
    acc: float = 1e-2  # R_a
    position: float = 1e-6  # the position process noise that keeps Q invertible
    zero_velocity: float = 1e-4  # R_v, (m/s)²
    floor: float = 1e-4  # R_r, m²
    position_init: float = 1e-4  # P_r,init, m²
    velocity_init: float = 1e-4  # P_v,init, (m/s)²
    gyro_bias_init: float = 1e-6  # P_bg,init, (rad/s)²
    acc_bias_init: float = 1e-6  # P_ba,init, (m/s²)²
    heading_init: float = 1e-11  # rad², the heading set to zero


@dataclass
class KalmanStep:
    """One sample of the filter: the state after its update (``q``, ``r``, ``v``, ``b``: the 6 biases,
    gyro then accelerometer), the covariance before (``p_prior``) and after (``p_post``) it, the
    update ``dx`` injected at this sample (zeros when there was none), the measurement residual and
    whether the sample was at zero velocity; ``phi``/``q_noise``: the transition to the next sample."""

    q: np.ndarray
    r: np.ndarray
    v: np.ndarray
    b: np.ndarray
    p_prior: np.ndarray
    p_post: np.ndarray
    dx: np.ndarray
    zero_velocity: bool
    phi: np.ndarray | None = None
    q_noise: np.ndarray | None = None


def skew(v: np.ndarray) -> np.ndarray:
    """``[v×]``: ``skew(a) @ b == cross(a, b)``."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def initial_orientation(acc: np.ndarray) -> np.ndarray:
    """TRIAD with the heading zero (Suh §3.1): the rotation taking the measured up to world z whose
    sensor x axis keeps a zero world heading (x axis in the world x-z plane)."""
    up = np.asarray(acc, float) / np.linalg.norm(acc)
    x = np.array([1.0, 0.0, 0.0]) - up[0] * up  # sensor x without its vertical part
    if np.linalg.norm(x) < 1e-6:  # sensor x vertical: use sensor y for the heading
        x = np.array([0.0, 1.0, 0.0]) - up[1] * up
    x /= np.linalg.norm(x)
    y = np.cross(up, x)
    # rows: the world axes in sensor coordinates -> R (sensor -> world) has them as rows
    return quat.from_matrix(np.stack([x, y, up]))


def transition(omega: np.ndarray, f: np.ndarray, rot: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """``Φ = I + A T + ½ (A T)²`` (Suh Eq 12) of the error model above, and ``A₁`` (its 9 × 9 part)."""
    a = np.zeros((STATES, STATES))
    a[0:3, 0:3] = -skew(omega)
    a[0:3, 9:12] = -np.eye(3)
    a[3:6, 6:9] = np.eye(3)
    a[6:9, 0:3] = -rot @ skew(f)
    a[6:9, 12:15] = -rot
    at = a * dt
    return np.eye(STATES) + at + 0.5 * at @ at, a[:NAV, :NAV]


def process_noise(a_nav: np.ndarray, noise: KalmanNoise, dt: float) -> np.ndarray:
    """``∫₀ᵀ e^{A₁τ} Q_c e^{A₁'τ} dτ`` to second order: ``Q_c T + (A₁Q_c + Q_cA₁') T²/2 + A₁Q_cA₁' T³/3``."""
    qc = np.diag([noise.gyro] * 3 + [noise.position] * 3 + [noise.acc] * 3)
    aq = a_nav @ qc
    return qc * dt + (aq + aq.T) * dt**2 / 2.0 + aq @ a_nav.T * dt**3 / 3.0


class FootKalman:
    """The filter of one foot. :meth:`start` sets the initial state at a stance sample;
    :meth:`update` propagates over ``dt`` with the previous sample's gyro and acceleration and applies
    the measurements of the new sample. :attr:`last` is the last :class:`KalmanStep` (its ``phi`` is
    set by the next update); :attr:`steps` keeps them all when ``keep``."""

    def __init__(self, noise: KalmanNoise | None = None, flat_floor: bool = True, keep: bool = True) -> None:
        self.noise = noise or KalmanNoise()
        self.flat_floor = flat_floor
        self.keep = keep
        self.steps: list[KalmanStep] = []
        self.last: KalmanStep | None = None

    def start(self, vertical: np.ndarray, gyr: np.ndarray, acc: np.ndarray, zero_velocity: bool = True,
              bias: np.ndarray | None = None) -> KalmanStep:
        """First sample: attitude from ``vertical`` (an acceleration at rest, e.g. a stance's mean),
        the sample's own ``gyr``/``acc`` (they act over the next interval), the 6 biases' prior."""
        n = self.noise
        self.q = initial_orientation(vertical)
        self.r = np.zeros(3)
        self.v = np.zeros(3)
        self.b = np.zeros(6) if bias is None else np.asarray(bias, float).copy()
        tilt = n.acc / GRAVITY**2
        # the attitude error is local (sensor frame): the heading variance is about the world z
        rot = _matrix(self.q)
        att_world = np.diag([tilt, tilt, n.heading_init])
        self.p = np.zeros((STATES, STATES))
        self.p[0:3, 0:3] = rot.T @ att_world @ rot
        self.p[3:6, 3:6] = np.eye(3) * n.position_init
        self.p[6:9, 6:9] = np.eye(3) * n.velocity_init
        self.p[9:12, 9:12] = np.eye(3) * n.gyro_bias_init
        self.p[12:15, 12:15] = np.eye(3) * n.acc_bias_init
        self._input = (np.asarray(gyr, float), np.asarray(acc, float))
        return self._measure(zero_velocity)

    def update(self, gyr: np.ndarray, acc: np.ndarray, dt: float, zero_velocity: bool) -> KalmanStep:
        """Propagate from the previous sample over ``dt`` and measure at this one, whose ``gyr``/``acc``
        act over the next interval."""
        self._propagate(*self._input, dt)
        self._input = (np.asarray(gyr, float), np.asarray(acc, float))
        return self._measure(zero_velocity)

    def _propagate(self, gyr: np.ndarray, acc: np.ndarray, dt: float) -> None:
        omega = gyr - self.b[:3]
        f = acc - self.b[3:]
        rot = _matrix(self.q)
        phi, a_nav = transition(omega, f, rot, dt)
        q_noise = np.zeros((STATES, STATES))
        q_noise[:NAV, :NAV] = process_noise(a_nav, self.noise, dt)
        self.last.phi = phi
        self.last.q_noise = q_noise
        acc_world = _matrix(_times_rotvec(self.q, omega * (dt / 2.0))) @ f - np.array([0.0, 0.0, GRAVITY])
        self.q = _times_rotvec(self.q, omega * dt)
        self.r = self.r + self.v * dt + 0.5 * acc_world * dt**2
        self.v = self.v + acc_world * dt
        self.p = phi @ self.p @ phi.T + q_noise

    def _measure(self, zero_velocity: bool) -> KalmanStep:
        p_prior = self.p
        dx = np.zeros(STATES)
        if zero_velocity:
            rows = 4 if self.flat_floor else 3
            h = np.zeros((rows, STATES))
            h[0:3, 6:9] = np.eye(3)
            residual = -self.v
            r_diag = [self.noise.zero_velocity] * 3
            if self.flat_floor:
                h[3, 5] = 1.0
                residual = np.append(residual, -self.r[2])
                r_diag.append(self.noise.floor)
            s = h @ p_prior @ h.T + np.diag(r_diag)
            gain = np.linalg.solve(s, h @ p_prior).T
            dx = gain @ residual
            ikh = np.eye(STATES) - gain @ h
            self.p = ikh @ p_prior @ ikh.T + gain @ np.diag(r_diag) @ gain.T  # Joseph form
            self._inject(dx)
        step = KalmanStep(self.q, self.r, self.v, self.b, p_prior, self.p, dx, zero_velocity)
        self.last = step
        if self.keep:
            self.steps.append(step)
        return step

    def _inject(self, dx: np.ndarray) -> None:
        self.q = _times_rotvec(self.q, dx[0:3])
        self.r = self.r + dx[3:6]
        self.v = self.v + dx[6:9]
        self.b = self.b + dx[9:15]


def _times_rotvec(q: np.ndarray, rv: np.ndarray) -> np.ndarray:
    """``q ⊗ exp(rv)`` normalised, in scalars (the per-sample path; :mod:`quaternion` broadcasts)."""
    x, y, z = float(rv[0]), float(rv[1]), float(rv[2])
    angle = math.sqrt(x * x + y * y + z * z)
    bw = math.cos(angle / 2.0)
    k = math.sin(angle / 2.0) / angle if angle > 1e-9 else 0.5
    bx, by, bz = x * k, y * k, z * k
    aw, ax, ay, az = (float(c) for c in q)
    out = np.array([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                    aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw])
    return out / math.sqrt(float(out @ out))


def _matrix(q: np.ndarray) -> np.ndarray:
    """``R(q)`` of a unit quaternion, in scalars."""
    w, x, y, z = (float(c) for c in q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
