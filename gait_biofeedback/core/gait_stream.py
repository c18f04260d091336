"""Both feet's live gait events and strides: the stream rules around the detector and the tracker.

:class:`GaitEventStream` is what the ``gait_events`` node and the offline analysis
(:mod:`gait_biofeedback.analyze`) both drive: per foot a
:class:`~gait_biofeedback.core.gait_events.GaitEventDetector` (thesis Algorithm 1) and one shared
:class:`~gait_biofeedback.core.gait_cycles.GaitCycleTracker`, plus what a real stream needs:

- Calibration: a foot's samples are not used (counted as ``uncalibrated``) until its calibration is
  in force, unless ``use_standing_reference`` (the mounting is then taken from the first orientation,
  :func:`standing_reference`). :meth:`GaitEventStream.set_calibration` with ``from_t`` > 0 takes
  effect at the first sample stamped ``>= from_t`` (so a live node and the offline path switch at
  the same sample); ``from_t = 0``, or a stamp the foot has already passed, takes effect at once. A
  new calibration resets the foot's detector and strides.
- Bad input: a non-finite or zero quaternion is skipped; a stamp going backwards or a gap
  > ``max_gap`` s resets that foot (detector and strides), counted and said (:meth:`pop_messages`).
  A stream that stopped (the node's wall-clock check) is reported with :meth:`stream_stopped`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.gait_cycles import GaitCycle, GaitCycleTracker
from gait_biofeedback.core.gait_events import (
    EXTREMUM_WINDOW_S,
    REFRACTORY_S,
    THRESHOLD,
    TREND_FRACTION,
    GaitEvent,
    GaitEventDetector,
)
from gait_biofeedback.core.in_force import InForceQueue

FOOT_SIDES = ("left", "right")


def standing_reference(q: np.ndarray) -> np.ndarray:
    """Rotation r whose segment x axis is the horizontal projection of the IMU x axis at orientation q
    (y up): ``q_segment = q ⊗ r`` keeps the heading and removes the standing roll/pitch."""
    forward = quat.rotate(q, np.array([1.0, 0.0, 0.0]))
    forward[2] = 0.0
    forward /= np.linalg.norm(forward)
    up = np.array([0.0, 0.0, 1.0])
    segment_in_world = np.column_stack([forward, up, np.cross(forward, up)])
    return quat.from_matrix(quat.as_matrix(quat.conjugate(q)) @ segment_in_world)


class GaitEventStream:
    """Gait events and strides of the feet in ``sides`` (see module docstring)."""

    def __init__(self, sides: tuple[str, ...] | list[str] = FOOT_SIDES, rate_hz: float = 100.0,
                 threshold: float = THRESHOLD, refractory_s: float = REFRACTORY_S,
                 window_s: float = EXTREMUM_WINDOW_S, trend_fraction: float = TREND_FRACTION,
                 max_gap: float = 0.5, use_standing_reference: bool = False, symmetry_window: int = 10,
                 min_stride_s: float = 0.4, max_stride_s: float = 3.0) -> None:
        self.sides = list(sides)
        if not self.sides or any(s not in FOOT_SIDES for s in self.sides):
            raise ValueError(f"gait_events: sides must be 'left' and/or 'right', got {self.sides}")
        self.max_gap = float(max_gap)
        self.use_standing_reference = bool(use_standing_reference)
        self.tracker = GaitCycleTracker(symmetry_window=int(symmetry_window), min_stride_s=min_stride_s,
                                        max_stride_s=max_stride_s)
        self.detectors = {s: GaitEventDetector(s, rate_hz, threshold=threshold, refractory_s=refractory_s,
                                               window_s=window_s, trend_fraction=trend_fraction)
                          for s in self.sides}
        self.calibrated = {s: False for s in self.sides}
        self.counts = {s: {"samples": 0, "uncalibrated": 0, "resets": 0, "stream_stops": 0, "ic": 0, "tc": 0,
                           "strides": 0, "implausible_strides": 0} for s in self.sides}
        self.notes: dict[str, str] = {s: "" for s in self.sides}
        self._last_t: dict[str, float | None] = {s: None for s in self.sides}
        self._waiting: dict[str, InForceQueue[np.ndarray]] = {s: InForceQueue() for s in self.sides}
        self._stamps: dict[tuple[str, float], Any] = {}
        self._messages: list[tuple[str, str]] = []

    def pop_messages(self) -> list[tuple[str, str]]:
        """(level "info"/"warn", text) said since the last call."""
        out, self._messages = self._messages, []
        return out

    def set_calibration(self, side: str, rotation: np.ndarray | None, valid: bool = True, message: str = "",
                        from_t: float = 0.0) -> None:
        """The foot calibration r (segment → sensor) of ``side``, in force from stamp ``from_t`` s."""
        if side not in self.detectors:
            return
        if not valid or rotation is None:
            self.notes[side] = f"calibration invalid: {message}"
            return
        last = self._last_t[side]
        if from_t > 0 and (last is None or from_t > last):
            self._waiting[side].put(float(from_t), np.asarray(rotation, dtype=float))
            return
        self._apply(side, np.asarray(rotation, dtype=float))

    def _apply(self, side: str, rotation: np.ndarray) -> None:
        self.detectors[side].set_mounting(rotation)
        self.reset(side, "new calibration")
        self.calibrated[side] = True
        self.notes[side] = ""

    def reset(self, side: str, why: str) -> None:
        """Forget ``side``'s detector state and open strides (counted; noted for /diagnostics)."""
        self.detectors[side].reset()
        self.tracker.reset(side)
        self._last_t[side] = None
        self.counts[side]["resets"] += 1
        self.notes[side] = f"state reset: {why}"

    def stream_stopped(self, side: str, seconds: float) -> None:
        """``side``'s samples stopped ``seconds`` ago (wall clock): reset its state."""
        self.counts[side]["stream_stops"] += 1
        self.reset(side, "stream stopped")
        self._messages.append(("warn", f"{side} foot: no data for {seconds:.1f} s, state reset"))

    def update(self, side: str, t: float, q: tuple[float, float, float, float],
               stamp: Any = None) -> list[tuple[GaitEvent, GaitCycle | None]]:
        """One orientation sample (sensor→world w, x, y, z) of ``side``'s foot at stamp ``t`` s →
        the events it confirmed, each with the stride it closed (or None). ``stamp`` is handed back in
        the event (and remembered for :meth:`stamp_of`)."""
        counts = self.counts[side]
        counts["samples"] += 1
        if not all(math.isfinite(v) for v in q) or tuple(q) == (0.0, 0.0, 0.0, 0.0):
            return []
        for rotation in self._waiting[side].due(t):
            self._apply(side, rotation)
        if not self.calibrated[side]:
            if not self.use_standing_reference:
                counts["uncalibrated"] += 1
                return []
            self.detectors[side].set_mounting(standing_reference(np.array(q)))
            self.calibrated[side] = True
        last = self._last_t[side]
        if last is not None and (t <= last or t - last > self.max_gap):
            self.reset(side, "time went backwards" if t <= last else f"{t - last:.2f} s gap in the stamps")
            self._messages.append(("warn", f"{side} foot: {self.notes[side]}"))
        self._last_t[side] = t
        event = self.detectors[side].update(t, q, stamp)
        if event is None:
            return []
        counts[event.kind] += 1
        self._stamps[(side, event.t)] = event.stamp
        if len(self._stamps) > 64:
            del self._stamps[next(iter(self._stamps))]
        cycle = self.tracker.add(event)
        if cycle is not None:
            counts["strides"] += 1
            if not cycle.plausible:
                counts["implausible_strides"] += 1
                self._messages.append(("warn", f"{cycle.side} stride {cycle.index} flagged: {cycle.flag}"))
        return [(event, cycle)]

    def stamp_of(self, side: str, t: float) -> Any:
        """The caller's stamp of ``side``'s recent event at ``t`` s, None if not remembered."""
        return self._stamps.get((side, t))
