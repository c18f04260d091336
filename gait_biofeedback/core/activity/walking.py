"""Walking bouts and steps from the trunk's SVM peaks (thesis §7.2.6, Table 16(b); gait.md §3.5).

A walking bout is ≥ 3 successive SVM peaks (steps.py) within a step duration of each other, the trunk
upright at each (Fig 27 lets only an upright trunk walk). A bout confirms a weak sit→stand waiting for
it, and one of SIT_WALK_MIN_STEPS confirms standing (posture.py).
"""

from __future__ import annotations

import math

from gait_biofeedback.core.activity.output import DelayLine
from gait_biofeedback.core.activity.posture import SIT_WALK_MIN_STEPS, Posture
from gait_biofeedback.core.activity.signal import STANDARD_GRAVITY
from gait_biofeedback.core.activity.steps import MAX_STEP_S, MIN_STEP_S, StepSvm

MIN_SUCCESSIVE_PEAKS = 3  # [T §7.2.6]
UPRIGHT_WALKING_RAD = math.radians(30.0)  # "small threshold" rejecting peaks of a non-upright trunk (chosen)


class Walking:
    """Steps (``steps``, s), the current run of successive peaks (``run``) and whether it is a walking
    bout (``walking``). Event times are corrected by the step low-pass's group delay (≈ 0.08 s at a
    typical 1.8 Hz step frequency)."""

    def __init__(self, rate_hz: float, posture: Posture, line: DelayLine) -> None:
        self._steps = StepSvm(rate_hz)
        self._posture = posture
        self._line = line
        self.last_peak_t = -math.inf
        self.run: list[float] = []
        self.walking = False
        self.steps: list[float] = []

    def svm(self, magnitude: float) -> float:
        """Each sample: the step SVM, |a| − g low-passed."""
        return self._steps.svm(magnitude - STANDARD_GRAVITY)

    def end(self) -> None:
        """The bout is over (a step duration without a peak, or sensor handling)."""
        self.walking = False
        self._line.relabel(self.last_peak_t + 0.5 * MIN_STEP_S, walking=False)
        self.run = []
        self._posture.overridden_onset = math.nan

    def pause(self) -> None:
        """Sensor handling: the bout ends and the peak picker starts again."""
        if self.walking:
            self.end()
        self.run = []
        self._steps.peaks.reset()

    def adopt(self, steps: list[float]) -> None:
        """The upright finder's walking bout becomes the walk in progress (steps counted)."""
        self.run = list(steps)
        self.last_peak_t = steps[-1]
        if not self.walking:
            self.walking = True
            self.steps.extend(s for s in steps if not self.steps or s > self.steps[-1])
            self._posture.stand_deadline = math.inf
            self._line.relabel(steps[0] - 0.5 * MIN_STEP_S, walking=True)

    def update(self, t: float, svm: float, theta: float) -> None:
        """SVM peaks → steps and walking bouts [T §7.2.6, Table 16(b) "low threshold + rejection"]."""
        if self.walking and t - self.last_peak_t > MAX_STEP_S:
            self.end()
        peak = self._steps.peak(t, svm, theta)
        if peak is None:
            return
        t_peak = peak[0]
        if t_peak - self.last_peak_t < MIN_STEP_S:
            return
        if peak[1] > UPRIGHT_WALKING_RAD:
            self.run = []
            self.last_peak_t = t_peak
            return
        if t_peak - self.last_peak_t > MAX_STEP_S:
            self.run = []
        self.last_peak_t = t_peak
        self.run.append(t_peak)
        posture = self._posture
        if self.walking:
            self.steps.append(t_peak)
        elif len(self.run) >= MIN_SUCCESSIVE_PEAKS:
            self.walking = True
            self.steps.extend(self.run)
            pending = posture.pending_sit_stand
            if pending is not None and posture.posture == "sitting" and self.run[0] <= pending[1]:
                # the event stands; standing itself needs a walk of SIT_WALK_MIN_STEPS within a minute
                posture.add_transition(pending[0], "sit_to_stand", "standing")
            posture.pending_sit_stand = None
            self._line.relabel(self.run[0] - 0.5 * MIN_STEP_S, walking=True)
        if not (self.walking and len(self.run) >= SIT_WALK_MIN_STEPS):
            return
        posture.stand_deadline = math.inf  # a real walk (not a seated wearer's few peaks) confirms standing
        assumed, posture.assumed = posture.assumed, False
        if posture.posture != "standing":
            # an assumed seat may have been a standing wearer's bow before the walk: no event from it
            if not assumed and posture.stand_up_before_walking(self.run[0], self.run):
                return
            if posture.posture == "sitting" and not assumed:
                posture.overridden_onset = self.run[0]  # a stand-up analysed later may still name it
            posture.posture = "standing"  # walking implies upright (Fig 27); no event is invented
            posture.relabel(self.run[0] - 0.5 * MIN_STEP_S, "standing")
