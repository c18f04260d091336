"""A real recording at another sample rate, for the rate benchmarks (issue 15 item 5).

Down: a 4th-order zero-phase Butterworth low-pass at 0.4 × the new rate first (no aliasing), then a
cubic spline at the new instants. Up: the spline alone (it adds no information: the question is only
whether the methods give the same answer at the new rate). The recording's own time base ``t`` (s,
increasing, holes allowed) is kept: the new instants run from its first to its last sample.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.signal import butter, filtfilt


def resample(t: np.ndarray, values: np.ndarray, rate_hz: float, new_rate_hz: float
             ) -> tuple[np.ndarray, np.ndarray]:
    """(new t (M,), values (M, ...)) of ``values`` (N, ...) sampled at ``t`` (nominally ``rate_hz``)."""
    t = np.asarray(t, dtype=float)
    x = np.asarray(values, dtype=float)
    if new_rate_hz < rate_hz:
        b, a = butter(4, 0.4 * new_rate_hz / (0.5 * rate_hz))
        x = filtfilt(b, a, x, axis=0)
    new_t = t[0] + np.arange(int(np.floor((t[-1] - t[0]) * new_rate_hz)) + 1) / new_rate_hz
    return new_t, CubicSpline(t, x, axis=0)(new_t)
