"""Walking modality: level vs stairs, up vs down (our replacement of thesis §7.2.6's variance of GA_v).

The thesis's variance of GA_v read 61.8 % of the walking samples of ``hapt_waist`` right (a waist
sensor sways no more on stairs): every step on stairs lifts or drops the whole body by a riser, so the
trunk's vertical displacement at step frequency (acceleration along GA, integrated twice, slow drift
removed: signal.vertical_displacement_sections) has about twice the amplitude of slow level walking's.
The body rises and falls alike at the chest and the pelvis, and the displacement needs no upright
reference and no forward axis. Spec: gait.md §3.5 (EXT, issue 15).
"""

from __future__ import annotations

import bisect
import math
from collections import deque

from gait_biofeedback.core.activity.output import DELAY_S
from gait_biofeedback.core.activity.signal import Biquad, vertical_displacement_sections

STAIRS_WINDOW_S = 2 * DELAY_S  # level/stairs window, centred on the emitted sample
STAIRS_DISPLACEMENT_M = 0.018  # the trunk's vertical displacement at step frequency (std σ_d over the
# window, signal.vertical_displacement_sections) above this → stairs ...
STAIRS_REFERENCE_RAD_S = 10.0  # ... the displacement of a faster vertical motion referred to 10 rad/s
# (1.6 Hz, 95 steps/min): σ_d·min(1, 10/ω), ω = √(σ_a/σ_d) the motion's effective angular frequency (σ_a
# the acceleration's std in the same band): a brisk walker bounces higher but faster, a step up or
# down is high and slow (slower motion is taken as it is: a slow walker's bounce is not inflated) ...
STAIRS_WEARER_RATIO = 1.3  # ... and above 1.3 × the wearer's own usual walking (the 10th percentile
# of the per-second values while walking, last 10 min, once 30 s are known: DISPLACEMENT_MIN_N), which
# is level walking even when stairs fill most of the history.
# Each step on stairs lifts or drops the body by a riser (~17 cm). hapt_waist bouts, σ_d (5-95 %):
# level 1.2-2.0 cm, upstairs 2.1-3.1, downstairs 2.4-3.5; but brisk or bouncy level walking reaches
# 2-2.7 cm (UCI chest subjects 2, 4, 6; the qmt walk at 112 steps/min: 1.9-2.1 cm at σ_a 3.7 m/s²).
# Chosen on hapt users 16-22 and UCI 1-7 (benchmark-like windows; level-vs-stairs accuracy among walking
# samples, hapt dev / UCI dev / qmt level share): σ_d > 1.9 cm alone 92.6 / 44.5 / 19-38 %; & 1.3× the
# wearer's 10th pct 90.0 / 66.7 / 46-52 %; referred to 10 rad/s, 1.8 cm & 1.3× 89.5 / 66.9 / 99-100 %
# (1.9 cm 84.5 / 70.1 / 100; 11 rad/s 78.8 / 72.5 / 100). Confirmed on hapt 23-30 / UCI 8-15: 97.9 /
# 85.3 % (UCI's "always level" reads 92 %: its stairs are 8 % of the walking)
DISPLACEMENT_MIN_N = 30  # seconds of walking before the wearer's ratio applies
DISPLACEMENT_HISTORY_N = 600  # the last 10 min of walking
DISPLACEMENT_QUANTILE = 0.1
UPSTAIRS_LEAN_RAD = math.radians(8.0)  # mean forward lean above this → upstairs (not validated), until ...
UPSTAIRS_LEVEL_LEAN_RAD = math.radians(5.0)  # ... the wearer's level walking is known (LEVEL_LEAN_MIN_N s):
# then upstairs = the trunk's direction over the window more than 5° from its mean over level walking, in
# any direction (no forward axis needed). hapt_waist bouts, angle from the wearer's level walking: upstairs
# 5.8-12.7° (10-90 %), downstairs 1.4-4.8°; per-sample UP/DOWN: see benchmarks/activity.py
LEVEL_LEAN_MIN_N = 10


class Modality:
    """Running sums over the stairs window (centred on the emitted sample) and the wearer's history;
    :meth:`label` names a walking sample's modality. ``forward_cos_sin``: the trunk's forward
    direction in the body frame's horizontal (x, z) plane (ActivityMonitor.set_forward_axis)."""

    def __init__(self, rate_hz: float) -> None:
        self.rate_hz = rate_hz
        self._n = round(STAIRS_WINDOW_S * rate_hz)
        self._ring: deque[tuple[float, float, float, float]] = deque()
        # Σ displacement, Σ displacement², Σ acceleration, Σ acceleration² (the same band), Σ lean along
        # body x, along z
        self._sum = [0.0] * 6
        self._displaced = [0.0, 0.0]  # the last two displacements (their second difference: the acceleration)
        self._displacement = [Biquad(b, a) for b, a in vertical_displacement_sections(rate_hz)]
        self._wearer_history: deque[float] = deque()  # per-second displacement std while walking
        self._wearer_sorted: list[float] = []  # the same values, sorted (running quantile)
        self.wearer_t = -math.inf  # when the history last took a value
        self._level_lean: deque[tuple[float, float]] = deque()  # per-second window lean while walking level
        self._level_lean_sum = [0.0, 0.0]
        self.forward_cos_sin = (1.0, 0.0)

    def keep_wearer(self, previous: Modality) -> None:
        """Carry the wearer's walking history over from the monitor a restart replaced."""
        self._wearer_history = deque(previous._wearer_history)
        self._wearer_sorted = list(previous._wearer_sorted)
        self._level_lean = deque(previous._level_lean)
        self._level_lean_sum = list(previous._level_lean_sum)

    def label(self) -> str:
        """Level vs stairs (the trunk's vertical displacement) and up vs down (mean forward lean).

        Stairs: the displacement referred to STAIRS_REFERENCE_RAD_S above STAIRS_DISPLACEMENT_M and
        above STAIRS_WEARER_RATIO × the wearer's usual walking (see there).

        Up vs down: the window's trunk direction more than UPSTAIRS_LEVEL_LEAN_RAD from the wearer's
        level walking once LEVEL_LEAN_MIN_N s of it are known; before, the thesis's lean along the
        forward axis. READING: the thesis integrates GA_f over the bout and uses one threshold; the
        mean over the centred window is that integral divided by the window length. With x forward, a forward
        lean gives GA_f = −g·sin(lean) (gait.md §3.2), so we test the lean −GA_f/g: upstairs = the
        trunk leans further forward than the upright reference.
        """
        n = len(self._ring)
        if n == 0 or self._referred_displacement() <= self._stairs_threshold:
            return "level"
        lean_x, lean_z = self._sum[4] / n, self._sum[5] / n
        known = len(self._level_lean)
        if known >= LEVEL_LEAN_MIN_N:
            level_x, level_z = (v / known for v in self._level_lean_sum)
            steeper = math.hypot(lean_x - level_x, lean_z - level_z) > math.sin(UPSTAIRS_LEVEL_LEAN_RAD)
        else:
            c, s = self.forward_cos_sin
            steeper = c * lean_x + s * lean_z > math.sin(UPSTAIRS_LEAN_RAD)
        return "upstairs" if steeper else "downstairs"

    def _referred_displacement(self) -> float:
        """σ_d·min(1, ω_ref/ω) (m) over the stairs window, ω = √(σ_a/σ_d) (see STAIRS_REFERENCE_RAD_S)."""
        n = len(self._ring)
        d1, d2, a1, a2 = (v / n for v in self._sum[:4])
        var_d, var_a = d2 - d1 * d1, a2 - a1 * a1
        if var_d <= 0.0 or var_a <= 0.0:
            return 0.0
        sigma_d = math.sqrt(var_d)
        omega = math.sqrt(math.sqrt(var_a) / sigma_d)
        return sigma_d * min(1.0, STAIRS_REFERENCE_RAD_S / omega)

    def remember_walking(self, t: float) -> None:
        """One value per second of walking into the wearer's history; the stairs threshold follows."""
        self.wearer_t = t
        history, ordered = self._wearer_history, self._wearer_sorted
        value = self._referred_displacement()
        history.append(value)
        bisect.insort(ordered, value)
        if len(history) > DISPLACEMENT_HISTORY_N:
            del ordered[bisect.bisect_left(ordered, history.popleft())]
        if value <= self._stairs_threshold:
            n = len(self._ring)
            lean = (self._sum[4] / n, self._sum[5] / n)
            self._level_lean.append(lean)
            self._level_lean_sum[0] += lean[0]
            self._level_lean_sum[1] += lean[1]
            if len(self._level_lean) > DISPLACEMENT_HISTORY_N:
                old_x, old_z = self._level_lean.popleft()
                self._level_lean_sum[0] -= old_x
                self._level_lean_sum[1] -= old_z

    @property
    def _stairs_threshold(self) -> float:
        ordered = self._wearer_sorted
        if len(ordered) < DISPLACEMENT_MIN_N:
            return STAIRS_DISPLACEMENT_M
        usual = ordered[int(DISPLACEMENT_QUANTILE * len(ordered))]
        return max(STAIRS_DISPLACEMENT_M, STAIRS_WEARER_RATIO * usual)

    def update(self, vertical: float, up_f: float, up_l: float) -> None:
        """Each sample: running sums of the vertical displacement and acceleration at step frequency
        (from ``vertical``, the acceleration along GA less g) and of the leans −GA_f/|GA|, −GA_l/|GA|
        (unit direction); the lean along the trunk's forward axis is combined from the last two in
        :meth:`label`."""
        ring = self._ring
        for section in self._displacement:
            vertical = section.step(vertical)
        before, last = self._displaced
        acceleration = (vertical - 2.0 * last + before) * self.rate_hz**2  # the band-passed input
        self._displaced = [last, vertical]
        row = (vertical, acceleration, -up_f, -up_l)
        ring.append(row)
        self._add(row, 1.0)
        if len(ring) > self._n:
            self._add(ring.popleft(), -1.0)

    def _add(self, row: tuple[float, float, float, float], sign: float) -> None:
        d, a, x, z = row
        sums = self._sum
        sums[0] += sign * d
        sums[1] += sign * d * d
        sums[2] += sign * a
        sums[3] += sign * a * a
        sums[4] += sign * x
        sums[5] += sign * z
