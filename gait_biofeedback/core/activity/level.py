"""Sitting vs standing from a level held: the pelvis tilt, the thighs' inclination, a held trunk lean.

Our rules beside the thesis's §7.2.5 excursion detector (which is for the chest, sit_stand.py): at the
pelvis, or while thigh sensors send (thigh.py), posture is a level with hysteresis (:class:`Level`);
at the chest a lean held for long without walking is sitting (:class:`LeanHold`).
"""

from __future__ import annotations

import math

from gait_biofeedback.core.activity.lying import LYING_THRESHOLD_RAD
from gait_biofeedback.core.activity.posture import Posture
from gait_biofeedback.core.activity.still import PELVIS_STEADY_RAD, Stillness
from gait_biofeedback.core.activity.thigh import THIGH_HOLD_S, THIGH_SIT_RAD, THIGH_STAND_RAD
from gait_biofeedback.core.activity.walking import Walking

# --- the pelvis placement, chosen on hapt_waist users 16-30 (benchmarks/activity.py) ------------------
# A waist or lower-back sensor tilts with the pelvis: seated θ held 7-56° (median 21°), standing 0-3°
# (after the standing reference), while the chest's stand/sit excursion and ΔY are too small to see
# (0/61 sit-stand transitions found). Posture is therefore a level with hysteresis on θ.
PELVIS_SIT_RAD = math.radians(12.0)  # θ held above this ⇒ sitting (dev: 11-14° alike, 10° flickers)
PELVIS_STAND_RAD = math.radians(8.0)  # θ held below this (or walking) ⇒ standing
PELVIS_HOLD_S = 3.0  # the new level must hold this long: a pause at a stair landing with the pelvis
# tilted is no seat (hapt users 16-22, with the gyro: false transitions 32 at 2 s, 20 at 3 s and 4 s, the
# same 77/85 found; 1 s gave 1.7× the false transitions of 2 s; confirmed on 23-30: 68 → 46, 78 → 79) ...
# ... and θ must be steady (PELVIS_STEADY_RAD, still.py) when confirmed
# --- the chest's held lean, chosen on the UCI development subjects 1–7 ----------------------------------
SIT_LEAN_RAD = math.radians(25.0)  # trunk lean held ≥ 25° (and < 70°) without walking ...
SIT_LEAN_HOLD_S = 30.0  # ... for 30 s ⇒ sitting (standing is upright). Dev: flags 0 % of standing
# samples and 0–89 % of sitting ones (20° or 10 s flagged up to 35 % of one subject's standing)
LEAN_RECOVERY = 4.0  # leaky hold: a second upright takes back 4 s (≥ 80 % of the time leaning)


class Level:
    """Posture from a value held above or below two levels (see :meth:`update`); ``ga_delay``: the GA
    filter's group delay (s), taken off an event's instant."""

    def __init__(self, posture: Posture, walking: Walking, still: Stillness, ga_delay: float) -> None:
        self._posture = posture
        self._walking = walking
        self._still = still
        self._ga_delay = ga_delay
        self._level: tuple[str, float] | None = None  # (posture the level points to, since)
        self._source = ""  # "thigh" or "pelvis": what the level state follows
        self._value = math.nan  # the value at the previous sample ...
        self._middle_t = -math.inf  # ... and when it last crossed the middle of the two levels

    def pelvis(self, t: float, theta: float) -> None:
        """Each sample at the pelvis placement (without thighs): θ against PELVIS_*."""
        self.update(t, "pelvis", theta, PELVIS_SIT_RAD, PELVIS_STAND_RAD, PELVIS_HOLD_S)

    def thighs(self, t: float, inclination: float) -> None:
        """Each sample the thighs' mean inclination is known: against THIGH_* (thigh.py)."""
        self.update(t, "thigh", inclination, THIGH_SIT_RAD, THIGH_STAND_RAD, THIGH_HOLD_S)

    def update(self, t: float, source: str, value: float, sit: float, stand: float, hold: float) -> None:
        """Sitting while ``value`` is held above ``sit`` for ``hold`` s, standing below ``stand`` or
        while walking: the pelvis placement (value = θ, see PELVIS_*; the thesis's §7.2.5 detector is
        for the chest) and the thighs (value = their mean inclination, see ``thigh.py``). Our rule.
        For the pelvis θ must also be steady when the level is confirmed. The event's instant is where
        the value last crossed the middle of the two levels (a symmetric movement's middle) within the
        hold before the level was left, else where it was left; less the GA filter's delay. A change
        of source (the thighs start or stop sending) starts the level state again."""
        if source != self._source:
            self.reset(t, source)
        posture, walking = self._posture, self._walking.walking
        middle = 0.5 * (sit + stand)
        previous, self._value = self._value, value
        if (previous - middle) * (value - middle) <= 0.0 and previous != value:
            self._middle_t = t
        if posture.posture == "lying":
            self._level = None
            return
        if walking or value < stand:
            target = "standing"
        elif value > sit:
            target = "sitting"
        elif self._level is None and posture.assumed:
            return  # between the two levels: no evidence for the assumed posture either way
        else:
            target = self._level[0] if self._level else posture.posture
        if target == posture.posture and not posture.assumed:
            self._level = None
            return
        if self._level is None or self._level[0] != target:
            self._level = (target, t)
            return
        steady = source != "pelvis" or self._still.spread < PELVIS_STEADY_RAD
        if not walking and (t - self._level[1] < hold or not steady):
            return
        since = self._level[1]
        instant = (self._middle_t if since - hold <= self._middle_t <= since else since) - self._ga_delay
        self._level = None
        if posture.assumed:  # the first reading of the level: a posture found, not a transition
            posture.posture, posture.assumed = target, False
            posture.relabel(since, target)
            return
        kind = "sit_to_stand" if target == "standing" else "stand_to_sit"
        posture.add_transition(instant, kind, target, walked=True)  # the level is the evidence: no deadline

    def reset(self, t: float, source: str | None = None) -> None:
        """Start the level state again (a new ``source``, or the same after sensor handling)."""
        if source is not None:
            self._source = source
        self._level = None
        self._value = math.nan
        self._middle_t = t


class LeanHold:
    """A trunk lean held in [25°, 70°) for 30 s without walking ⇒ sitting (no event).

    Thesis §7.2.6 rejects walking with a non-upright trunk, i.e. standing is upright; the
    converse used here (a long-held lean is not standing) is our choice, tuned on UCI dev data.
    The hold is leaky: each second outside the band takes back LEAN_RECOVERY seconds, so a
    seated person who sits up now and then for a moment still accumulates the hold.
    """

    def __init__(self, posture: Posture, walking: Walking) -> None:
        self._posture = posture
        self._walking = walking
        self.hold = 0.0  # s of trunk lean accumulated (leaky) without walking
        self._t = -math.inf

    def update(self, t: float, theta: float) -> None:
        dt = t - self._t
        self._t = t
        if self._walking.walking or not 0.0 < dt < 1.0:
            self.hold = 0.0
        elif SIT_LEAN_RAD <= theta < LYING_THRESHOLD_RAD:
            self.hold += dt
            posture = self._posture
            if self.hold >= SIT_LEAN_HOLD_S and posture.posture == "standing":
                posture.posture = "sitting"
                posture.assumed = False
                posture.pending_sit_stand = None
                posture.relabel(t, "sitting")
        else:
            self.hold = max(0.0, self.hold - LEAN_RECOVERY * dt)
