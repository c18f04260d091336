"""Sit-to-lie and lie-to-sit: θ crossing 70°, confirmed by a static second (thesis §7.2.4; gait.md §3.3)."""

from __future__ import annotations

import math

from gait_biofeedback.core.activity.posture import Posture
from gait_biofeedback.core.activity.still import STATIC_WINDOW_S, Stillness

LYING_THRESHOLD_RAD = math.radians(70.0)  # [T §7.2.4]
LYING_STATIC_BEFORE_S = 10.0  # the static lying second at most 10 s before a lie-to-sit crossing (chosen)
LYING_HYSTERESIS_RAD = math.radians(10.0)  # lie-to-sit confirmed below 60° (not tuned: a trunk resting
# near 70° flickered lying/sitting every 1–2 s, UCI subject 8 at the end of its recording)


class Lying:
    """``update(t, θ, θ of the previous sample)`` adds the lying transitions to ``posture``; ``ga_delay``:
    the GA filter's group delay (s), taken off the crossing's time."""

    def __init__(self, posture: Posture, still: Stillness, ga_delay: float) -> None:
        self._posture = posture
        self._still = still
        self._ga_delay = ga_delay
        self._crossing_t: float | None = None
        self._static_lying_t = -math.inf
        self._above_since = math.inf
        self._sitting_up_t: float | None = None  # downward 70° crossing awaiting the hysteresis

    def reset(self) -> None:
        """Sensor handling: no crossing is pending."""
        self._crossing_t = self._sitting_up_t = None

    def update(self, t: float, theta: float, theta_prev: float) -> str | None:
        """Sit-to-lie / lie-to-sit: θ crossing 70°, direction from dθ/dt, static check [T §7.2.4].

        READINGs: θ rising through 70° is sit-to-lie (GA_v falling), θ falling is lie-to-sit. The
        static period must show gravity on the trunk's horizontal plane: we accept the frontal axis
        (supine/prone, as the thesis) and also the lateral axis (side-lying), i.e. θ > 70° while
        static. The instant is the crossing minus the GA filter's group delay. Our addition: a
        lie-to-sit is confirmed only once θ is 10° below the threshold (hysteresis), so a trunk
        resting near 70° does not flicker between lying and sitting.

        Returns "crossed" when θ crossed into lying (a stand/sit candidate in flight is none), "sat up"
        when a lie-to-sit was added (the θ excursion tracker starts again), else None.
        """
        posture = self._posture
        lying_now = theta > LYING_THRESHOLD_RAD
        prev_lying = theta_prev > LYING_THRESHOLD_RAD
        said = None
        if lying_now and not prev_lying:
            self._above_since = t
        if lying_now and t - self._above_since >= STATIC_WINDOW_S and self._still.static:
            self._static_lying_t = t
        if lying_now and not prev_lying and posture.posture != "lying":
            self._crossing_t = t
            said = "crossed"
        elif not lying_now and self._crossing_t is not None:
            self._crossing_t = None  # never static while above 70°: unknown movement
        if self._crossing_t is not None and self._static_lying_t >= self._crossing_t:
            kind = "stand_to_lie" if posture.posture == "standing" else "sit_to_lie"
            posture.add_transition(self._crossing_t - self._ga_delay, kind, "lying")
            self._crossing_t = None
        if posture.posture != "lying" or lying_now:
            self._sitting_up_t = None
        elif prev_lying and t - self._static_lying_t <= LYING_STATIC_BEFORE_S:
            self._sitting_up_t = t
        if self._sitting_up_t is not None and theta < LYING_THRESHOLD_RAD - LYING_HYSTERESIS_RAD:
            # a trunk that rested between 60° and 70° for long sat up later than its 70° crossing
            crossing = self._sitting_up_t if t - self._sitting_up_t <= LYING_STATIC_BEFORE_S else t
            posture.add_transition(crossing - self._ga_delay, "lie_to_sit", "sitting")
            self._sitting_up_t = None
            said = "sat up"
        return said
