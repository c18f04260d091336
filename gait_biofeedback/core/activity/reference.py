"""The trunk monitor's upright reference, found in the stream (issue 15; our addition to thesis §7.2.3).

The thesis takes "up" from a standing period the user names (Eq 14). A real recording starts with
the sensor being put on and handled (the first seconds of ``hapt_waist`` read as 23° of trunk
inclination), or seated (UCI), so the start cannot be taken blindly. :class:`UprightFinder` looks
for two things, sample by sample, with no orientation yet:

- a **quiet** period: ``quiet_s`` seconds in which every axis varies by less than
  ``QUIET_RELATIVE_STD`` of the mean's norm (2 %, 0.2 m/s²: a worn sensor standing still; the
  strap being fastened moves it far more). Its mean is a provisional "up": it may be a seated or
  lying rest, which nothing in the accelerometer alone can tell from standing;
- a **walking bout**: ``WALK_REFERENCE_STEPS`` successive peaks of the acceleration magnitude (the
  monitor's step detector, which needs no orientation), step intervals within the monitor's step
  duration, regular (interval CV < 25 %) and of steady direction. People walk upright, so the
  bout's mean acceleration is "up" (the issue's "mean acceleration over walking bouts"). It checks
  the quiet reference: within ``REREFERENCE_RAD`` (15°) the quiet one is kept (a still period is
  the more precise of the two, walking adds its own forward lean: 2-9° on ``hapt_waist``), beyond
  it the walking one replaces it.

A given ``reference_acc`` (the session calibration's standing, or a labelled period) skips all this.
Units do not matter here: the magnitude is compared with its own running mean.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from gait_biofeedback.core.activity.signal import STANDARD_GRAVITY, Biquad, group_delay_s, step_lowpass_ba
from gait_biofeedback.core.activity.steps import (
    MAX_STEP_S,
    MIN_STEP_S,
    STEP_LOWPASS_HZ,
    STEP_PEAK_RELEASE,
    STEP_PEAK_THRESHOLD,
    SvmPeaks,
)

QUIET_RELATIVE_STD = 0.02  # per-axis std / |mean| of a still worn sensor (hapt_waist standing: 0.3-1 %)
WALK_REFERENCE_STEPS = 10  # successive steps before a bout's mean is taken as "up" (~5 s of walking)
REREFERENCE_RAD = math.radians(15.0)  # a quiet reference this far from walking's "up" is replaced
WALK_STEADINESS = 0.9  # |mean a| / mean |a| over a bout: walking keeps its direction (≈ 0.97); a sensor
# turned over while handled does not (a 130° flip every second: ≈ 0.6)
WALK_INTERVAL_CV = 0.25  # step intervals of walking are regular: std/mean below this (shaking is not)
GRAVITY_TAU_S = 5.0  # time constant of the running mean of |a| that stands for 1 g


def angle_between(a: np.ndarray, b: np.ndarray) -> float:
    """Angle (rad) between two non-zero 3-vectors."""
    cos = float(a @ b) / float(np.linalg.norm(a) * np.linalg.norm(b))
    return math.acos(max(-1.0, min(1.0, cos)))


class UprightFinder:
    """``update(t, ax, ay, az) -> "quiet" | "walking" | "confirmed" | None``: what this sample decided.

    "quiet": the first quiet period is the reference; "walking": a walking bout is (the first
    reference, or it replaced the quiet one beyond ``REREFERENCE_RAD``); "confirmed": a walking bout
    kept the quiet one. :attr:`reference` is the current "up" (mean acceleration, sensor axes, input
    units), :attr:`angle` the angle (rad) between the walking bout and the reference it checked (nan
    if there was none), :attr:`walk_steps` the bout's step times (s, corrected by the step filter's
    group delay, as the monitor's steps). After a walking bout the finder is :attr:`done`. A
    ``reference`` given is taken as a quiet one already found (a monitor restarted after a gap).
    """

    def __init__(self, rate_hz: float, quiet_s: float, *, reference: np.ndarray | None = None) -> None:
        self.quiet_s = quiet_s
        self._n_quiet = max(2, round(quiet_s * rate_hz))
        self._window: deque[tuple[float, float, float]] = deque()
        self._sums = [0.0] * 6  # Σx, Σy, Σz, Σx², Σy², Σz²
        self.reference = reference
        self.angle = math.nan
        self.done = False
        self.walk_steps: list[float] = []
        b, a = step_lowpass_ba(rate_hz, STEP_LOWPASS_HZ)
        self._svm = Biquad(b, a)
        self._step_delay = group_delay_s(b, a, 1.8, rate_hz)
        self._peaks = SvmPeaks(STEP_PEAK_THRESHOLD, STEP_PEAK_RELEASE)
        self._alpha = 1.0 / (GRAVITY_TAU_S * rate_hz)
        self._g = math.nan
        self._run: list[float] = []
        self._run_sum = [0.0] * 5  # Σx, Σy, Σz, Σ|a|, n since the run's first step

    def update(self, t: float, ax: float, ay: float, az: float) -> str | None:
        norm = math.sqrt(ax * ax + ay * ay + az * az)
        if norm == 0.0 or self.done:
            return None  # a driver's all-zero start-up sample: no direction, no magnitude
        if math.isnan(self._g):
            self._g = norm
            self._svm.reset_steady(0.0)
        self._g += self._alpha * (norm - self._g)
        walking = self._walk(t, ax, ay, az, norm)
        if self.reference is None and self._is_quiet(ax, ay, az):
            self.reference = np.array(self._sums[:3]) / len(self._window)
            return "quiet"
        if walking is None:
            return None
        self.done = True
        if self.reference is not None:
            self.angle = angle_between(self.reference, walking)
            if self.angle <= REREFERENCE_RAD:
                return "confirmed"
        self.reference = walking
        return "walking"

    def _is_quiet(self, ax: float, ay: float, az: float) -> bool:
        window, s = self._window, self._sums
        window.append((ax, ay, az))
        for k, v in enumerate((ax, ay, az)):
            s[k] += v
            s[k + 3] += v * v
        if len(window) > self._n_quiet:
            for k, v in enumerate(window.popleft()):
                s[k] -= v
                s[k + 3] -= v * v
        n = len(window)
        if n < self._n_quiet:
            return False
        mean = [s[k] / n for k in range(3)]
        limit = (QUIET_RELATIVE_STD**2) * sum(m * m for m in mean)
        return all(s[k + 3] / n - mean[k] ** 2 < limit for k in range(3))

    def _walk(self, t: float, ax: float, ay: float, az: float, norm: float) -> np.ndarray | None:
        """The mean acceleration of a walking bout that has just reached WALK_REFERENCE_STEPS."""
        svm = self._svm.step(STANDARD_GRAVITY * (norm / self._g - 1.0))
        run, rs = self._run, self._run_sum
        if run:
            rs[0] += ax
            rs[1] += ay
            rs[2] += az
            rs[3] += norm
            rs[4] += 1.0
        peak = self._peaks.update(t, svm)
        if peak is None:
            if run and t - run[-1] > MAX_STEP_S + self._step_delay:
                run.clear()
            return None
        t_peak = peak[0] - self._step_delay
        if run and t_peak - run[-1] < MIN_STEP_S:
            return None
        if not run or t_peak - run[-1] > MAX_STEP_S:
            run.clear()
            rs[:] = [ax, ay, az, norm, 1.0]
        run.append(t_peak)
        if len(run) < WALK_REFERENCE_STEPS:
            return None
        mean = np.array(rs[:3]) / rs[4]
        intervals = np.diff(run)
        steps = list(run)
        run.clear()
        if float(np.linalg.norm(mean)) < WALK_STEADINESS * rs[3] / rs[4]:
            return None
        if float(np.std(intervals)) > WALK_INTERVAL_CV * float(np.mean(intervals)):
            return None
        self.walk_steps = steps
        return mean
