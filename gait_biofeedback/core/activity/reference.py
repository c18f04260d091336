"""The trunk monitor's upright reference, found in the stream (issue 15; our addition to thesis §7.2.3).

The thesis takes "up" from a standing period the user names (Eq 14). A real recording starts with
the sensor being put on and handled (the first seconds of ``hapt_waist`` read as 23° of trunk
inclination), or seated (UCI), so the start cannot be taken blindly. :class:`UprightFinder` looks
for two things, sample by sample, with no orientation yet:

- a **quiet** period: ``quiet_s`` seconds in which every axis varies by less than
  ``QUIET_RELATIVE_STD`` of the mean's norm (2 %, 0.2 m/s²: a worn sensor standing still; the
  strap being fastened moves it far more). Its mean is a provisional "up": it may be a seated or
  lying rest, which nothing in the accelerometer alone can tell from standing. The period must also
  show a wearer (:class:`WearerWindow`, on the gyro, or without one on the accelerometer): a sensor
  lying on a table before it is worn is as quiet as a standing wearer, but it reads only its own
  noise, where a worn trunk sways and breathes (UCI chest subjects 6, 8, 10: 14-30 s on a table, their
  counts' low band 0.5-1.5× white noise; worn and seated mostly 2-30×);
- a **walking bout**: ``WALK_REFERENCE_STEPS`` successive peaks of the acceleration magnitude (the
  monitor's step detector, which needs no orientation), step intervals within the monitor's step
  duration, regular (interval CV < 25 %) and of steady direction. People walk upright, so the
  bout's mean acceleration is "up" (the issue's "mean acceleration over walking bouts"). It checks
  the quiet reference: within ``REREFERENCE_RAD`` (15°; the chest 8°) the quiet one is kept (a still period is
  the more precise of the two, walking adds its own forward lean: 2-9° on ``hapt_waist``), beyond
  it the walking one replaces it.

A given ``reference_acc`` (the session calibration's standing, or a labelled period) skips all this.
Units do not matter here: the magnitude is compared with its own running mean.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np
from scipy import signal

from gait_biofeedback.core.activity.signal import STANDARD_GRAVITY, Biquad
from gait_biofeedback.core.activity.steps import MAX_STEP_S, MIN_STEP_S, StepSvm

QUIET_RELATIVE_STD = 0.02  # per-axis std / |mean| of a still worn sensor (hapt_waist standing: 0.3-1 %)
WALK_REFERENCE_STEPS = 10  # successive steps before a bout's mean is taken as "up" (~5 s of walking)
REREFERENCE_RAD = math.radians(15.0)  # a quiet reference this far from walking's "up" is replaced ...
CHEST_REREFERENCE_RAD = math.radians(8.0)  # ... on the chest from 8°: walking leans the chest 0.9-6.5° from
# its standing (UCI, 15 subjects), a seated chest is 4-45° from walking. UCI dev 1-7, nothing handed, posture:
# 15° 82.9 %, 12° and 10° 90.9 %, 6-8° 95.9 %; held-out 8-15 90.0 % at all of them
WALK_STEADINESS = 0.9  # |mean a| / mean |a| over a bout: walking keeps its direction (≈ 0.97); a sensor
# turned over while handled does not (a 130° flip every second: ≈ 0.6)
WALK_INTERVAL_CV = 0.25  # step intervals of walking are regular: std/mean below this (shaking is not)
GRAVITY_TAU_S = 5.0  # time constant of the running mean of |a| that stands for 1 g
WORN_LOW_HZ = 2.0  # a wearer's trunk sways and breathes below 2 Hz ...
WORN_NOISE_HZ = 8.0  # ... against the gyro's noise, measured from 2 to 8 Hz (or 0.3 × the rate: a sensor's
# anti-alias filter passes to ~0.4 × its rate)
WORN_SETTLE_S = 1.0  # the filters' start-up (the 2 Hz low-pass settles in ~0.5 s)
WORN_RATIO = 2.0  # the gyro's power density below 2 Hz ≥ 2× that from 2 to 8 Hz (white noise: 1×; its 2 s
# windows 0.5-1.4×, 5-95 %). hapt_waist: the phone on a table 0.6× (user23_run1, 0-12 s); worn standing
# windows 0.7-12×, the first ≥ 2× within 0-6 s of the first quiet one (3× gave the same scores)
NO_GYRO_VARIANCE = 1e-12  # (rad/s)²: a gyro quieter than this from 2 to 8 Hz sends nothing (MEMS: ≥ 1e-8)


def angle_between(a: np.ndarray, b: np.ndarray) -> float:
    """Angle (rad) between two non-zero 3-vectors."""
    cos = float(a @ b) / float(np.linalg.norm(a) * np.linalg.norm(b))
    return math.acos(max(-1.0, min(1.0, cos)))


class WearerWindow:
    """Whether the last ``n`` gyro (or accelerometer) samples show a wearer, not just the sensor's noise.

    The signal is low-passed at WORN_LOW_HZ and band-passed from there to WORN_NOISE_HZ (two
    Butterworth low-passes, per axis); the window's variances (bias-free) are compared as power
    densities, each against what white noise gives through the same filter (their impulse responses'
    energy). The filters start from the first reading and settle for WORN_SETTLE_S before the window
    takes their output (a start-up transient is low-frequency power the sensor never had).
    :meth:`shows_wearer` is None before any reading and when the signal is exactly constant (a driver
    that sends no gyro: the accelerometer's window decides instead), False until the window is full.
    """

    def __init__(self, rate_hz: float, n: int) -> None:
        self._n = n
        sections = [signal.butter(2, f, fs=rate_hz) for f in (WORN_LOW_HZ, min(WORN_NOISE_HZ, 0.3 * rate_hz))]
        impulse = np.zeros(round(5.0 * rate_hz))
        impulse[0] = 1.0
        low, wide = (signal.lfilter(b, a, impulse) for b, a in sections)
        self._white = float(np.sum(low**2) / np.sum((wide - low) ** 2))
        self._filters = [[Biquad(b, a) for b, a in sections] for _ in range(3)]
        self._window: deque[tuple[float, ...]] = deque()
        self._sums = [0.0] * 12  # Σ and Σ² of the low and the band, per axis
        self._started = False
        self._settling = round(WORN_SETTLE_S * rate_hz)

    def update(self, gyro: tuple[float, float, float]) -> None:
        if not self._started:
            for filters, value in zip(self._filters, gyro, strict=True):
                for biquad in filters:
                    biquad.reset_steady(value)
            self._started = True
        row = []
        for (low_pass, wide_pass), value in zip(self._filters, gyro, strict=True):
            low = low_pass.step(value)
            row += [low, wide_pass.step(value) - low]
        if self._settling:
            self._settling -= 1
            return
        self._window.append(tuple(row))
        self._add(row, 1.0)
        if len(self._window) > self._n:
            self._add(self._window.popleft(), -1.0)

    def _add(self, row, sign: float) -> None:
        for k, value in enumerate(row):
            self._sums[k] += sign * value
            self._sums[k + 6] += sign * value * value

    def shows_wearer(self) -> bool | None:
        n = len(self._window)
        if n < self._n:
            return None if not self._started else False
        variances = [self._sums[k + 6] / n - (self._sums[k] / n) ** 2 for k in range(6)]
        low, band = sum(variances[0::2]), sum(variances[1::2])
        if band <= NO_GYRO_VARIANCE:
            return None
        return low / band >= WORN_RATIO * self._white


class UprightFinder:
    """``update(t, ax, ay, az, gyro) -> "quiet" | "walking" | "confirmed" | None``: what this sample decided.

    "quiet": the first quiet period is the reference; "walking": a walking bout is (the first
    reference, or it replaced the quiet one beyond ``REREFERENCE_RAD``); "confirmed": a walking bout
    kept the quiet one. :attr:`reference` is the current "up" (mean acceleration, sensor axes, input
    units), :attr:`angle` the angle (rad) between the walking bout and the reference it checked (nan
    if there was none), :attr:`walk_steps` the bout's step times (s, corrected by the step filter's
    group delay, as the monitor's steps). After a walking bout the finder is :attr:`done`. A
    ``reference`` given is taken as a quiet one already found (a monitor restarted after a gap).
    ``gyro`` (rad/s, any bias) or None: a quiet period counts only if the gyro, or without one (or with
    one that sends a constant) the accelerometer, shows a wearer (a noiseless simulated sensor passes:
    nothing to judge).
    ``rereference_rad``: how far from the walking bout a quiet reference may be and be kept.
    """

    def __init__(self, rate_hz: float, quiet_s: float, *, reference: np.ndarray | None = None,
                 rereference_rad: float = REREFERENCE_RAD) -> None:
        self.quiet_s = quiet_s
        self.rereference_rad = rereference_rad
        self._n_quiet = max(2, round(quiet_s * rate_hz))
        self._window: deque[tuple[float, float, float]] = deque()
        self._sums = [0.0] * 6  # Σx, Σy, Σz, Σx², Σy², Σz²
        self.reference = reference
        self.angle = math.nan
        self.done = False
        self.walk_steps: list[float] = []
        self._steps = StepSvm(rate_hz)
        self._alpha = 1.0 / (GRAVITY_TAU_S * rate_hz)
        self._g = math.nan
        self._run: list[float] = []
        self._run_sum = [0.0] * 5  # Σx, Σy, Σz, Σ|a|, n since the run's first step
        self._gyro = WearerWindow(rate_hz, self._n_quiet)
        self._acc = WearerWindow(rate_hz, self._n_quiet)

    def update(self, t: float, ax: float, ay: float, az: float,
               gyro: tuple[float, float, float] | None = None) -> str | None:
        norm = math.sqrt(ax * ax + ay * ay + az * az)
        if norm == 0.0 or self.done:
            return None  # a driver's all-zero start-up sample: no direction, no magnitude
        if math.isnan(self._g):
            self._g = norm
            self._steps.filter.reset_steady(0.0)
        self._g += self._alpha * (norm - self._g)
        walking = self._walk(t, ax, ay, az, norm)
        if self.reference is None:
            if gyro is not None:
                self._gyro.update(gyro)
            self._acc.update((ax, ay, az))
            wearer = self._gyro.shows_wearer()  # None: no gyro, or one that sends a constant
            if wearer is None:
                wearer = self._acc.shows_wearer()
            if self._is_quiet(ax, ay, az) and wearer is not False:
                self.reference = np.array(self._sums[:3]) / len(self._window)
                return "quiet"
        if walking is None:
            return None
        self.done = True
        if self.reference is not None:
            self.angle = angle_between(self.reference, walking)
            if self.angle <= self.rereference_rad:
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
        svm = self._steps.svm(STANDARD_GRAVITY * (norm / self._g - 1.0))
        run, rs = self._run, self._run_sum
        if run:
            rs[0] += ax
            rs[1] += ay
            rs[2] += az
            rs[3] += norm
            rs[4] += 1.0
        peak = self._steps.peak(t, svm)
        if peak is None:
            if run and t - run[-1] > MAX_STEP_S + self._steps.delay:
                run.clear()
            return None
        t_peak = peak[0]
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
