"""The chest activity monitor on a live stream: the input rules around :class:`ActivityMonitor`.

Shared by the ``activity_monitor`` node and the offline ``analyze`` path, so both see the same
states. NaN/inf samples and repeated stamps are skipped and counted; a stamp going backwards or a gap
longer than ``max_gap`` s restarts the monitor (its upright reference is taken again from the next
``reference_s`` s); a state is "changed" when posture, locomotion or the last transition differ from
the last changed one. A trunk forward axis (from the chest's sensor-to-segment calibration) is handed
to the monitor at the first sample at or after its "in force" stamp, or at once if that has passed,
as the calibration is for the other consumers (the monitor applies it to the states it emits from
then on, see ``ActivityMonitor.set_forward_axis``). A restart keeps the forward axis and the wearer's
walking-sway history.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from gait_biofeedback.core.activity import ActivityMonitor, ActivityState, check_forward_axis
from gait_biofeedback.core.in_force import InForceQueue


class ActivityStream:
    """One chest accelerometer stream (see module docstring)."""

    def __init__(self, rate_hz: float, max_gap: float = 0.5, **monitor_options: Any) -> None:
        self.rate_hz = float(rate_hz)
        self.max_gap = float(max_gap)
        self.options = dict(monitor_options)
        self.monitor = ActivityMonitor(self.rate_hz, **monitor_options)
        self.counts = {"samples": 0, "nan_skipped": 0, "duplicates": 0, "restarts": 0}
        self.latest: ActivityState | None = None
        self._t_last: float | None = None
        self._key: tuple | None = None
        self._waiting_forward: InForceQueue[list[float]] = InForceQueue()

    def set_forward_axis(self, forward_axis: Sequence[float], from_t: float = 0.0) -> None:
        """Trunk forward in sensor axes, in force from stamp ``from_t`` s (see module docstring).

        Raises ValueError when it is not a usable direction (zero, NaN, or vertical for the mounting).
        """
        forward = check_forward_axis(forward_axis).tolist()
        if from_t > 0.0 and (self._t_last is None or from_t > self._t_last):
            self._waiting_forward.put(float(from_t), forward)
            return
        problem = self._apply_forward(forward)
        if problem:
            raise ValueError(problem)

    def _apply_forward(self, forward: list[float]) -> str:
        """Hand the axis to the monitor; the reason it was refused, or ""."""
        try:
            self.monitor.set_forward_axis(forward)
        except ValueError as exc:
            return f"{exc}: the previous forward axis is kept"
        self.options["forward_axis"] = forward  # kept across restarts
        return ""

    def update(self, t: float, acc: tuple[float, float, float]) -> tuple[ActivityState | None, bool, str]:
        """One sample → (the newest state or None, whether it changed, a warning or "")."""
        self.counts["samples"] += 1
        if not all(math.isfinite(v) for v in acc):
            self.counts["nan_skipped"] += 1
            return None, False, ""
        warning = ""
        if self._t_last is not None:
            dt = t - self._t_last
            if dt == 0.0:
                self.counts["duplicates"] += 1
                return None, False, ""
            if dt < 0.0 or dt > self.max_gap:
                self.counts["restarts"] += 1
                warning = (f"time went back {-dt:.3f} s" if dt < 0.0 else f"{dt:.2f} s without data") \
                    + ": activity monitor restarted"
                previous, self.monitor = self.monitor, ActivityMonitor(self.rate_hz, **self.options)
                self.monitor.keep_wearer_history(previous)
        self._t_last = t
        for forward in self._waiting_forward.due(t):
            problem = self._apply_forward(forward)
            warning = "; ".join(text for text in (warning, problem) if text)
        state = self.monitor.update(t, acc)
        if state is None:
            return None, False, warning
        self.latest = state
        key = (state.posture, state.locomotion, state.last_transition, state.last_transition_t)
        changed = key != self._key
        self._key = key
        return state, changed, warning
