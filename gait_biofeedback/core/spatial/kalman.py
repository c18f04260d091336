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
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gait_biofeedback.core.jit import fast, plain
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


def kernels(python: bool = False) -> tuple:
    """(foot_step, foot_measure, foot_run) of :mod:`._kalman_kernel`, compiled
    (:func:`~gait_biofeedback.core.jit.fast`: once per process, seconds on a first run, then loaded from
    numba's disk cache), or their plain Python twins (``python``). The foot-trajectory stream asks at
    its start, not at the first stance: a live node compiling mid-session stalled its executor and lost
    samples."""
    names = ("foot_step", "foot_measure", "foot_run")
    if python:
        return tuple(plain(kernel, name) for name in names)
    s, p, kp = np.zeros(kernel.N_STATE), np.eye(STATES), np.zeros(kernel.N_KP)
    s[kernel.Q] = 1.0
    variance = np.ones(4)
    one = (STATES, STATES)
    helpers = ["_product", "propagate", "measure", "half_turn", "_turn", "_set_q", "shock_gain",
               "foot_measure"]
    step = fast(kernel, "foot_step", (s, p, kp, _ROWS_FLOOR, variance, 0.1, 0.0, 0.0, 0.0, 0.0, 9.8, 0.01,
                                      True, *(np.empty(one) for _ in range(4)), np.empty(STATES)), helpers)
    measure = fast(kernel, "foot_measure", (s, p, kp, _ROWS_FLOOR, variance, True, np.empty(one),
                                            np.empty(STATES)), helpers[:-1])
    rows = (np.zeros((1, 3)), np.ones((1, 3)), np.full(1, 0.01), np.ones(1, bool),
            *(np.empty((1, *one)) for _ in range(4)), np.empty((1, STATES)), np.empty((1, 16)))
    run = fast(kernel, "foot_run", (s, p, kp, _ROWS_FLOOR, variance, *rows), [*helpers, "foot_step"])
    return step, measure, run


def floats(v: np.ndarray | Sequence[float]) -> list[float]:
    """A 3-vector's values as Python floats (what a kernel's scalar arguments take)."""
    return v.ravel().tolist() if isinstance(v, np.ndarray) else [float(x) for x in v]


def shock_gain(f: np.ndarray, noise: KalmanNoise) -> float:
    """The factor of ``R_a`` for the specific force ``f`` (module docstring, shocks; its norm
    ``sqrt(x² + y² + z²)``, as the kernel's)."""
    return kernel.shock_gain(*(float(v) for v in f), noise.acc_shock)


class FootKalman:
    """The filter of one foot. :meth:`start` sets the initial state at a stance sample;
    :meth:`update` propagates over ``dt`` with the previous sample's gyro and acceleration and applies
    the measurements of the new sample (one call of the compiled kernel
    :func:`._kalman_kernel.foot_step`); :meth:`update_batch` runs the same kernel over whole arrays.
    :attr:`last` is the last :class:`KalmanStep` (its ``phi`` is set by the next update); :attr:`steps`
    keeps them all when ``keep``."""

    def __init__(self, noise: KalmanNoise | None = None, flat_floor: bool = True, keep: bool = True) -> None:
        self.noise = noise or KalmanNoise()
        self.flat_floor = flat_floor
        self.keep = keep
        self.steps: list[KalmanStep] = []
        self.last: KalmanStep | None = None
        self._step, self._measure_kernel, self._run = kernels()
        n = self.noise
        self._s = np.zeros(kernel.N_STATE)
        self._s[kernel.RUN], self._s[kernel.STANCE] = math.nan, math.inf  # the first stance counts as long
        self._kp = np.array((n.gyro,) * 3 + (n.position,) * 3 + (n.acc,) * 3  # Q_c's diagonal
                            + (n.acc_shock, n.shock_stance_s, 1.0 if flat_floor else 0.0))
        self._zero_velocity = ((_ROWS_FLOOR, np.array((n.zero_velocity,) * 3 + (n.floor,))) if flat_floor
                               else (_ROWS, np.array((n.zero_velocity,) * 3)))  # measured states, R

    @property
    def q(self) -> tuple[float, float, float, float]:
        return tuple(self._s[kernel.Q:kernel.Q + 4].tolist())

    @property
    def r(self) -> np.ndarray:
        return self._s[kernel.R:kernel.R + 3].copy()

    @property
    def v(self) -> np.ndarray:
        return self._s[kernel.V:kernel.V + 3].copy()

    @property
    def b(self) -> np.ndarray:
        return self._s[kernel.B:kernel.B + 6].copy()

    def start(self, vertical: np.ndarray, gyr: np.ndarray, acc: np.ndarray, zero_velocity: bool = True,
              bias: np.ndarray | None = None) -> KalmanStep:
        """First sample: attitude from ``vertical`` (an acceleration at rest, e.g. a stance's mean),
        the sample's own ``gyr``/``acc`` (they act over the next interval), the 6 biases' prior."""
        n = self.noise
        q = tuple(attitude_from_vectors(vertical).tolist())  # TRIAD, heading zero
        self._s[kernel.Q:kernel.Q + 4] = q
        self._s[kernel.R:kernel.B] = 0.0
        self._s[kernel.B:kernel.B + 6] = 0.0 if bias is None else np.asarray(bias, float)
        self._s[kernel.INPUT:kernel.INPUT + 6] = np.concatenate([np.ravel(gyr), np.ravel(acc)])
        tilt = n.acc / GRAVITY**2
        # the attitude error is local (sensor frame): the heading variance is about the world z
        rot = np.array(scalar.matrix(q))
        att_world = np.diag([tilt, tilt, n.heading_init])
        self.p = np.zeros((STATES, STATES))
        self.p[0:3, 0:3] = rot.T @ att_world @ rot
        self.p[3:6, 3:6] = np.eye(3) * n.position_init
        self.p[6:9, 6:9] = np.eye(3) * n.velocity_init
        self.p[9:12, 9:12] = np.eye(3) * n.gyro_bias_init
        self.p[12:15, 12:15] = np.eye(3) * n.acc_bias_init
        p_prior, dx = self.p, np.zeros(STATES)
        self.p = np.empty((STATES, STATES)) if zero_velocity else p_prior
        self._measure_kernel(self._s, p_prior, self._kp, *self._zero_velocity, zero_velocity, self.p, dx)
        return self._keep(p_prior, dx, zero_velocity)

    def update(self, gyr: np.ndarray, acc: np.ndarray, dt: float, zero_velocity: bool) -> KalmanStep:
        """Propagate from the previous sample over ``dt`` and measure at this one, whose ``gyr``/``acc``
        act over the next interval."""
        gx, gy, gz = floats(gyr)
        ax, ay, az = floats(acc)
        one = (STATES, STATES)
        phi, q_noise, p_prior = np.empty(one), np.empty(one), np.empty(one)
        p_post = np.empty((STATES, STATES)) if zero_velocity else p_prior
        dx = np.empty(STATES)
        self._step(self._s, self.p, self._kp, *self._zero_velocity, gx, gy, gz, ax, ay, az, float(dt),
                   bool(zero_velocity), phi, q_noise, p_prior, p_post, dx)
        self.last.phi, self.last.q_noise = phi, q_noise
        self.p = p_post
        return self._keep(p_prior, dx, zero_velocity)

    def _keep(self, p_prior: np.ndarray, dx: np.ndarray, zero_velocity: bool) -> KalmanStep:
        s = self._s
        step = KalmanStep(tuple(s[kernel.Q:kernel.Q + 4].tolist()), s[kernel.R:kernel.R + 3].copy(),
                          s[kernel.V:kernel.V + 3].copy(), s[kernel.B:kernel.B + 6].copy(), p_prior, self.p,
                          dx, bool(zero_velocity))
        self.last = step
        if self.keep:
            self.steps.append(step)
        return step

    def update_batch(self, gyr: np.ndarray, acc: np.ndarray, dt: np.ndarray,
                     zero_velocity: np.ndarray) -> list[KalmanStep]:
        """:meth:`update` of each row (gyro, acc (n, 3), dt (n,) s, zero_velocity (n,)) in one compiled
        loop: their steps, equal to :meth:`update`'s. Each step's arrays are views of (n, ...) blocks."""
        n = len(dt)
        if n == 0:
            return []
        phi, q_noise, p_prior, p_post = (np.empty((n, STATES, STATES)) for _ in range(4))
        dx, states = np.empty((n, STATES)), np.empty((n, 16))
        zv = np.asarray(zero_velocity, bool)
        self._run(self._s, self.p, self._kp, *self._zero_velocity, np.ascontiguousarray(gyr, float),
                  np.ascontiguousarray(acc, float), np.asarray(dt, float), zv, phi, q_noise, p_prior, p_post,
                  dx, states)
        quaternions = states[:, 0:4].tolist()
        zv_list = zv.tolist()
        out = []
        last = self.last
        for j in range(n):
            last.phi, last.q_noise = phi[j], q_noise[j]
            last = KalmanStep(tuple(quaternions[j]), states[j, 4:7], states[j, 7:10], states[j, 10:16],
                              p_prior[j], p_post[j] if zv_list[j] else p_prior[j], dx[j], zv_list[j])
            out.append(last)
        self.last = last
        self.p = last.p_post
        if self.keep:
            self.steps += out
        return out


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
