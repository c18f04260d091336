"""Steps from the trunk's acceleration magnitude: the SVM peak picker of thesis §7.2.6.

Shared by the activity monitor and the upright-reference finder (which has no orientation yet:
the magnitude needs none).
"""

from __future__ import annotations

from gait_biofeedback.core.activity.signal import Biquad, group_delay_s, step_lowpass_ba

STEP_LOWPASS_HZ = 3.0  # step SVM from raw |a| (READING gait.md §6 item 26), cadence < 180/min kept
STEP_PEAK_THRESHOLD = 1.0  # m/s² (≈ 0.1 g): "low" SVM peak threshold; slow walking peaks ≈ 2 m/s²
STEP_PEAK_RELEASE = 0.0  # m/s²: an SVM peak ends when the signal falls back below 0
MIN_STEP_S = 0.25  # successive peaks closer than this are one step (≤ 240 steps/min)
MAX_STEP_S = 1.3  # "pre-defined step duration": slow (stroke) gait has steps ≤ ~1.2 s
STEP_FREQUENCY_HZ = 1.8  # a typical step frequency, at which the low-pass's group delay is taken


class SvmPeaks:
    """Peaks of the step SVM: a peak starts above ``threshold`` and ends when the signal falls back
    below ``release``; its time is that of the maximum [T §7.2.6, Table 16(b) "low threshold"].

    ``update`` returns ``(t_max, tag_at_max)`` when a peak ends (the tag is any value the caller
    wants to know at the maximum, e.g. θ), else None.
    """

    __slots__ = ("_in", "_t", "_tag", "_value", "release", "threshold")

    def __init__(self, threshold: float, release: float) -> None:
        self.threshold = threshold
        self.release = release
        self._in = False
        self._value = self._t = self._tag = 0.0

    def reset(self) -> None:
        self._in = False

    def update(self, t: float, svm: float, tag: float = 0.0) -> tuple[float, float] | None:
        if not self._in:
            if svm > self.threshold:
                self._in = True
                self._value, self._t, self._tag = svm, t, tag
            return None
        if svm > self._value:
            self._value, self._t, self._tag = svm, t, tag
        if svm >= self.release:
            return None
        self._in = False
        return self._t, self._tag


class StepSvm:
    """The step SVM and its peaks, one definition for the walking detector and the upright finder:
    ``svm(excess)`` low-passes a sample's acceleration magnitude beyond gravity (m/s²) at
    :data:`STEP_LOWPASS_HZ`; ``peak(t, svm, tag)`` is :meth:`SvmPeaks.update` with the peak's time
    taken back by the low-pass's group delay (``delay``, ≈ 0.08 s at :data:`STEP_FREQUENCY_HZ`)."""

    def __init__(self, rate_hz: float) -> None:
        b, a = step_lowpass_ba(rate_hz, STEP_LOWPASS_HZ)
        self.filter = Biquad(b, a)
        self.delay = group_delay_s(b, a, STEP_FREQUENCY_HZ, rate_hz)
        self.peaks = SvmPeaks(STEP_PEAK_THRESHOLD, STEP_PEAK_RELEASE)

    def svm(self, excess: float) -> float:
        return self.filter.step(excess)

    def peak(self, t: float, svm: float, tag: float = 0.0) -> tuple[float, float] | None:
        found = self.peaks.update(t, svm, tag)
        return None if found is None else (found[0] - self.delay, found[1])
