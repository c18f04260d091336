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


def _shoe_statistic(gyr: np.ndarray, acc: np.ndarray, acc_scale: float, gyro_scale: float) -> float:
    """Skog et al. 2010's SHOE statistic over one window, in the units above (≤ 1: at rest)."""
    total = acc.sum(axis=0)
    n = len(acc)
    acc_part = (np.sum(acc * acc) - 2.0 * GRAVITY_SHOE * np.linalg.norm(total) + n * GRAVITY_SHOE**2)
    return float((acc_part / acc_scale**2 + np.sum(gyr * gyr) / gyro_scale**2) / n)



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
                         acc_scale: float = SHOE_ACC, gyro_scale: float = SHOE_GYRO) -> np.ndarray:
    """(N,) bool on whole arrays; equal to :class:`ZeroVelocityDetector` sample for sample."""
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

