"""Zero-velocity (stance) detection of a foot IMU, Suh 2014 Eq 4 (gait.md §4.2).

A sample ``k`` is at zero velocity when, over the centred window ``[k - h, k + h]``, every gyro norm is
at most ``gyro_limit`` and every change of the acceleration from the sample ``lag`` before is at most
``jerk_limit * lag / rate``.

READINGs (gait.md §6.4 item 37):

- Units: ``B_g = 0.2`` rad/s and ``B_a = 0.4`` m/s² per 10 ms sample (Suh Table 1, 100 Hz).
- Rates other than 100 Hz: the windows keep their duration (``N_g = N_a = 10`` samples at 100 Hz are
  ``window_s = 0.1`` s, so ``h = round(window_s * rate / 2)``). The acceleration is compared over a
  lag of ``max(1, round(0.01 * rate))`` samples, and ``B_a`` is held as a jerk, 0.4 / 0.01 =
  40 m/s³, times the lag's duration. Comparing consecutive samples at 200 Hz would halve the motion
  seen while keeping the noise: stances would grow.
- The detector needs ``h`` samples of look-ahead: 50 ms at every rate.

EXT, the valley rule (:class:`StanceDetector`, ``valley``): one stance per gait cycle where the fixed
thresholds find none. Running shoes rest for 10-70 ms and turn at 0.3-1 rad/s while they do
(pyshoe_vicon's running trials): no fixed threshold that holds for walking finds them, and a gait
cycle without a stance is integrated over twice its length. The foot's stillest moment of the cycle
is taken instead:

- the statistic ``c_k = sqrt(mean |ω|² + mean |a - g û|² / κ²)`` over ``k ± s`` samples (``s`` =
  ``max(1, round(0.005 rate))``, ``û`` the window's mean acceleration direction, ``κ`` = 6 m/s² per
  rad/s: an acceleration 3 m/s² off gravity counts as a turn at 0.5 rad/s), in rad/s;
- sample ``m`` is a valley when ``c_m ≤ valley_max`` (1.5 rad/s), ``c_m`` is the smallest ``c`` from
  0.3 s before to 0.1 s after it, ``c`` exceeded ``valley_swing`` (2.5 rad/s: a swing) in the 0.3 s
  before it, and the fixed rule found no stance within ``valley_gap_s`` (0.45 s) on either side;
- a valley and its ``s`` neighbours on each side are at zero velocity.

Chosen on pyshoe_vicon's 28 trials (benchmarks/spatial.py): the running trials' ARMSE from 0.2-7 m
to 0.03-0.16 m (0.06-0.24 m with the shock noise of :mod:`.kalman`), the others unchanged or better.

The look-ahead is variable: a sample is decided as soon as no undecided valley can reach it. In
walking the fixed stance arrives within the gap and rejects the swing's valleys, so foot flat is
decided with the fixed rule's 25 ms; an accepted valley waits ``valley_gap_s`` (0.45 s + 25 ms).
"""

from __future__ import annotations

from collections import deque

import numpy as np

GYRO_LIMIT = 0.2  # rad/s, B_g
JERK_LIMIT = 40.0  # m/s³, B_a = 0.4 m/s² per 10 ms
WINDOW_S = 0.1  # s, N_g = N_a = 10 samples at 100 Hz
ACC_LAG_S = 0.01  # s, the sample period Suh's B_a is given for


def window_half(rate_hz: float, window_s: float = WINDOW_S) -> int:
    """``h``: samples on each side of the centred window."""
    return max(1, round(window_s * rate_hz / 2.0))


def acc_lag(rate_hz: float) -> int:
    """Samples between the two accelerations compared."""
    return max(1, round(ACC_LAG_S * rate_hz))


SHOE_ACC = 1.0  # m/s²: scale of |a - g û| in the SHOE statistic
SHOE_GYRO = 0.5  # rad/s: scale of |ω|
SHOE_WINDOW_S = 0.05  # s
GRAVITY_SHOE = 9.81  # m/s², the g of the SHOE statistic
DETECTORS = ("suh", "shoe")
VALLEY_MAX = 1.5  # rad/s: the largest valley statistic taken as a stance
VALLEY_SWING = 2.5  # rad/s: the statistic in the swing before a valley
VALLEY_GAP_S = 0.45  # s: no stance of the fixed rule this close to a valley
VALLEY_BEFORE_S = 0.3  # s: a valley is the minimum from this long before it ...
VALLEY_AFTER_S = 0.1  # s: ... to this long after it
VALLEY_ACC_PER_GYRO = 6.0  # m/s² of |a - g û| that count as 1 rad/s
VALLEY_HALF_S = 0.005  # s: half width of the statistic's window and of a valley's stance


def _shoe_statistic(gyr: np.ndarray, acc: np.ndarray, acc_scale: float, gyro_scale: float) -> float:
    """Skog et al. 2010's SHOE statistic over one window, in the units above (≤ 1: at rest)."""
    total = acc.sum(axis=0)
    n = len(acc)
    acc_part = (np.sum(acc * acc) - 2.0 * GRAVITY_SHOE * np.linalg.norm(total) + n * GRAVITY_SHOE**2)
    return float((acc_part / acc_scale**2 + np.sum(gyr * gyr) / gyro_scale**2) / n)



def valley_half(rate_hz: float) -> int:
    """``s``: half width (samples) of the valley statistic's window and of a valley's stance."""
    return max(1, round(VALLEY_HALF_S * rate_hz))


def valley_value(gyr: np.ndarray, acc: np.ndarray) -> float:
    """The valley statistic ``c`` (rad/s) over one window of samples (module docstring): the root of
    SHOE's with the scales κ and 1 rad/s."""
    return float(np.sqrt(max(0.0, _shoe_statistic(gyr, acc, VALLEY_ACC_PER_GYRO, 1.0))))


def valley_statistic(gyr: np.ndarray, acc: np.ndarray, rate_hz: float) -> np.ndarray:
    """``c_k`` of every sample; the window is cut at the ends of the data."""
    half, n = valley_half(rate_hz), len(gyr)
    return np.array([valley_value(gyr[max(0, k - half):k + half + 1], acc[max(0, k - half):k + half + 1])
                     for k in range(n)])


class ZeroVelocityDetector:
    """Streaming zero-velocity detection. ``update(gyr, acc)`` takes sample ``k`` and returns the
    decision for sample ``k - h`` (None for the first ``h`` samples); :meth:`flush` gives the last
    ``h`` decisions at the end, judged on the part of their window that exists.

    ``detector="suh"``: Suh Eq 4 (module docstring) with ``gyro_limit``, ``jerk_limit``, ``window_s``.
    ``detector="shoe"``: Skog et al. 2010's SHOE (the stance hypothesis optimal detector), here
    ``mean over the window of |a - g û|² / acc_scale² + |ω|² / gyro_scale² ≤ 1``, with ``û`` the
    window's mean acceleration direction and ``g`` = 9.81 m/s². Skog's noise variances and threshold
    γ are folded into the two scales, so that they read in m/s² and rad/s.
    """

    def __init__(self, rate_hz: float, gyro_limit: float = GYRO_LIMIT, jerk_limit: float = JERK_LIMIT,
                 window_s: float = WINDOW_S, detector: str = "suh", acc_scale: float = SHOE_ACC,
                 gyro_scale: float = SHOE_GYRO) -> None:
        if detector not in DETECTORS:
            raise ValueError(f"detector: one of {', '.join(DETECTORS)}, not {detector!r}")
        self.detector = detector
        self.half = window_half(rate_hz, window_s)
        self.lag = acc_lag(rate_hz)
        self.gyro_limit = gyro_limit
        self.acc_limit = jerk_limit * self.lag / rate_hz
        self.acc_scale, self.gyro_scale = acc_scale, gyro_scale
        self._acc: deque[np.ndarray] = deque(maxlen=self.lag)
        self._window: deque[tuple[bool, np.ndarray, np.ndarray]] = deque(maxlen=2 * self.half + 1)
        self._seen = 0

    def _quiet_sample(self, gyr: np.ndarray, acc: np.ndarray) -> bool:
        still = bool(np.linalg.norm(gyr) <= self.gyro_limit)
        if len(self._acc) == self.lag:
            still = still and bool(np.linalg.norm(acc - self._acc[0]) <= self.acc_limit)
        self._acc.append(acc)
        return still

    def _judge(self, window: list[tuple[bool, np.ndarray, np.ndarray]]) -> bool:
        if self.detector == "suh":
            return all(w[0] for w in window)
        gyr = np.array([w[1] for w in window])
        acc = np.array([w[2] for w in window])
        return _shoe_statistic(gyr, acc, self.acc_scale, self.gyro_scale) <= 1.0

    def update(self, gyr: np.ndarray, acc: np.ndarray) -> bool | None:
        gyr, acc = np.array(gyr, dtype=float), np.array(acc, dtype=float)
        self._window.append((self._quiet_sample(gyr, acc), gyr, acc))
        self._seen += 1
        if self._seen <= self.half:
            return None
        return self._judge(list(self._window))

    def flush(self) -> list[bool]:
        """Decisions for the samples still waiting for their look-ahead."""
        window = list(self._window)
        waiting = min(self.half, self._seen)
        out = []
        for j in range(waiting):
            k = len(window) - waiting + j  # position of the waiting sample in the window
            out.append(self._judge(window[max(0, k - self.half):]))
        return out


def detect_zero_velocity(gyr: np.ndarray, acc: np.ndarray, rate_hz: float, gyro_limit: float = GYRO_LIMIT,
                         jerk_limit: float = JERK_LIMIT, window_s: float = WINDOW_S, detector: str = "suh",
                         acc_scale: float = SHOE_ACC, gyro_scale: float = SHOE_GYRO, valley: bool = False,
                         valley_max: float = VALLEY_MAX, valley_swing: float = VALLEY_SWING,
                         valley_gap_s: float = VALLEY_GAP_S) -> np.ndarray:
    """(N,) bool on whole arrays; equal to :class:`ZeroVelocityDetector` (``valley``:
    :class:`StanceDetector`) sample for sample."""
    fixed = _fixed_zero_velocity(gyr, acc, rate_hz, gyro_limit, jerk_limit, window_s, detector, acc_scale,
                                 gyro_scale)
    if not valley:
        return fixed
    c = valley_statistic(np.asarray(gyr, float), np.asarray(acc, float), rate_hz)
    half = valley_half(rate_hz)
    before, after = round(VALLEY_BEFORE_S * rate_hz), round(VALLEY_AFTER_S * rate_hz)
    gap = round(valley_gap_s * rate_hz)
    out = fixed.copy()
    for m in np.flatnonzero(c <= valley_max):
        lo = max(0, m - before)
        if (c[lo:m + after + 1].min() < c[m] or m == lo or c[lo:m].max() < valley_swing
                or fixed[max(0, m - gap):m + gap + 1].any()):
            continue
        out[max(0, m - half):m + half + 1] = True
    return out


def _fixed_zero_velocity(gyr, acc, rate_hz, gyro_limit, jerk_limit, window_s, detector, acc_scale,
                         gyro_scale) -> np.ndarray:
    gyr = np.asarray(gyr, float)
    acc = np.asarray(acc, float)
    n = len(gyr)
    half, lag = window_half(rate_hz, window_s), acc_lag(rate_hz)
    k = np.arange(n)
    lo, hi = np.maximum(k - half, 0), np.minimum(k + half, n - 1)

    def window_sum(x: np.ndarray) -> np.ndarray:
        c = np.concatenate([np.zeros((1, *x.shape[1:])), np.cumsum(x, axis=0)])
        return c[hi + 1] - c[lo]

    if detector == "shoe":
        count = hi - lo + 1
        acc_part = (window_sum(np.sum(acc * acc, axis=1)) - 2.0 * GRAVITY_SHOE
                    * np.linalg.norm(window_sum(acc), axis=1) + count * GRAVITY_SHOE**2)
        value = (acc_part / acc_scale**2 + window_sum(np.sum(gyr * gyr, axis=1)) / gyro_scale**2) / count
        return value <= 1.0
    if detector != "suh":
        raise ValueError(f"detector: one of {', '.join(DETECTORS)}, not {detector!r}")
    quiet = np.linalg.norm(gyr, axis=1) <= gyro_limit
    if n > lag:
        quiet[lag:] &= np.linalg.norm(acc[lag:] - acc[:-lag], axis=1) <= jerk_limit * lag / rate_hz
    return window_sum((~quiet).astype(float)) == 0



class StanceDetector:
    """Streaming zero velocity: the fixed rule (:class:`ZeroVelocityDetector`) and, with ``valley``, the
    valley rule (module docstring). ``update(gyr, acc)`` returns the decisions of the next samples in
    order (none, one or several: the look-ahead is variable); :meth:`flush` the rest at the end.
    Equal to :func:`detect_zero_velocity` sample for sample."""

    def __init__(self, rate_hz: float, gyro_limit: float = GYRO_LIMIT, jerk_limit: float = JERK_LIMIT,
                 window_s: float = WINDOW_S, detector: str = "suh", acc_scale: float = SHOE_ACC,
                 gyro_scale: float = SHOE_GYRO, valley: bool = False, valley_max: float = VALLEY_MAX,
                 valley_swing: float = VALLEY_SWING, valley_gap_s: float = VALLEY_GAP_S) -> None:
        self.fixed = ZeroVelocityDetector(rate_hz, gyro_limit, jerk_limit, window_s, detector, acc_scale,
                                          gyro_scale)
        self.valley = valley
        self.valley_max, self.valley_swing = valley_max, valley_swing
        self.half = valley_half(rate_hz)
        self.before, self.after = round(VALLEY_BEFORE_S * rate_hz), round(VALLEY_AFTER_S * rate_hz)
        self.gap = round(valley_gap_s * rate_hz)
        self._raw: deque[tuple[np.ndarray, np.ndarray]] = deque(maxlen=2 * self.half + 1)
        self._seen = 0  # samples in
        self._base = 0  # absolute index of _c[0] and _f[0]
        self._c: list[float] = []  # valley statistic, from _base on
        self._f: list[bool] = []  # fixed-rule decisions, from _base on
        self._status: dict[int, bool] = {}  # decided valleys (True: accepted)
        self._next = 0  # the next sample to decide
        self._end: int | None = None  # number of samples, once flushed

    def update(self, gyr: np.ndarray, acc: np.ndarray) -> list[bool]:
        gyr, acc = np.array(gyr, dtype=float), np.array(acc, dtype=float)
        decision = self.fixed.update(gyr, acc)
        if not self.valley:
            return [] if decision is None else [decision]
        if decision is not None:
            self._f.append(decision)
        self._raw.append((gyr, acc))
        self._seen += 1
        if self._seen > self.half:  # sample seen - 1 - half has its whole window
            self._c.append(self._value(self._seen - 1 - self.half))
        return self._release()

    def flush(self) -> list[bool]:
        decisions = self.fixed.flush()
        if not self.valley:
            return decisions
        self._f += decisions
        for k in range(self._base + len(self._c), self._seen):
            self._c.append(self._value(k))
        self._end = self._seen
        return self._release()

    def _value(self, k: int) -> float:
        """``c`` of sample ``k``, whose window ends at the newest sample (cut at sample 0)."""
        raw = list(self._raw)
        first = max(0, k - self.half) - (self._seen - len(raw))
        window = raw[first:k + self.half + 1 - (self._seen - len(raw))]
        return valley_value(np.array([w[0] for w in window]), np.array([w[1] for w in window]))

    def _release(self) -> list[bool]:
        out = []
        while self._next - self._base < len(self._f):
            k = self._next
            decision = self._f[k - self._base] or self._marked(k)
            if decision is None:
                break
            out.append(bool(decision))
            self._next += 1
        self._trim()
        return out

    def _marked(self, k: int) -> bool | None:
        """True if an accepted valley covers ``k``, False if none can, None while undecided."""
        waiting = False
        for m in range(max(0, k - self.half), k + self.half + 1):
            status = self._valley(m)
            if status:
                return True
            waiting = waiting or status is None
        return None if waiting else False

    def _valley(self, m: int) -> bool | None:
        if m in self._status:
            return self._status[m]
        status = self._judge(m)
        if status is not None:
            self._status[m] = status
        return status

    def _judge(self, m: int) -> bool | None:
        known_c, known_f = self._base + len(self._c), self._base + len(self._f)
        if m >= known_c:
            return False if self._end is not None else None
        c = self._c
        value = c[m - self._base]
        if value > self.valley_max:
            return False
        lo = max(0, m - self.before)
        if m == lo or max(c[lo - self._base:m - self._base]) < self.valley_swing:
            return False
        if min(c[lo - self._base:min(known_c, m + self.after + 1) - self._base]) < value:
            return False
        f = self._f[max(0, m - self.gap) - self._base:min(known_f, m + self.gap + 1) - self._base]
        if any(f):
            return False
        whole = self._end is not None or (m + self.after < known_c and m + self.gap < known_f)
        return True if whole else None

    def _trim(self) -> None:
        """Forget what no undecided sample can need."""
        keep = self._next - self.half - self.gap - self.before - 1
        cut = keep - self._base
        if cut > 4 * (self.gap + self.before):
            del self._c[:cut], self._f[:cut]
            self._base = keep
            self._status = {m: v for m, v in self._status.items() if m >= keep - self.half}
