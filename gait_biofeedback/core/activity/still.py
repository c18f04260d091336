"""Stillness of the trunk (the static second of thesis §7.2.4, the steadiness of θ) and sensor handling.

The lying detector confirms a crossing by one static second [T §7.2.4]; sensor handling is a turn
beyond any trunk's while not static (:class:`Handling`); a pelvis level is confirmed only while θ is
steady; and a transition merges with the next only if the wearer was never still (static and steady)
in between (posture.py).
"""

from __future__ import annotations

import math
from collections import deque

from gait_biofeedback.core.activity.signal import STANDARD_GRAVITY

# --- chosen (not given by the thesis, gait.md §3.7) -----------------------------------------------
STATIC_WINDOW_S = 1.0  # static (the lying confirmation of §7.2.4): one second ...
STATIC_STD = 0.5  # ... with std(|a|) < 0.5 m/s² (≈ 0.05 g)
PELVIS_STEADY_RAD = math.radians(2.0)  # θ steady: its range over the last 1 s below this (a pelvis level
# is confirmed only then, see level.py PELVIS_HOLD_S; still = static and steady)
HANDLING_THETA_RAD = math.radians(110.0)  # a chest turned beyond 110° = the sensor is being handled
HANDLING_SETTLE_S = 5.0
PELVIS_HANDLING_RAD = math.radians(120.0)  # the pelvis lies back further than the chest: hapt lying θ up to
# 102°, 113° passing through while lying down (user22_run2; at 110° detection paused: its stand→lie 6 s
# late). Users 16-22: 77 → 79 of 85 found, 22 → 21 false; 23-30: 79 of 92 either way, 46 → 47 false


class RunningRange:
    """Smallest and largest value over the last ``span_s`` seconds (monotonic queues, O(1) per sample)."""

    def __init__(self, span_s: float) -> None:
        self.span_s = span_s
        self._low: deque[tuple[float, float]] = deque()
        self._high: deque[tuple[float, float]] = deque()

    def push(self, t: float, value: float) -> None:
        low, high = self._low, self._high
        while low and low[-1][1] >= value:
            low.pop()
        while high and high[-1][1] <= value:
            high.pop()
        low.append((t, value))
        high.append((t, value))
        while low[0][0] < t - self.span_s:
            low.popleft()
        while high[0][0] < t - self.span_s:
            high.popleft()

    @property
    def spread(self) -> float:
        """Largest minus smallest value (inf before any)."""
        return self._high[0][1] - self._low[0][1] if self._low else math.inf


class Stillness:
    """``update(t, |a|, θ)`` per sample: whether the trunk is static (std(|a|) over the last
    STATIC_WINDOW_S), θ's range over the last second, and how long it has been still (static and θ
    steady) now and at most since :meth:`reset_moment`."""

    def __init__(self, rate_hz: float) -> None:
        self.rate_hz = rate_hz
        self._n = round(STATIC_WINDOW_S * rate_hz)
        self._ring: deque[float] = deque()
        self._sum = [0.0, 0.0]
        self.theta_range = RunningRange(1.0)
        self.still_s = 0.0  # how long the wearer has been still up to now ...
        self.longest_still = 0.0  # ... and the longest such moment since the last reset_moment

    def update(self, t: float, magnitude: float, theta: float) -> None:
        ring, sums = self._ring, self._sum
        m = magnitude - STANDARD_GRAVITY
        ring.append(m)
        sums[0] += m
        sums[1] += m * m
        if len(ring) > self._n:
            old = ring.popleft()
            sums[0] -= old
            sums[1] -= old * old
        self.theta_range.push(t, theta)
        still = self.static and self.theta_range.spread < PELVIS_STEADY_RAD
        self.still_s = self.still_s + 1.0 / self.rate_hz if still else 0.0
        self.longest_still = max(self.longest_still, self.still_s)

    @property
    def static(self) -> bool:
        """std(|a|) < STATIC_STD over a full STATIC_WINDOW_S."""
        n = len(self._ring)
        if n < self._n:
            return False
        mean = self._sum[0] / n
        return self._sum[1] / n - mean * mean < STATIC_STD**2

    @property
    def spread(self) -> float:
        """θ's range (rad) over the last second."""
        return self.theta_range.spread

    def reset_moment(self) -> None:
        """A transition: still moments are counted from here."""
        self.still_s = self.longest_still = 0.0


class Handling:
    """``update(t, θ, stillness) -> bool``: whether detection is paused because the sensor is being put
    on or adjusted.

    Our addition (gait.md §3 has no such state): a worn chest sensor does not turn beyond
    θ = 110° while moving (lying still head-down is allowed); UCI subjects 2, 4, 6, 8, 10, 11,
    13, 14 do so in their first 45 s (strap being fastened), which produced false sit→stand,
    walking and lying. Detection restarts 5 s after the last such sample. (A criterion on
    |a| > 3.5 g was tried and dropped: the simulator's walking reaches it.) The pelvis: 120°.
    """

    def __init__(self, placement: str) -> None:
        self._rad = PELVIS_HANDLING_RAD if placement == "pelvis" else HANDLING_THETA_RAD
        self._until = -math.inf  # detection paused until then
        self.pauses = 0  # how often detection was paused

    def update(self, t: float, theta: float, still: Stillness) -> bool:
        if theta > self._rad and not still.static:
            self.pauses += t >= self._until
            self._until = t + HANDLING_SETTLE_S
        return t < self._until
