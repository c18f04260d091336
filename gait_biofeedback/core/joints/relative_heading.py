"""Relative heading of the two sensors of a joint, from the joint's own kinematics (issue 14).

Joint angles need the proximal and distal orientations in one world frame, heading included
(gait.md §1.6, §9 item 13). Indoors the magnetometer is disturbed and many sensor sets are 6D, so each
sensor's filter has a heading of its own: the two world frames differ by a rotation ``δ`` about the
vertical, which drifts slowly with the gyro biases (Laidig, Müller & Seel 2017 call it the heading
offset and estimate it from the joint's constraint). Method (READING, chosen here; the thesis does not
treat it):

1. **Joint centre** (Seel, Schauer & Raisch 2012, joint position estimation): the joint centre is one
   point of both segments, so the specific force there has one norm seen from either sensor,
   ``‖a₁ + Γ₁ r₁‖ = ‖a₂ + Γ₂ r₂‖`` with ``Γ r = ω × (ω × r) + ω̇ × r`` (r: sensor → joint centre, in
   sensor coordinates). :func:`estimate_joint_position` solves it by Gauss–Newton over a window of
   motion, with a small ridge on ``r`` (for a hinge, whose centre is any point of its axis, it picks the
   point nearest the sensors, as Seel et al. do). It holds for hinges, 2-DoF and ball joints alike, so
   the knee, ankle, hip and the lumbar "joint" (pelvis–chest, approximately) all use it.
2. **Heading** (the joint-centre acceleration constraint of Weygers & Kok 2020): that specific force is
   one physical vector, so in the two world frames ``R(q₁)(a₁ + Γ₁r₁) = R_z(δ) R(q₂)(a₂ + Γ₂r₂)``.
   Only its horizontal parts ``h₁, h₂`` (complex numbers x + iy) depend on ``δ``:
   ``δ = arg Σ w·h₁·conj(h₂)``. READING: the sum is exponentially weighted (``time_constant``, 5 s: it
   follows the filters' heading drift), each product weighs by its size (large, clear accelerations
   count most), and a mean over ``highpass_s`` (0.6 s) is removed from each ``h`` first, because a
   tilt error ε of a 6D filter leaks ``g·ε`` of gravity into it (0.3 m/s² for 2°, as large as slow joint
   accelerations), slowly and in one direction. The mean is centred on the sample (the products lag
   the newest sample by ``highpass_s / 2``). A causal mean (an exponential one of time constant 0.5 s,
   before) passes more of the slow leakage: on dfjimu_weygers it biased δ by 2–5° on most 2- and
   3-DoF recordings (median relative-orientation RMSE 3.8°, 2.6° centred). READING: the span is a
   compromise between data sets (docs/benchmarks/joint_angles.md): shorter removes more leakage (dfjimu's
   hand-moved joints: 2.3° at 0.3–0.5 s), longer keeps more of walking's stride-frequency accelerations
   (a 0.6 s mean removed keeps half of a 1 Hz component; at 0.3 s the qmt walk's hips never establish).
3. **Heading turns the gyro does not explain** (our addition): a filter's world frame turns whenever
   the filter corrects its heading from its magnetometer (disturbed or not: a magnet that becomes the
   filter's new reference turns it by tens of degrees within seconds), and δ turns with it at once,
   faster than step 2 can follow. Per sensor, the correction of each sample,
   ``C = q_k ⊗ conj(q_{k−1} ⊗ exp(ω̄ dt))`` (ω̄ the mean of the two samples' bias-corrected rates), has
   a twist about the vertical ``2·atan2(C_z, C_w)``; their running sum ``E`` is that sensor's world
   turn. Step 2 runs on ``R_z(−E) ⊗ q`` (worlds that turn only with gyro drift) and the estimate is
   ``δ = δ_kinematic + E₁ − E₂``. Only consecutive samples (``dt`` ≤ ``MAX_TURN_STEP_S``) count: over a
   longer gap the segment's own rotation is unknown, and step 2 re-converges instead. READING: only
   filters whose heading comes from a magnetometer (``magnetic``) are read so; a 6D filter's
   corrections twist its heading by a few degrees a minute as well, but compensating them made
   dfjimu_weygers worse (median 2.61° → 2.83°), so there step 2 alone follows them. With a magnet
   near the thigh (simulator) the knee's error fell from 2.06° to 1.01°, the 6D figure
   (docs/benchmarks/joint_angles.md).
4. **Established** once the products summed since the start weigh ``min_information`` (m²/s⁴·s) and
   agree (``|Σ|`` / ``Σ|·|`` ≥ ``min_coherence``). Before that the estimate is not used (live: that
   joint's angles are not published; offline: :func:`estimate_relative_heading` holds the first
   established value backwards). Without motion (quiet standing) the last value is kept.

The magnetometer, when present, enters through the filters: 9D orientations start with ``δ ≈ 0`` and
the joint constraint only corrects it; a magnet near one thigh turns that filter's world, which step 3
reads and undoes at once. It is never required.

Delay: none for the joint angles (each sample gets the estimate in force). A sample enters the
estimate ``highpass_s / 2`` (0.3 s) after it arrives (the centred mean; ω̇ is the central difference
of the rates); the estimate lags a change of the offset by about ``time_constant``. The joint centre
needs ``position_window_s`` s of motion first, within at most ``MAX_WINDOW_SPAN`` times that span
(older samples are dropped: memory stays bounded through a long stillness).
Stamps are int ns.
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.jit import fast
from gait_biofeedback.core.joints import _heading_kernel as hk
from gait_biofeedback.core.stamps import seconds_to_ns

TIME_CONSTANT_S = 5.0
HIGHPASS_S = 0.6
POSITION_WINDOW_S = 10.0
MIN_INFORMATION = 20.0  # (m/s²)² s: e.g. 10 s of 1.4 m/s² horizontal joint-centre accelerations
MIN_COHERENCE = 0.3
MIN_WINDOW_INFORMATION = 2.0  # (m/s²)² s, one window (calibration), after WINDOW_LOWPASS_HZ
MIN_WINDOW_COHERENCE = 0.5
JUMP_BACK_NS = hk.JUMP_BACK_NS
MAX_WINDOW_SPAN = 6.0  # the joint-centre window keeps at most this many position windows of time (memory)
MOVING = hk.MOVING
MAX_JOINT_DISTANCE = 1.0  # m: a larger sensor-to-joint distance is not a joint centre
MAX_RESIDUAL = 2.0  # m/s²: RMS of the norm mismatch above which the joint-centre fit is refused
HUBER = hk.HUBER
WINDOW_LOWPASS_HZ = 3.0  # Hz: zero-phase low-pass of the window's world joint-centre accelerations
LOWPASS_HZ = 5.0  # Hz: zero-phase low-pass of the joint-centre window (heel-strike impacts)
MAX_TURN_STEP_S = hk.MAX_TURN_STEP_NS * 1e-9


def _gamma(gyr: np.ndarray, gyr_dot: np.ndarray) -> np.ndarray:
    """(N, 3, 3) Γ with ``Γ r = ω × (ω × r) + ω̇ × r``."""
    def skew(v: np.ndarray) -> np.ndarray:
        z = np.zeros(len(v))
        return np.stack([np.stack([z, -v[:, 2], v[:, 1]], -1), np.stack([v[:, 2], z, -v[:, 0]], -1),
                         np.stack([-v[:, 1], v[:, 0], z], -1)], 1)
    w = skew(gyr)
    return w @ w + skew(gyr_dot)


def rate_derivative(gyr: np.ndarray, dt: float) -> np.ndarray:
    """(N, 3) ω̇ as the central difference (one-sided at the ends), as the stream has it."""
    return np.gradient(np.asarray(gyr, dtype=float), dt, axis=0)


def estimate_joint_position(gyr1: np.ndarray, acc1: np.ndarray, gyr2: np.ndarray, acc2: np.ndarray,
                            rate_hz: float, iterations: int = 30, ridge: float = 1e-3
                            ) -> tuple[np.ndarray, np.ndarray, float]:
    """(r₁, r₂, RMS residual m/s²): sensor → joint centre in each sensor's coordinates (m), by
    Gauss–Newton on ``‖a₁ + Γ₁r₁‖ − ‖a₂ + Γ₂r₂‖`` (module docstring step 1, Seel et al. 2012).
    ``ridge`` (dimensionless, relative to the mean squared Jacobian row) keeps a hinge's fit on the
    point of its axis nearest the sensors."""
    dt = 1.0 / rate_hz
    gyr1, gyr2 = np.asarray(gyr1, float), np.asarray(gyr2, float)
    if len(gyr1) < 20:
        raise ValueError("joint centre: fewer than 20 samples of motion")
    return _fit(gyr1, rate_derivative(gyr1, dt), np.asarray(acc1, float),
                gyr2, rate_derivative(gyr2, dt), np.asarray(acc2, float), iterations, ridge)


class HeadingEstimate(NamedTuple):
    """One sample's result: ``delta`` (rad, rotate the distal sensor's world frame by it about the
    vertical to put it in the proximal's), ``established``, ``coherence`` (0..1) and a ``state`` word
    for diagnostics ("collecting motion", "joint centre refused: …", "converging", "ok"). (A named
    tuple: every joint makes one per instant.)"""

    delta: float
    established: bool
    coherence: float
    state: str


class RelativeHeadingEstimator:
    """Streaming heading offset of one joint's two sensors (module docstring). :meth:`update` takes one
    synchronised sample of both (orientation w,x,y,z sensor→own world, bias-corrected rate rad/s, acc
    m/s², stamp int ns). The per-sample arithmetic is :func:`._heading_kernel.step` (numba-compiled when
    possible, on this object's state arrays); the joint-centre fit (step 1) stays here."""

    _kind = hk.RELATIVE  # the kernel's name of this estimator (stacked in a :class:`HeadingBank`)
    _bank: HeadingBank | None = None

    def __init__(self, time_constant: float = TIME_CONSTANT_S, highpass_s: float = HIGHPASS_S,
                 position_window_s: float = POSITION_WINDOW_S, min_information: float = MIN_INFORMATION,
                 min_coherence: float = MIN_COHERENCE) -> None:
        self.time_constant = float(time_constant)
        self.highpass_s = float(highpass_s)
        self.position_window_s = float(position_window_s)
        self.min_information = float(min_information)
        self.min_coherence = float(min_coherence)
        self._k = _kernels()
        new = self._k.new
        self._f, self._i = new(hk.N_FLOAT, 0.0), new(hk.N_INT, 0)
        self._ring, self._row = new(RING_ROWS * hk.RING_WIDTH, 0.0), new(hk.ROW_WIDTH, 0.0)
        self._p = new(hk.N_PARAM, 0.0)
        self._p[hk.P_TIME_CONSTANT], self._p[hk.P_HALF] = self.time_constant, 0.5 * self.highpass_s
        self._p[hk.P_MIN_INFORMATION], self._p[hk.P_MIN_COHERENCE] = self.min_information, self.min_coherence
        self.residual = math.nan
        self.reset()

    def reset(self) -> None:
        """Forget everything but the joint centre (time went back: the filters restarted, their headings
        are new)."""
        self._k.restart(self._f, self._i)
        self._restarted()

    def _restarted(self) -> None:
        self._window: deque[np.ndarray] = deque()  # joint-centre window rows (hk.ROW_WIDTH)
        self._window_s = 0.0  # motion time in the window
        self._span_s = 0.0  # all time in the window
        self.state = "collecting motion" if self.r1 is None else "converging"

    def _centre(self, at: int) -> np.ndarray | None:
        return np.array(self._f[at:at + 3], dtype=float) if self._i[hk.FITTED] else None

    def _set_centre(self, at: int, r: np.ndarray | None) -> None:
        self._i[hk.FITTED] = int(r is not None)
        for k in range(3):
            self._f[at + k] = 0.0 if r is None else float(r[k])

    r1 = property(lambda self: self._centre(hk.CENTRE), lambda self, r: self._set_centre(hk.CENTRE, r),
                  doc="sensor 1 → joint centre (m, sensor coordinates), None before the fit")
    r2 = property(lambda self: self._centre(hk.CENTRE + 3),
                  lambda self, r: self._set_centre(hk.CENTRE + 3, r),
                  doc="sensor 2 → joint centre (m, sensor coordinates), None before the fit")

    @property
    def established(self) -> bool:
        """The products weigh ``min_information`` and agree (module docstring step 4)."""
        return bool(self._i[hk.ESTABLISHED])

    @property
    def delta(self) -> float:
        """The heading offset in force (rad): the kinematic one plus the worlds' own turns (step 3)."""
        return float(self._k.delta(self._f))

    def _estimate(self) -> HeadingEstimate:
        return HeadingEstimate(self.delta, self.established, float(self._k.coherence(self._f)), self.state)

    def _room(self) -> None:
        """At least one free row in the ring of recent products (it doubles when full)."""
        ring, i, width = self._ring, self._i, hk.RING_WIDTH
        cap = len(ring) // width
        if i[hk.COUNT] < cap:
            return
        if self._bank is not None:
            self._bank.grow()
            return
        grown = self._k.new(2 * cap * width, 0.0)
        for k in range(cap):
            at = (int(i[hk.START]) + k) % cap * width
            grown[k * width:(k + 1) * width] = ring[at:at + width]
        self._ring, i[hk.START] = grown, 0

    def _after(self, code: int) -> None:
        if code & hk.RESTARTED:
            self._restarted()
        if code & hk.NOW_ESTABLISHED:
            self.state = "ok"

    def update(self, ns: int, q1: tuple, gyr1: tuple, acc1: tuple, q2: tuple, gyr2: tuple,
               acc2: tuple, magnetic: tuple[bool, bool] = (False, False)) -> HeadingEstimate:
        """Add one sample; the estimate in force for it (which has used the samples before it: the
        previous sample is added now, with ω̇ as the central difference around it). A sample with a
        value that is not finite is skipped (one NaN would otherwise poison every later estimate).
        ``magnetic``: whether each filter's heading comes from a magnetometer (module docstring step 3)."""
        self._room()
        self._took(self._k.step(self._f, self._i, self._ring, self._p, self._row, int(ns), *q1, *gyr1,
                                *acc1, *q2, *gyr2, *acc2, bool(magnetic[0]), bool(magnetic[1])))
        return self._estimate()

    def _took(self, code: int) -> None:
        """What a kernel step's result bits ask of this object: a restart, the state word, and a row made
        into the joint-centre window (step 1: fitted once the window holds enough motion)."""
        self._after(code)
        if code & hk.ROW_MADE:
            row = np.array(self._row, dtype=float)
            self._window.append(row)
            self._window_s += row[28]
            self._span_s += row[26]
            while self._span_s > MAX_WINDOW_SPAN * self.position_window_s:  # long stillness: forget its start
                old = self._window.popleft()
                self._span_s -= old[26]
                self._window_s -= old[28]
            if self._window_s >= self.position_window_s and len(self._window) >= 20:
                self._fit_position()

    def _fit_position(self) -> None:
        rows = np.array(self._window)
        self._window, self._window_s, self._span_s = deque(), 0.0, 0.0
        rate_hz = 1.0 / float(np.median(rows[:, 26]))
        g1, d1, a1, g2, d2, a2 = (_zero_phase_lowpass(np.ascontiguousarray(rows[:, k:k + 3]), rate_hz)
                                  for k in (4, 7, 10, 17, 20, 23))
        r1, r2, res = _fit(g1, d1, a1, g2, d2, a2)
        if (refused := _joint_centre_refused(r1, r2, res)) is not None:
            self.state = f"{refused}: are both sensors on this joint's segments? collecting motion again"
            return
        self.r1, self.r2, self.residual = r1, r2, res
        self.state = "converging"
        for row in rows:  # the window's own samples inform the heading too
            self._room()
            self._after(self._k.add_row(self._f, self._i, self._ring, self._p, self._k.row(row)))


RING_ROWS = 128  # first capacity of the ring of recent products (0.6 s at 100 Hz needs 61; it grows)


class _Kernels(NamedTuple):
    """The entry points of :mod:`._heading_kernel` and the state they run on: numpy arrays when
    compiled, lists as plain Python (faster there)."""

    step: Any
    instant: Any
    segment_angles: Any
    add_row: Any
    axis_step: Any
    restart: Any
    delta: Any
    coherence: Any
    new: Any  # (size, fill) → a state sequence
    row: Any  # an array row → the kernel's sequence


_LOADED: list[_Kernels] = []


def _kernels(python: bool = False) -> _Kernels:
    """:mod:`._heading_kernel`'s entry points compiled with numba (:func:`~gait_biofeedback.core.jit.fast`:
    once per process, numba's disk cache), or plain Python (``python``: the module's functions as they
    are, the twin when they are the plain ones)."""
    if python:
        return _Kernels(hk.step, hk.instant, hk.segment_angles, hk.add_row, hk.axis_step, hk._restart,
                        hk.delta, hk.coherence, lambda n, fill: [fill] * n, lambda r: r.tolist())
    if not _LOADED:
        f, i, p = np.zeros(hk.N_FLOAT), np.zeros(hk.N_INT, dtype=np.int64), np.ones(hk.N_PARAM)
        ring, row = np.zeros(RING_ROWS * hk.RING_WIDTH), np.zeros(hk.ROW_WIDTH)
        i[hk.EDGE], i[hk.FITTED] = -1, 1
        sample = (1.0, 0.0, 0.0, 0.0, 0.1, 0.2, 0.3, 0.0, 0.0, 9.8) * 2
        helpers = ("half_turn", "_norm", "_wrap", "_turned_back", "_vertical_correction", "_turn_worlds",
                   "_restart",
                   "_rotate", "_centre_force", "_coherence", "_add_product", "add_row")
        step = fast(hk, "step", (f, i, ring, p, row, 10_000_000, *sample, True, True), helpers)
        if not hasattr(step, "py_func"):
            _LOADED.append(_kernels(python=True))
            return _LOADED[0]
        bank = (f[None], i[None], ring[None], p[None], row[None], np.array([hk.RELATIVE]))
        table, flags = np.array([[0.0, 1.0, 1.0, 1.0, 1.0]]), np.full(2, hk.PRESENT | hk.CALIBRATED | hk.LIMB)
        s, rot, q = np.array([sample[:10], sample[10:]]), np.array([sample[:4]] * 2), np.zeros((2, 4))
        instant = fast(hk, "instant", (*bank, table, s, flags, rot, q, np.zeros(3),
                                       np.zeros(1, dtype=np.int64), True, 20_000_000, 0.2, 0.5),
                       ("_multiply", "_upright", "segment_angles", "axis_step", "step", "delta"))
        angles = fast(hk, "segment_angles", (table, s, flags, rot, np.zeros(3)))
        _LOADED.append(_Kernels(step, instant, angles,
                                fast(hk, "add_row", (f, i, ring, p, row)),
                                fast(hk, "axis_step", (f, i, p, 10_000_000, *sample[:7], *sample[:7], True,
                                                       True)),
                                fast(hk, "_restart", (f, i)), fast(hk, "delta", (f,)),
                                fast(hk, "coherence", (f,)),
                                lambda n, fill: np.full(n, fill, dtype=type(fill)), lambda r: r))
    return _LOADED[0]


class HeadingBank:
    """Several estimators' state stacked one a row (``f``, ``i``, ``ring``, ``p``, ``row``, ``kind``), so
    that one kernel call (:func:`._heading_kernel.instant`) steps them all; each estimator goes on working
    on its row (its methods and the joint-centre fit)."""

    def __init__(self, estimators: list[RelativeHeadingEstimator]) -> None:
        self.estimators = list(estimators)
        self.plain = any(isinstance(e._f, list) for e in self.estimators)  # the twin's lists, kept as lists
        names = ("_f", "_i", "_p", "_row", "_ring")
        rows = {name: [getattr(e, name) for e in self.estimators] for name in names}
        self.f, self.i, self.p, self.row, self.ring = (self._stack(r) for r in rows.values())
        self.kind = np.array([e._kind for e in self.estimators], dtype=np.int64)
        self._link()

    def _stack(self, rows: list) -> Any:
        return [list(r) for r in rows] if self.plain else np.array(rows)

    def _link(self) -> None:
        for k, e in enumerate(self.estimators):
            e._f, e._i, e._p, e._row, e._ring, e._bank = (self.f[k], self.i[k], self.p[k], self.row[k],
                                                          self.ring[k], self)

    def grow(self) -> None:
        """Every ring twice as long, its rows from its first one on (the same ring: its start moves)."""
        width = hk.RING_WIDTH
        cap = len(self.ring[0]) // width
        grown = self._stack([[0.0] * (2 * cap * width) for _ in self.estimators])
        for k in range(len(self.estimators)):
            for r in range(cap):
                at = (int(self.i[k][hk.START]) + r) % cap * width
                grown[k][r * width:(r + 1) * width] = self.ring[k][at:at + width]
            self.i[k][hk.START] = 0
        self.ring = grown
        self._link()


def _joint_centre_refused(r1: np.ndarray, r2: np.ndarray, residual: float) -> str | None:
    """Why a joint-centre fit is not one (too far from a sensor, or the norms do not match), or None."""
    d1, d2 = float(np.linalg.norm(r1)), float(np.linalg.norm(r2))
    if d1 < MAX_JOINT_DISTANCE and d2 < MAX_JOINT_DISTANCE and residual < MAX_RESIDUAL:
        return None
    return f"joint centre refused ({d1:.2f} m, {d2:.2f} m from the sensors, mismatch {residual:.1f} m/s²)"


def _zero_phase_lowpass(x: np.ndarray, rate_hz: float, cutoff_hz: float = LOWPASS_HZ) -> np.ndarray:
    """``x`` (N, 3) of the joint-centre window, low-passed at ``cutoff_hz`` forwards and backwards."""
    from scipy.signal import butter, filtfilt

    if len(x) < 15 or 0.45 * rate_hz <= cutoff_hz:
        return x
    b, a = butter(2, cutoff_hz / (0.5 * rate_hz))
    return filtfilt(b, a, x, axis=0)


def _fit(g1: np.ndarray, d1: np.ndarray, a1: np.ndarray, g2: np.ndarray, d2: np.ndarray, a2: np.ndarray,
         iterations: int = 30, ridge: float = 1e-3) -> tuple[np.ndarray, np.ndarray, float]:
    """Gauss–Newton of :func:`estimate_joint_position` on given rates ω, their derivatives ω̇ and accs."""
    gam1, gam2 = _gamma(g1, d1), _gamma(g2, d2)
    x = np.zeros(6)
    e = np.zeros(len(a1))
    for _ in range(iterations):
        v1 = a1 + gam1 @ x[:3]
        v2 = a2 + gam2 @ x[3:]
        n1 = np.maximum(np.linalg.norm(v1, axis=1), 1e-9)
        n2 = np.maximum(np.linalg.norm(v2, axis=1), 1e-9)
        e = n1 - n2
        w = np.minimum(1.0, HUBER / np.maximum(np.abs(e), 1e-12))  # Huber weights: impacts count less
        jac = np.concatenate([np.einsum("ni,nij->nj", v1 / n1[:, None], gam1),
                              -np.einsum("ni,nij->nj", v2 / n2[:, None], gam2)], axis=1)
        lam = ridge * float(np.mean(w * np.sum(jac**2, axis=1))) * len(e)
        step = np.linalg.solve(jac.T @ (w[:, None] * jac) + lam * np.eye(6), jac.T @ (w * e) + lam * x)
        x = x - step
        if np.linalg.norm(step) < 1e-6:
            break
    return x[:3], x[3:], float(np.sqrt(np.mean(e**2)))


def heading_rotation(delta: np.ndarray | float) -> np.ndarray:
    """(..., 4) rotation by ``delta`` rad about the world vertical."""
    return quat.from_axis_angle([0.0, 0.0, 1.0], delta)


@dataclass(frozen=True)
class WindowHeading:
    """:func:`window_relative_heading`'s result: ``delta`` (N,) rad, ``coherence`` 0..1, ``information``
    (m²/s⁴·s) and the joint centre ``r1``, ``r2`` (m, sensor coordinates) with its ``residual`` m/s²;
    ``problem`` (None when usable) says why not."""

    delta: np.ndarray
    coherence: float
    information: float
    r1: np.ndarray
    r2: np.ndarray
    residual: float
    problem: str | None = None


def window_relative_heading(q1: np.ndarray, gyr1: np.ndarray, acc1: np.ndarray, q2: np.ndarray,
                            gyr2: np.ndarray, acc2: np.ndarray, rate_hz: float,
                            min_information: float = MIN_WINDOW_INFORMATION,
                            min_coherence: float = MIN_WINDOW_COHERENCE) -> WindowHeading:
    """The heading offset over one window of motion (the calibration's: a walk of 8 steps is shorter
    than the stream's ``position_window_s``): the joint centre fitted on the window itself (module
    docstring step 1, same fit and refusals as the stream), then per sample δ = arg Σ w·h₁·conj(h₂)
    over a centred ``TIME_CONSTANT_S`` box (step 2 offline: the stream's exponential weighting made
    centred; the 0.5 s mean removed is centred too). READING: the world joint-centre accelerations are
    low-passed at ``WINDOW_LOWPASS_HZ`` first (zero phase): on the qmt walk the raw products agree
    poorly (knee coherence 0.1–0.4, soft-tissue vibration at each heel strike), low-passed 0.95–0.99.
    The stream does not low-pass: on dfjimu_weygers a causal 2–3 Hz low-pass raised its median error
    (then 3.8°) to 5.2–6.0°, and this function over whole recordings scores 2.6° unfiltered against
    3.6° at 3 Hz there. ``coherence``: ``|Σ|/Σ|·|`` of the boxes, averaged with their weights.
    Usable when the products weigh ``min_information`` and agree to ``min_coherence``."""
    q1, q2 = np.asarray(q1, float), np.asarray(q2, float)
    g1, a1, g2, a2 = (np.asarray(v, float) for v in (gyr1, acc1, gyr2, acc2))
    nothing = WindowHeading(np.zeros(len(g1)), 0.0, 0.0, np.zeros(3), np.zeros(3), math.nan)
    if len(g1) < 20:
        return dataclasses.replace(nothing, problem="fewer than 20 samples of motion")
    dt = 1.0 / rate_hz
    d1, d2 = rate_derivative(g1, dt), rate_derivative(g2, dt)
    r1, r2, residual = _fit(*(_zero_phase_lowpass(v, rate_hz) for v in (g1, d1, a1, g2, d2, a2)))
    if (refused := _joint_centre_refused(r1, r2, residual)) is not None:
        return WindowHeading(np.zeros(len(g1)), 0.0, 0.0, r1, r2, residual, refused)
    c1 = a1 + _gamma(g1, d1) @ r1
    c2 = a2 + _gamma(g2, d2) @ r2
    w1 = _zero_phase_lowpass(quat.rotate(q1, c1), rate_hz, WINDOW_LOWPASS_HZ)
    w2 = _zero_phase_lowpass(quat.rotate(q2, c2), rate_hz, WINDOW_LOWPASS_HZ)
    h1, h2 = w1[:, 0] + 1j * w1[:, 1], w2[:, 0] + 1j * w2[:, 1]
    n = max(1, round(HIGHPASS_S * rate_hz))
    count = _centred_sum(np.ones(len(h1)), n)
    h1, h2 = h1 - _centred_sum(h1, n) / count, h2 - _centred_sum(h2, n) / count
    mismatch = (np.linalg.norm(c1, axis=1) - np.linalg.norm(c2, axis=1)) / HUBER
    p = h1 * np.conj(h2) / (1.0 + mismatch**2)
    span = max(1, min(len(p), round(TIME_CONSTANT_S * rate_hz)))
    local = _centred_sum(p, span)  # the stream's exponential weighting, centred offline
    size = float(np.abs(p).sum())
    coherence = float(np.abs(local).sum() / _centred_sum(np.abs(p), span).sum()) if size > 0 else 0.0
    information = size * dt
    out = WindowHeading(np.angle(local), coherence, information, r1, r2, residual)
    if information < min_information:
        return dataclasses.replace(out, problem=f"too little joint-centre acceleration ({information:.1f} of "
                                   f"{min_information:g} m²/s⁴·s)")
    if coherence < min_coherence:
        return dataclasses.replace(out, problem=f"the accelerations seen by the two sensors disagree "
                                   f"(coherence {coherence:.2f} < {min_coherence:g})")
    return out


def _centred_sum(x: np.ndarray, n: int) -> np.ndarray:
    """Sum of ``x`` over the ``n`` samples centred on each (fewer at the ends)."""
    return np.convolve(x, np.ones(n), mode="same")


def estimate_relative_heading(t_ns: np.ndarray, q1: np.ndarray, gyr1: np.ndarray, acc1: np.ndarray,
                              q2: np.ndarray, gyr2: np.ndarray, acc2: np.ndarray,
                              magnetic: tuple[bool, bool] = (False, False),
                              **options: float) -> tuple[np.ndarray, np.ndarray]:
    """Batch form of :class:`RelativeHeadingEstimator` (same object, sample by sample): (δ (N,) rad,
    established (N,) bool). Samples before the heading was established get its first established value
    (offline only; live they are not used), or 0 when it never was."""
    est = RelativeHeadingEstimator(**options)
    n = len(t_ns)
    delta = np.zeros(n)
    ok = np.zeros(n, dtype=bool)
    rows = zip(np.asarray(t_ns, dtype=np.int64).tolist(), np.asarray(q1, float).tolist(),
               np.asarray(gyr1, float).tolist(), np.asarray(acc1, float).tolist(),
               np.asarray(q2, float).tolist(), np.asarray(gyr2, float).tolist(),
               np.asarray(acc2, float).tolist(), strict=True)
    for i, row in enumerate(rows):
        e = est.update(*row, magnetic=magnetic)
        delta[i], ok[i] = e.delta, e.established
    if ok.any():
        first = int(np.argmax(ok))
        delta[:first] = delta[first]
    return delta, ok


def estimate_relative_orientation(gyr1: np.ndarray, acc1: np.ndarray, gyr2: np.ndarray, acc2: np.ndarray,
                                  rate_hz: float, dof: int = 3, mag1: np.ndarray | None = None,
                                  mag2: np.ndarray | None = None, algorithm: str | None = None
                                  ) -> np.ndarray:
    """(N, 4) orientation of sensor 2 in sensor 1's frame (w, x, y, z): ``conj(q₁) ⊗ R_z(δ) ⊗ q₂`` with
    q₁, q₂ from the project's filter (6D, or 9D when both magnetometers are given) and δ from the
    joint's kinematics (module docstring). ``dof`` (1, 2 or 3) is checked but not needed: the
    joint-centre constraint holds for all three (a hinge's centre is any point of its axis)."""
    from gait_biofeedback.core.orientation.filters import estimate_orientation
    from gait_biofeedback.core.orientation.filters.startup import quiet_samples

    if dof not in (1, 2, 3):
        raise ValueError(f"dof must be 1, 2 or 3, got {dof!r}")
    if (mag1 is None) != (mag2 is None):
        raise ValueError("give both magnetometers or neither")
    arrays = [np.asarray(a, dtype=float) for a in (gyr1, acc1, gyr2, acc2)]
    if any(a.ndim != 2 or a.shape != arrays[0].shape or a.shape[1] != 3 for a in arrays):
        raise ValueError(f"gyr1, acc1, gyr2, acc2 must all be (N, 3), got {[a.shape for a in arrays]}")
    gyr1, acc1, gyr2, acc2 = arrays
    q1 = estimate_orientation(gyr1, acc1, mag1, rate_hz, algorithm, startup_s=5.0)
    q2 = estimate_orientation(gyr2, acc2, mag2, rate_hz, algorithm, startup_s=5.0)
    rates = []
    for gyr, acc in ((gyr1, acc1), (gyr2, acc2)):
        n = quiet_samples(gyr, acc, rate_hz, max_s=5.0)
        rates.append(gyr - (gyr[:n].mean(axis=0) if n > 0 else 0.0))
    t_ns = seconds_to_ns(np.arange(len(gyr1)) / rate_hz)
    good = np.all(np.isfinite(q1), axis=1) & np.all(np.isfinite(q2), axis=1)
    delta = np.zeros(len(gyr1))
    nine = (mag1 is not None,) * 2
    delta[good], _ = estimate_relative_heading(t_ns[good], q1[good], rates[0][good], acc1[good], q2[good],
                                               rates[1][good], acc2[good], magnetic=nine)
    return quat.multiply(quat.conjugate(q1), quat.multiply(heading_rotation(delta), q2))
