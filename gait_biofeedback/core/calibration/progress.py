"""How far the calibration protocol has got, live: seconds of quiet standing, movement cycles per leg.

The clinician sees "standing still: 2.1 of 3 s", then "hip moves: left 6, right 4 (hip flexion needs
10 per leg, walking 4 swings)" while the patient performs the protocol, before pressing Calibrate
(issue 48). The counts follow the calibration's own rules, computed sample by sample at a few
arithmetic operations per sample instead of over the buffer:

* *still* (:mod:`.windows`): on every segment the mean gyro norm below ``GYRO_STILL`` and the standard
  deviation of the accelerometer norm below ``ACC_STILL``; here the means are exponential, time
  constant half of ``STILL_WINDOW`` (the centred 0.5 s window of the calibration cannot be had live);
* *cycles* (:func:`.cycles.count_cycles`): a rise above ``+CYCLE_THRESHOLD`` after a fall below
  ``-CYCLE_THRESHOLD`` of the angular rate about the movement's axis, 25 ms exponential smoothing in
  place of the 50 ms moving mean. The axis is not known before the calibration: each sensor axis gets
  its own counter, and the count shown is that of the axis with the largest mean square since the
  standing (the diagonal of the calibration's principal-axis search). One leg sensor per side is
  counted: the thigh, else the shank, else the foot (a feet-only kit's walking calibration).

The cycles are counted from the moment the standing reaches the duration the calibration needs (the
calibration looks for the last such standing, then counts every cycle after it); a new standing that
long starts the count again. A figure, not the calibration's decision: the calibration itself says
what it found.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from gait_biofeedback.core.calibration.cycles import CYCLE_THRESHOLD, MIN_CYCLES
from gait_biofeedback.core.calibration.windows import ACC_STILL, GYRO_STILL, STILL_WINDOW
from gait_biofeedback.core.segments import SIDES
from gait_biofeedback.core.stamps import NS_PER_S

STILL_TAU_S = STILL_WINDOW / 2
SMOOTH_TAU_S = 0.025
BIAS_TAU_S = 1.0
SILENT_AFTER_S = 1.0
"""s: a segment without a sample for this long no longer holds the standing back (a kit's lost sensor)."""
LEG_ORDER = ("thigh", "shank", "foot")


@dataclass(frozen=True)
class Progress:
    """The protocol so far: quiet standing ``standing_s`` (the current run; 0 when moving) of the
    ``standing_needed_s``; ``ready``: a standing that long happened, and ``cycles`` per side counts the
    movement cycles since (None for a side without a leg sensor)."""

    standing_s: float
    standing_needed_s: float
    ready: bool
    cycles: dict[str, int | None]

    def text(self) -> str:
        """One line a clinician reads."""
        standing = f"standing still: {min(self.standing_s, self.standing_needed_s):.1f} of " \
                   f"{self.standing_needed_s:g} s"
        if not self.ready:
            return standing
        counts = ", ".join(f"{side} {n}" for side, n in self.cycles.items() if n is not None)
        return (f"standing done; moves since: {counts or 'no leg sensor'} (hip flexion needs "
                f"{MIN_CYCLES['hip_flexion']} per leg, walking {MIN_CYCLES['walking']} swings per leg)")

    def values(self) -> dict[str, str]:
        """Key-values of the ``calibration: progress`` status on /diagnostics."""
        out = {"standing_s": f"{self.standing_s:.2f}", "standing_needed_s": f"{self.standing_needed_s:g}",
               "standing_done": str(self.ready).lower(),
               "hip_flexion_cycles_needed": str(MIN_CYCLES["hip_flexion"]),
               "walking_swings_needed": str(MIN_CYCLES["walking"])}
        for side, n in self.cycles.items():
            out[f"{side}_cycles"] = "" if n is None else str(n)
        return out


class _Stillness:
    """One segment's exponential still test (module docstring)."""

    def __init__(self) -> None:
        self.t: float | None = None
        self.gyro = math.inf
        self.acc_mean = 0.0
        self.acc_square = 0.0
        self.still_since: float | None = None
        self.bias = [0.0, 0.0, 0.0]

    def add(self, t: float, acc: Sequence[float], gyr: Sequence[float]) -> None:
        a = math.sqrt(acc[0] ** 2 + acc[1] ** 2 + acc[2] ** 2)
        w = math.sqrt(gyr[0] ** 2 + gyr[1] ** 2 + gyr[2] ** 2)
        dt = math.inf if self.t is None else t - self.t
        if -SILENT_AFTER_S < dt <= 0.0:
            return  # a repeated or slightly older sample
        if not dt <= SILENT_AFTER_S:  # a first sample, a gap or time gone back: start over
            self.gyro, self.acc_mean, self.acc_square = w, a, a * a
            self.still_since = None
            self.bias = list(gyr)
        else:
            k = 1.0 - math.exp(-dt / STILL_TAU_S)
            self.gyro += k * (w - self.gyro)
            self.acc_mean += k * (a - self.acc_mean)
            self.acc_square += k * (a * a - self.acc_square)
        self.t = t
        acc_std = math.sqrt(max(self.acc_square - self.acc_mean ** 2, 0.0))
        if not (self.gyro < GYRO_STILL and acc_std < ACC_STILL):
            self.still_since = None
            return
        if self.still_since is None:
            self.still_since = t
        k = 1.0 - math.exp(-min(dt, SILENT_AFTER_S) / BIAS_TAU_S)  # the gyro's rest value, for the counters
        self.bias = [b + k * (g - b) for b, g in zip(self.bias, gyr, strict=True)]


class _CycleCounter:
    """Hysteresis cycle counters on the three axes of one leg sensor (module docstring)."""

    def __init__(self, bias: Sequence[float]) -> None:
        self.bias = list(bias)
        self.t: float | None = None
        self.smooth = [0.0, 0.0, 0.0]
        self.state = [0, 0, 0]
        self.counts = [0, 0, 0]
        self.square = [0.0, 0.0, 0.0]

    def add(self, t: float, gyr: Sequence[float]) -> None:
        k = 1.0 if self.t is None or not t > self.t else 1.0 - math.exp(-(t - self.t) / SMOOTH_TAU_S)
        self.t = t
        for i in range(3):
            rate = gyr[i] - self.bias[i]
            self.square[i] += rate * rate
            v = self.smooth[i] = self.smooth[i] + k * (rate - self.smooth[i])
            if v < -CYCLE_THRESHOLD:
                self.state[i] = -1
            elif v > CYCLE_THRESHOLD and self.state[i] == -1:
                self.counts[i] += 1
                self.state[i] = 1

    @property
    def cycles(self) -> int:
        return self.counts[max(range(3), key=self.square.__getitem__)]


class CalibrationProgress:
    """Live progress of the calibration protocol of ``segments`` (module docstring): feed every
    segment's samples with :meth:`add`, read :meth:`progress`."""

    def __init__(self, segments: Sequence[str], standing_needed_s: float) -> None:
        self.segments = list(segments)
        self.standing_needed_s = float(standing_needed_s)
        self._still = {s: _Stillness() for s in self.segments}
        self._counters: dict[str, _CycleCounter] = {}
        self._newest = -math.inf
        self.ready = False

    def _counted(self) -> dict[str, str | None]:
        """Side → its leg sensor counted (the first of thigh, shank, foot that sent data)."""
        return {side: next((f"{side}_{p}" for p in LEG_ORDER if self._still.get(f"{side}_{p}")
                            and self._still[f"{side}_{p}"].t is not None), None) for side in SIDES}

    def _standing_start(self) -> float | None:
        """Start (s) of the standing of every segment heard from in the last ``SILENT_AFTER_S``."""
        starts = [st.still_since for st in self._still.values()
                  if st.t is not None and self._newest - st.t <= SILENT_AFTER_S]
        if not starts or any(s is None for s in starts):
            return None
        return max(starts)

    def add(self, segment: str, stamp_ns: int, acc: Sequence[float], gyr: Sequence[float]) -> None:
        """One sample of ``segment`` (acc m/s², bias-corrected gyro rad/s)."""
        still = self._still.get(segment)
        if still is None:
            return
        t = stamp_ns / NS_PER_S
        if not all(math.isfinite(v) for v in (*acc, *gyr)):
            return
        still.add(t, acc, gyr)
        self._newest = max(self._newest, t)
        counter = self._counters.get(segment)
        if counter is not None:
            counter.add(t, gyr)
        start = self._standing_start()
        if start is not None and self._newest - start >= self.standing_needed_s:
            self.ready = True  # a (new) standing as long as needed: count from its end
            self._counters = {seg: _CycleCounter(self._still[seg].bias)
                              for seg in self._counted().values() if seg is not None}

    def progress(self) -> Progress:
        start = self._standing_start()
        standing = 0.0 if start is None else self._newest - start
        counted = self._counted()
        cycles = {side: (self._counters[seg].cycles if seg in self._counters else 0) if seg else None
                  for side, seg in counted.items()}
        return Progress(standing, self.standing_needed_s, self.ready, cycles)
