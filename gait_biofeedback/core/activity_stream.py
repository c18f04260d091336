"""The chest activity monitor on a live stream: the input rules around :class:`ActivityMonitor`.

Shared by the ``activity_monitor`` node and the offline ``analyze`` path, so both see the same
states. NaN/inf samples and repeated stamps are skipped and counted; a stamp going backwards or a gap
longer than ``max_gap`` s restarts the monitor (its upright reference is taken again from the next
``reference_s`` s); a state is "changed" when posture, locomotion or the last transition differ from
the last changed one.
"""

from __future__ import annotations

import math
from typing import Any

from gait_biofeedback.core.activity import ActivityMonitor, ActivityState


class ActivityStream:
    """One chest accelerometer stream (see module docstring)."""

    def __init__(self, rate_hz: float, max_gap: float = 0.5, **monitor_options: Any) -> None:
        self.rate_hz = float(rate_hz)
        self.max_gap = float(max_gap)
        self.options = monitor_options
        self.monitor = ActivityMonitor(self.rate_hz, **monitor_options)
        self.counts = {"samples": 0, "nan_skipped": 0, "duplicates": 0, "restarts": 0}
        self.latest: ActivityState | None = None
        self._t_last: float | None = None
        self._key: tuple | None = None

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
                self.monitor = ActivityMonitor(self.rate_hz, **self.options)
        self._t_last = t
        state = self.monitor.update(t, acc)
        if state is None:
            return None, False, warning
        self.latest = state
        key = (state.posture, state.locomotion, state.last_transition, state.last_transition_t)
        changed = key != self._key
        self._key = key
        return state, changed, warning
