"""Movement cycles of a calibration motion (thesis §3.6: ≥ 10 hip flexions; §3.3 PC8: 8 steps, 4 per
leg): the low-pass of the motion gyro and the hysteresis cycle counter, shared by the calibration
(:mod:`.sensor_to_segment`) and the search for one in a recording (:mod:`.protocol`)."""

from __future__ import annotations

import numpy as np
from scipy.signal import butter, filtfilt

MIN_CYCLES: dict[str, int] = {"hip_flexion": 10, "walking": 4}  # per leg segment
CYCLE_THRESHOLD = 0.35  # rad/s, hysteresis of the cycle counter (20 °/s)
MOTION_LOWPASS_HZ = 6.0  # READING: low-pass of the motion gyro before PCA and the sign rules


def count_cycles(rate: np.ndarray, threshold: float = CYCLE_THRESHOLD) -> int:
    """Sagittal movement cycles in an angular-rate signal: each rise above +threshold after a fall
    below -threshold (hysteresis), on a 50 ms moving average."""
    rate = np.asarray(rate, dtype=float)
    if rate.size == 0:
        return 0
    smooth = np.convolve(rate, np.ones(5) / 5.0, mode="same")
    state, cycles = 0, 0
    for v in smooth:
        if v < -threshold:
            state = -1
        elif v > threshold and state == -1:
            cycles += 1
            state = 1
    return cycles


def lowpass_motion(gyr: np.ndarray, rate_hz: float, cutoff_hz: float = MOTION_LOWPASS_HZ) -> np.ndarray:
    """Zero-phase 2nd-order Butterworth low-pass of (N, 3) angular rates (the calibration's step 2,
    :mod:`.sensor_to_segment`).

    Returned unchanged when too short to filter (< 15 samples) or when the cut-off is not below the
    Nyquist frequency."""
    gyr = np.asarray(gyr, dtype=float)
    if gyr.shape[0] < 15 or cutoff_hz >= 0.5 * rate_hz:
        return gyr
    b, a = butter(2, cutoff_hz / (0.5 * rate_hz))
    return filtfilt(b, a, gyr, axis=0)
