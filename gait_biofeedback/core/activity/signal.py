"""Signal helpers of the chest activity monitor (thesis ch. 7; spec gait.md §3.2).

Everything here is cheap enough to run per sample in pure Python (floats, no numpy calls on the
hot path) or is called once (filter design, mounting from a reference period, window analysis).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from scipy import signal

STANDARD_GRAVITY = 9.80665  # m/s², used as "g" after the input is scaled to its static norm


class UnitMismatchWarning(UserWarning):
    """The static norm of the input does not match the declared unit (m/s² or g)."""


class Biquad:
    """One second-order IIR section, direct form II transposed, on Python floats.

    Cheaper per sample than ``scipy.signal.lfilter`` with a carried state (a call costs ~10 µs,
    this costs well under 1 µs).
    """

    __slots__ = ("a1", "a2", "b0", "b1", "b2", "s1", "s2")

    def __init__(self, b: np.ndarray, a: np.ndarray) -> None:
        b = np.asarray(b, dtype=float) / a[0]
        a = np.asarray(a, dtype=float) / a[0]
        self.b0, self.b1, self.b2 = (float(v) for v in b)
        self.a1, self.a2 = float(a[1]), float(a[2])
        self.s1 = 0.0
        self.s2 = 0.0

    def reset_steady(self, value: float) -> None:
        """State of a filter that has seen ``value`` forever (unit DC gain assumed)."""
        self.s1 = (1.0 - self.b0) * value
        self.s2 = (self.b2 - self.a2) * value

    def step(self, x: float) -> float:
        y = self.b0 * x + self.s1
        self.s1 = self.b1 * x - self.a1 * y + self.s2
        self.s2 = self.b2 * x - self.a2 * y
        return y


def gravity_lowpass_ba(rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """The thesis's GA filter: 2nd-order elliptic low-pass, 0.25 Hz, 0.01 dB, −100 dB [T §7.2.3].

    READING (gait.md §3.2, §6 item 28): 0.25 Hz is the passband edge as in MATLAB ``ellip``; the
    real −3 dB point is ≈ 0.82 Hz and the causal group delay near DC ≈ 0.27 s (at 100 Hz; the
    design is redone for each rate so these hold from 20 to 200 Hz).
    """
    b, a = signal.ellip(2, 0.01, 100, 0.25, fs=rate_hz)
    return b, a


def step_lowpass_ba(rate_hz: float, cutoff_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """2nd-order Butterworth low-pass for the step SVM (choice: see ``steps.STEP_LOWPASS_HZ``)."""
    b, a = signal.butter(2, min(cutoff_hz, 0.45 * rate_hz), fs=rate_hz)
    return b, a


DISPLACEMENT_HIGHPASS_HZ = 0.6  # below the slowest step frequency the monitor counts (1 / 1.3 s = 0.77 Hz)


def vertical_displacement_sections(rate_hz: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """Two biquads (b, a) turning vertical acceleration (m/s²) into displacement (m) at step frequency.

    A 4th-order Butterworth high-pass at DISPLACEMENT_HIGHPASS_HZ followed by two integrations
    (T²/(1 − z⁻¹)²): two of the high-pass's four zeros at z = 1 cancel the integrators' poles, so the
    result is stable and has no drift (above the cut-off the gain is 1/ω², below it falls as ω²).
    """
    sos = signal.butter(4, DISPLACEMENT_HIGHPASS_HZ, btype="high", fs=rate_hz, output="sos")
    first = (sos[0, :3] / rate_hz**2, sos[0, 3:])  # gain·(1 − z⁻¹)² · T²
    second = (np.array([1.0, 0.0, 0.0]), sos[1, 3:])  # its (1 − z⁻¹)² cancelled by the integrators
    return [first, second]


def mounting_from_reference(mean_acc: np.ndarray, forward_hint: np.ndarray | None = None) -> np.ndarray:
    """Rotation body←sensor (rows: forward x, up y, right z) from an upright mean accelerometer.

    Thesis Eq 14 (vertical calibration) applied to the chest: y = mean specific force (points up
    while standing still), x = the forward hint (default sensor +x) made horizontal, z = x × y
    (right). A standing period fixes only "up"; the heading of x comes from the hint, which
    matters only for the sign of the forward lean (up- vs downstairs, supine vs prone).
    """
    up = np.asarray(mean_acc, dtype=float)
    up = up / np.linalg.norm(up)
    candidates = [np.asarray(forward_hint, dtype=float)] if forward_hint is not None else []
    candidates += [np.eye(3)[0], np.eye(3)[2], np.eye(3)[1]]
    for hint in candidates:
        horizontal = hint - (hint @ up) * up
        if np.linalg.norm(horizontal) > 0.3 * np.linalg.norm(hint):
            break
    forward = horizontal / np.linalg.norm(horizontal)
    right = np.cross(forward, up)
    return np.vstack([forward, up, right])


def scale_to_si(static_norm: float, units: str) -> float:
    """Factor turning input units into m/s², so the static norm becomes standard gravity.

    The thesis leaves g open (gait.md §3.7: "9.81 or the sensor's static norm"): we use the static
    norm of the reference period, which also absorbs a wrong unit or an uncalibrated gain. A norm
    more than 30 % away from 1 g in the declared unit is a clear mismatch and is warned about.
    """
    declared = {"m/s2": 1.0, "m/s^2": 1.0, "g": STANDARD_GRAVITY}
    if units not in declared:
        raise ValueError(f"units must be 'm/s2' or 'g', got {units!r}")
    norm_si = static_norm * declared[units]
    if not 0.7 * STANDARD_GRAVITY < norm_si < 1.3 * STANDARD_GRAVITY:
        guess = "g" if 0.7 < static_norm < 1.3 else ("m/s2" if 6.9 < static_norm < 12.7 else "raw counts")
        warnings.warn(
            f"static acceleration norm is {static_norm:.3g} {units} ({norm_si:.3g} m/s²): the input looks "
            f"like {guess}, not {units}; it is rescaled to its static norm = 1 g",
            UnitMismatchWarning,
            stacklevel=4,
        )
    return STANDARD_GRAVITY / static_norm if static_norm > 0 else declared[units]


def zero_phase_gravity(acc_body: np.ndarray, rate_hz: float) -> np.ndarray:
    """Zero-phase version of the GA filter, used only inside a transition window.

    The window analysis (ΔY, ∫SVM, transition instant) runs once per candidate on buffered data, so
    it can afford forward–backward filtering and avoid the 0.27 s lag of the causal GA.
    """
    b, a = gravity_lowpass_ba(rate_hz)
    pad = min(len(acc_body) - 1, int(3 * rate_hz))
    return signal.filtfilt(b, a, acc_body, axis=0, padlen=pad)


def group_delay_s(b: np.ndarray, a: np.ndarray, freq_hz: float, rate_hz: float) -> float:
    """Group delay (s) of a filter at one frequency."""
    _, delay = signal.group_delay((b, a), w=[freq_hz], fs=rate_hz)
    return float(delay[0]) / rate_hz


def clip_acos(x: float) -> float:
    """arccos clipped to [−1, 1] (gait.md §3.2, EXT)."""
    return math.acos(1.0 if x > 1.0 else (-1.0 if x < -1.0 else x))
