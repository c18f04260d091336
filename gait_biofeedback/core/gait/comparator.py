"""Literature comparator (thesis Table 15): IC/TC from the sagittal angular velocity of the foot or shank.

The rules follow the cues the thesis gives for Catalfamo et al. 2010 [T ref 372] and Maqbool et al.
2017 [T ref 378] (gait.md §2.9): a mid-swing peak of the sagittal angular velocity ω, TC = the minimum
of ω before the mid-swing peak (below a magnitude threshold), IC = the first local minimum of ω after
the mid-swing peak, and a 300 ms time threshold between events of one type (Maqbool). The exact
thresholds of those papers are not in the thesis (gait.md §6.2 #22); the values here are ours, stated
in SI, not tuned on the benchmark data. Written from that description only.

Signal: ω = gyro · R(r) e_z, the angular rate about the segment's mediolateral axis (ISB z, right), so
ω > 0 rotates the toes (or the shank) forward/up: positive in mid-swing for foot and shank.
Causality: IC is confirmed one sample after the local minimum; TC can only be known to be the last
minimum before swing once ω crosses ``swing_threshold``, so its latency is longer (reported).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.gait.events import INITIAL_CONTACT, TERMINAL_CONTACT, GaitEvent, samples_for
from gait_biofeedback.core.stamps import sample_stamps

SWING_THRESHOLD = 1.0  # rad/s, mid-swing: ω above this
TC_THRESHOLD = 0.3  # rad/s, the pre-swing minimum must be below -TC_THRESHOLD
COMPARATOR_REFRACTORY_S = 0.300  # Maqbool et al. 2017 time threshold


class AngularVelocityEventDetector:
    """Streaming comparator for one foot (or shank); ``update(t, omega)`` → :class:`GaitEvent` or None."""

    def __init__(self, side: str = "left", rate_hz: float = 100.0, swing_threshold: float = SWING_THRESHOLD,
                 tc_threshold: float = TC_THRESHOLD, refractory_s: float = COMPARATOR_REFRACTORY_S) -> None:
        self.side = side
        self.swing_threshold = float(swing_threshold)
        self.tc_threshold = float(tc_threshold)
        self.refractory = samples_for(refractory_s, rate_hz)
        self.counts = {INITIAL_CONTACT: 0, TERMINAL_CONTACT: 0}
        self.reset()

    def reset(self) -> None:
        """Forget the state (stream gap)."""
        self._k = -1
        self._k_ic = -math.inf
        self._k_tc = -math.inf
        self.in_swing = False
        self._past_peak = False
        self._min = (math.inf, 0)  # (ω, stamp ns) of the lowest ω since the last IC
        self._prev: list[tuple[float, int]] = []

    def update(self, stamp_ns: int, omega: float) -> GaitEvent | None:
        """One sagittal angular-velocity sample (rad/s) stamped ``stamp_ns``."""
        self._k += 1
        k = self._k
        prev = self._prev
        prev.append((omega, stamp_ns))
        if len(prev) > 3:
            del prev[0]
        event = None
        if not self.in_swing:
            if k - self._k_ic > self.refractory and omega < self._min[0]:
                self._min = (omega, stamp_ns)
            if (omega > self.swing_threshold and self._min[0] < -self.tc_threshold
                    and k - self._k_tc > self.refractory):
                w_min, stamp_min = self._min
                event = self._event(TERMINAL_CONTACT, stamp_min, stamp_ns, w_min)
                self._k_tc = k
                self.in_swing, self._past_peak = True, False
        else:
            if len(prev) == 3 and prev[1][0] < prev[0][0]:
                self._past_peak = True
            if (self._past_peak and len(prev) == 3 and prev[1][0] < 0.0 and prev[1][0] < prev[0][0]
                    and prev[1][0] <= omega and k - self._k_ic > self.refractory):
                w, stamp_ic = prev[1]
                event = self._event(INITIAL_CONTACT, stamp_ic, stamp_ns, w)
                self._k_ic = k
                self.in_swing = False
                self._min = (math.inf, 0)
        return event

    def _event(self, kind: str, stamp_ns: int, detected_ns: int, value: float) -> GaitEvent:
        self.counts[kind] += 1
        return GaitEvent(self.side, kind, stamp_ns, detected_ns, value, self.counts[kind])


def sagittal_rate(gyr: np.ndarray, mounting: np.ndarray | None) -> np.ndarray:
    """ω (N,) about the segment's mediolateral axis R(r) e_z from gyro (N, 3) in the sensor frame."""
    r = quat.IDENTITY if mounting is None else np.asarray(mounting, dtype=float)
    return np.asarray(gyr, dtype=float) @ quat.rotate(quat.normalize(r), np.array([0.0, 0.0, 1.0]))


def angular_velocity_events(gyr: np.ndarray, rate_hz: float, mounting: np.ndarray | None = None,
                            **options: Any) -> dict[str, list[float]]:
    """Batch comparator: ``{"ic": [s], "tc": [s]}`` event times (sample 0 at 0 s) of one foot's gyro
    (N, 3) in the sensor frame with the calibration ``mounting`` r."""
    omega = sagittal_rate(gyr, mounting)
    detector = AngularVelocityEventDetector(rate_hz=rate_hz, **options)
    out: dict[str, list[float]] = {INITIAL_CONTACT: [], TERMINAL_CONTACT: []}
    for stamp_ns, wk in zip(sample_stamps(len(omega), rate_hz).tolist(), omega.tolist(), strict=True):
        if math.isfinite(wk) and (event := detector.update(stamp_ns, wk)) is not None:
            out[event.kind].append(event.t)
    return out
