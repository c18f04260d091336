"""Thigh inclination for posture (issue 15 item 4; our addition to thesis ch. 7).

A trunk sensor alone cannot tell still sitting from still standing: the chest is as upright in both
(the qmt walk sits for 30 s with the chest at 3-4° and the thighs at 80°). With thigh sensors (this
project's own set) the thigh's inclination decides: a seated thigh is near horizontal, a standing one
near vertical. :class:`ThighTilt` gives that inclination sample by sample: the angle between the
thigh accelerometer's gravity component (the monitor's GA low-pass, thesis §7.2.3) and the thigh's
upright, which :class:`~gait_biofeedback.core.activity.reference.UprightFinder` finds as for the
trunk (the first quiet period, checked by walking: a thigh swings about its upright while walking,
mean flexion 5-10°, within the finder's 15°). A sensor-to-segment calibration gives the upright
outright (the thigh segment's y axis in sensor axes): from the stamp it is in force, it replaces the
finder's, so a calibration in force from the start (``analyze``) reads the posture from the first
samples instead of assuming one until the first quiet period (qmt: "sitting (assumed)" for 5.2 s of
standing).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence

import numpy as np

from gait_biofeedback.core.activity.reference import UprightFinder
from gait_biofeedback.core.activity.signal import Biquad, clip_acos, gravity_lowpass_ba
from gait_biofeedback.core.in_force import InForceQueue
from gait_biofeedback.core.stamps import NS_PER_S

THIGH_SIT_RAD = math.radians(50.0)  # mean thigh inclination held above this ⇒ sitting (qmt seated: 80°)
THIGH_STAND_RAD = math.radians(30.0)  # below this (or walking) ⇒ standing (qmt walking: 5-15°)
THIGH_HOLD_S = 1.0  # the new level must hold this long


class ThighTilt:
    """``update(t, acc) -> inclination (rad) | None``: None until the thigh's upright is known."""

    def __init__(self, rate_hz: float, quiet_s: float) -> None:
        self._finder = UprightFinder(rate_hz, quiet_s)
        b, a = gravity_lowpass_ba(rate_hz)
        self._gravity = [Biquad(b, a) for _ in range(3)]
        self._up: np.ndarray | None = None
        self._calibrated = False
        self._started = False

    @property
    def upright(self) -> np.ndarray | None:
        """The thigh's upright in sensor axes (unit vector), once found."""
        return self._up

    def set_upright(self, upright: Sequence[float]) -> None:
        """The thigh's upright in sensor axes from a calibration: kept, the finder no longer moves it."""
        up = np.asarray(upright, dtype=float)
        self._up = up / np.linalg.norm(up)
        self._calibrated = True

    def update(self, t: float, acc: Sequence[float]) -> float | None:
        ax, ay, az = float(acc[0]), float(acc[1]), float(acc[2])
        if not self._started:
            for biquad, value in zip(self._gravity, (ax, ay, az), strict=True):
                biquad.reset_steady(value)
            self._started = True
        gx, gy, gz = (f.step(v) for f, v in zip(self._gravity, (ax, ay, az), strict=True))
        finder = self._finder
        if finder.update(t, ax, ay, az) in ("quiet", "walking") and not self._calibrated:
            self._up = finder.reference / np.linalg.norm(finder.reference)
        up = self._up
        if up is None:
            return None
        norm = math.sqrt(gx * gx + gy * gy + gz * gz)
        return clip_acos((gx * up[0] + gy * up[1] + gz * up[2]) / norm) if norm > 0.0 else None


THIGH_WAIT_S = 0.2  # a trunk sample waits at most this long (trunk stream time) for the thighs' samples
THIGH_SILENT_S = 1.0  # a thigh silent this long is neither waited for nor used until it sends again
THIGH_MATCH_S = 0.1  # the thigh value used is the newest at or before the trunk stamp, at most this old
_HISTORY_NS = 2 * NS_PER_S


class ThighInputs:
    """The thighs' inclinations matched to the trunk's samples by stamp.

    Each thigh stream gets a :class:`ThighTilt`. A trunk sample is ``ready`` once every thigh that is
    sending (heard within THIGH_SILENT_S) has a sample at or after its stamp, or once the trunk
    stream is THIGH_WAIT_S past it: the node (arrival order) and ``analyze`` (log order) then see
    the same values unless a thigh message arrives over 0.2 s late. The value for a trunk sample is
    the mean over the thighs of their newest inclination at or before its stamp (≤ THIGH_MATCH_S old).
    """

    def __init__(self, segments: Sequence[str], rate_hz: float, quiet_s: float) -> None:
        self.rate_hz = rate_hz
        self.quiet_s = quiet_s
        self._tilts: dict[str, ThighTilt] = {}
        self._history: dict[str, deque[tuple[int, float | None]]] = {seg: deque() for seg in segments}
        self._uprights: dict[str, InForceQueue[np.ndarray]] = {seg: InForceQueue() for seg in segments}
        self.counts = {"thigh_samples": 0, "thigh_skipped": 0, "thigh_restarts": 0}

    @property
    def segments(self) -> tuple[str, ...]:
        return tuple(self._history)

    def calibrate(self, segment: str, upright: np.ndarray, from_ns: int) -> None:
        """A calibration's upright (sensor axes) for ``segment``, used from its sample stamped ``from_ns``
        on (by stamp, so the node and ``analyze`` switch at the same sample)."""
        self._uprights[segment].put(int(from_ns), upright)

    def clear(self) -> None:
        """Forget the samples heard (the trunk's time went back); the thighs' uprights are kept."""
        for history in self._history.values():
            history.clear()

    def add(self, segment: str, stamp_ns: int, acc: Sequence[float]) -> None:
        """One thigh sample; NaN samples and stamps not after the last are skipped and counted."""
        history = self._history[segment]
        self.counts["thigh_samples"] += 1
        if not all(math.isfinite(v) for v in acc) or (history and stamp_ns == history[-1][0]):
            self.counts["thigh_skipped"] += 1
            return
        if history and stamp_ns < history[-1][0]:
            history.clear()  # time went back (a loop, a restart): the history starts again
            self.counts["thigh_restarts"] += 1
        tilt = self._tilts.get(segment)
        if tilt is None:
            tilt = self._tilts[segment] = ThighTilt(self.rate_hz, self.quiet_s)
        for upright in self._uprights[segment].due(stamp_ns):
            tilt.set_upright(upright)
        history.append((stamp_ns, tilt.update(stamp_ns / NS_PER_S, acc)))
        while history[0][0] < stamp_ns - _HISTORY_NS:
            history.popleft()

    def _sending(self, newest_ns: int) -> list[deque[tuple[int, float | None]]]:
        limit = newest_ns - round(THIGH_SILENT_S * NS_PER_S)
        return [h for h in self._history.values() if h and h[-1][0] >= limit]

    def ready(self, stamp_ns: int, newest_ns: int) -> bool:
        if newest_ns - stamp_ns > THIGH_WAIT_S * NS_PER_S:
            return True
        return all(h[-1][0] >= stamp_ns for h in self._sending(newest_ns))

    def inclination_at(self, stamp_ns: int, newest_ns: int) -> float | None:
        values = []
        oldest = stamp_ns - round(THIGH_MATCH_S * NS_PER_S)
        for history in self._sending(newest_ns):
            for t, value in reversed(history):
                if t <= stamp_ns:
                    if t >= oldest and value is not None:
                        values.append(value)
                    break
        return sum(values) / len(values) if values else None
