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
EXT of gait.md §4.3). ``R_g`` and ``R_a`` are white-noise densities (Suh Table 1's values are the
defaults of :class:`KalmanNoise`; the foot-trajectory stage's own are in its parameters), and
``R_r = 10⁻⁶`` keeps Q invertible for the smoother.

EXT, shocks: an accelerometer is not as good in a heel strike as in the swing (its range, its
mounting's resonance, its nonlinearity). With ``acc_shock``, the density of a sample whose specific
force is more than ``acc_shock`` off gravity grows as ``R_a (1 + (excess / 2 m/s²)²)``. The
velocity error that the next stance reveals is then put mostly in the impact that made it, instead of
being spread over the swing as a drift. The foot-trajectory stage uses 30 m/s² (about 3 g); on
gaitmap_example's 56 mocap strides (benchmarks/spatial.py) the stride-length SD drops from 4.5 to
1.7 cm; on pyshoe_vicon's walking trials it changes nothing.

EXT, ``shock_stance_s``: the shock noise applies only in a swing whose stance before it lasted at least
``shock_stance_s`` s (the first stance counts as long). Running's stances (10-70 ms; a valley is
15 ms at 200 Hz) hold the velocity at zero too briefly to pin the velocity error an impact made, and
its shocks are many: with the shock noise in every swing pyshoe_vicon's 9 running trials scored a mean
ARMSE of 0.139 m, without it 0.080 m. The foot-trajectory stage uses 0.05 s: running 0.077 m, and
walking's stances (0.2-0.5 s) keep the noise (benchmarks/spatial.py; chosen on half of the trials,
docs/benchmarks/spatial.md).

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

from gait_biofeedback.core.jit import fast
from gait_biofeedback.core.orientation.filters import _scalar as scalar
from gait_biofeedback.core.orientation.filters.startup import attitude_from_vectors
from gait_biofeedback.core.spatial import _kalman_kernel as kernel

GRAVITY = 9.8  # m/s², Suh's g̃ = [0, 0, 9.8]
SHOCK_SCALE = 2.0  # m/s²: excess over acc_shock that doubles the accelerometer's noise density
STATES = kernel.N  # the error state: attitude, position, velocity, gyro and accelerometer biases
NAV = kernel.NAV  # attitude, position, velocity: the smoother's X_SM (Suh Eq 17)


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
    acc_shock: float = math.inf  # m/s²: |f| this far off gravity is a shock (module docstring)
    shock_stance_s: float = 0.0  # s: shocks only in a swing after a stance at least this long (EXT)


@dataclass
class KalmanStep:
    """One sample of the filter: the state after its update (``q``, ``r``, ``v``, ``b``: the 6 biases,
    gyro then accelerometer), the covariance before (``p_prior``) and after (``p_post``) it, the
    update ``dx`` injected at this sample (zeros when there was none), the measurement residual and
    whether the sample was at zero velocity; ``phi``/``q_noise``: the transition to the next sample."""

    q: tuple[float, float, float, float]
    r: np.ndarray
    v: np.ndarray
    b: np.ndarray
    p_prior: np.ndarray
    p_post: np.ndarray
    dx: np.ndarray
    zero_velocity: bool
    phi: np.ndarray | None = None
    q_noise: np.ndarray | None = None


_ROWS = np.array([6, 7, 8])  # the zero-velocity update's measured states: velocity x, y, z
_ROWS_FLOOR = np.array([6, 7, 8, 5])  # and with a flat floor the height


def kernels() -> tuple:
    """(propagate, measure) of :mod:`._kalman_kernel`, compiled (:func:`~gait_biofeedback.core.jit.fast`:
    once per process, seconds on a first run, then loaded from numba's disk cache). The foot-trajectory
    stream asks at its start, not at the first stance: a live node compiling mid-session stalled its
    executor and lost samples."""
    p, out = np.eye(STATES), np.empty((STATES, STATES))
    warmup = (p, np.ones(3), np.ones(3), np.eye(3), 0.01, np.ones(9), out, out.copy(), out.copy())
    return (fast(kernel, "propagate", warmup, helpers=["_product"]),
            fast(kernel, "measure", (p, _ROWS_FLOOR, np.ones(4), np.ones(4), np.empty(STATES), out),
                 helpers=["_product"]))


def shock_gain(f: np.ndarray, noise: KalmanNoise) -> float:
    """The factor of ``R_a`` for the specific force ``f`` (module docstring, shocks)."""
    excess = abs(float(np.linalg.norm(f)) - GRAVITY) - noise.acc_shock
    return 1.0 + (excess / SHOCK_SCALE) ** 2 if excess > 0.0 else 1.0


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
        self._run_s: float | None = None  # s: the stance in progress so far (None: in a swing)
        self._stance_s = math.inf  # s: the last stance's duration (the first stance: unknown, long)
        self.last: KalmanStep | None = None
        self._kernels = kernels()
        n = self.noise
        self._density = np.array((n.gyro,) * 3 + (n.position,) * 3 + (n.acc,) * 3)  # Q_c's diagonal
        self._zero_velocity = ((_ROWS_FLOOR, np.array((n.zero_velocity,) * 3 + (n.floor,))) if flat_floor
                               else (_ROWS, np.array((n.zero_velocity,) * 3)))  # measured states, R

    def start(self, vertical: np.ndarray, gyr: np.ndarray, acc: np.ndarray, zero_velocity: bool = True,
              bias: np.ndarray | None = None) -> KalmanStep:
        """First sample: attitude from ``vertical`` (an acceleration at rest, e.g. a stance's mean),
        the sample's own ``gyr``/``acc`` (they act over the next interval), the 6 biases' prior."""
        n = self.noise
        self.q = tuple(attitude_from_vectors(vertical).tolist())  # TRIAD, heading zero
        self.r = np.zeros(3)
        self.v = np.zeros(3)
        self.b = np.zeros(6) if bias is None else np.asarray(bias, float).copy()
        tilt = n.acc / GRAVITY**2
        # the attitude error is local (sensor frame): the heading variance is about the world z
        rot = np.array(scalar.matrix(self.q))
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
        if zero_velocity:
            self._run_s = (self._run_s or 0.0) + dt  # each zero-velocity sample stands for dt
        elif self._run_s is not None:  # a stance ended at the previous sample
            self._stance_s, self._run_s = self._run_s, None
        return self._measure(zero_velocity)

    def _propagate(self, gyr: np.ndarray, acc: np.ndarray, dt: float) -> None:
        omega = gyr - self.b[:3]
        f = acc - self.b[3:]
        rot = np.array(scalar.matrix(self.q))
        gain = shock_gain(f, self.noise) if self._stance_s >= self.noise.shock_stance_s else 1.0
        density = self._density
        if gain != 1.0:
            density = density.copy()
            density[6:9] *= gain
        phi, q_noise, p = (np.empty((STATES, STATES)) for _ in range(3))
        self._kernels[0](self.p, omega, f, rot, dt, density, phi, q_noise, p)
        self.last.phi = phi
        self.last.q_noise = q_noise
        wx, wy, wz = omega.tolist()
        acc_world = np.array(scalar.to_world(scalar.gyro_step(self.q, wx, wy, wz, dt / 2.0), *f.tolist()))
        acc_world[2] -= GRAVITY
        self.q = scalar.normalized(scalar.gyro_step(self.q, wx, wy, wz, dt))
        self.r = self.r + self.v * dt + 0.5 * acc_world * dt**2
        self.v = self.v + acc_world * dt
        self.p = p

    def _measure(self, zero_velocity: bool) -> KalmanStep:
        p_prior = self.p
        dx = np.zeros(STATES)
        if zero_velocity:
            rows, variance = self._zero_velocity
            residual = np.append(-self.v, -self.r[2]) if self.flat_floor else -self.v
            self.p = np.empty((STATES, STATES))
            self._kernels[1](p_prior, rows, residual, variance, dx, self.p)  # Joseph form
            self._inject(dx)
        step = KalmanStep(self.q, self.r, self.v, self.b, p_prior, self.p, dx, zero_velocity)
        self.last = step
        if self.keep:
            self.steps.append(step)
        return step

    def _inject(self, dx: np.ndarray) -> None:
        self.q = scalar.normalized(scalar.gyro_step(self.q, *dx[0:3].tolist(), 1.0))
        self.r = self.r + dx[3:6]
        self.v = self.v + dx[6:9]
        self.b = self.b + dx[9:15]



def filter_recording(gyr: np.ndarray, acc: np.ndarray, rate_hz: float, zero_velocity: np.ndarray,
                     noise: KalmanNoise | None = None, flat_floor: bool = True) -> FootKalman:
    """The filter run over whole arrays from the first zero-velocity sample (its acceleration the
    vertical), with given zero-velocity labels; its :attr:`~FootKalman.steps` from that sample on."""
    k0 = int(np.argmax(zero_velocity))
    kf = FootKalman(noise, flat_floor)
    kf.start(acc[k0], gyr[k0], acc[k0], bool(zero_velocity[k0]))
    for k in range(k0 + 1, len(gyr)):
        kf.update(gyr[k], acc[k], 1.0 / rate_hz, bool(zero_velocity[k]))
    return kf
