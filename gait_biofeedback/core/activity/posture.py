"""The monitor's posture and transitions, which every detector reads and changes (thesis §7.2.4–7.2.6).

Posture consistency (our additions to §7.2.5, thresholds chosen on UCI dev subjects 1–7 only):
a sit→stand needs the posture sitting, a stand→sit standing (unless the posture is only assumed, see
``initial_posture_for``); stand→sit and an immediate sit→stand need strong evidence (sit_stand.py); a
weaker sit→stand is reported only if a walking bout (3 peaks) starts within 10 s (event keeps its
instant, posture switches at confirmation); standing entered by a sit→stand without a walk of
SIT_WALK_MIN_STEPS within 60 s reverts to sitting; walking overrides a seated/lying posture after 8
steps (walking.py), and a θ excursion ending from 5 s before to 2 s after the first step of such a
walk (whatever its ΔY) names the sit→stand (:meth:`Posture.stand_up_before_walking`). Stand→sit then
sit→lie (lie→sit then sit→stand) close together is one stand→lie (lie→stand): HAPT's six transitions,
where the thesis names four.
"""

from __future__ import annotations

import math
from collections import deque

from gait_biofeedback.core.activity.output import DelayLine
from gait_biofeedback.core.activity.steps import MIN_STEP_S
from gait_biofeedback.core.activity.still import Stillness

# --- chosen on the UCI development subjects 1–7 (benchmarks/activity.py; 8–15 are held out) ---------
WALK_ONSET_GAP_S = 5.0  # any θ excursion (peak ≥ 20°, whatever its ΔY) ending ≤ 5 s before the first
# step of a walking bout, or ≤ 2 s after it (ONSET_OVERLAP_S), is the sit→stand of a seated person who
# walks off. UCI dev: the real stand-ups peaked 1–5 s before the first step; their double-integrated
# |ΔY| was often below the thesis gate (0.05–0.3 m, some of the wrong sign: short windows, reclined
# seats whose θ only falls)
ONSET_OVERLAP_S = 2.0
STAND_CONFIRM_S = 60.0  # standing entered by a sit→stand and never followed by a walk of SIT_WALK_MIN_STEPS
# within 60 s reverts to sitting (no event): on dev, every false strong sit→stand was followed by minutes of
# sitting still, every true one by walking within 20 s
SIT_WALK_MIN_STEPS = 8  # a walking bout overrides sitting/lying to standing only after 8 steps (dev:
# false "walking" while seated were bouts of 3–4 peaks, real walks after standing up ≥ 5–21 steps)
MERGE_S = 5.0  # stand→sit then sit→lie (lie→sit then sit→stand) within 5 s is one stand→lie (lie→stand) ...
MERGE_MOVING_S = 10.0  # ... and within 10 s if the wearer was never still (STATIC_*, θ steady) for 2 s in
MERGE_STILL_S = 2.0  # between: getting up, people sit on the bed's edge a few seconds, moving, before they
# stand. Chosen on hapt users 23-30, the only half whose lie→stand sat that long (7-8 s: 79/92 found at
# 5 s, 81 at 10 s; false 46 → 42); 16-22 unchanged (77/85). The simulator's 5 s of sitting still between
# lie→sit and sit→stand stay two events
_MERGED = {("stand_to_sit", "sit_to_lie"): "stand_to_lie", ("lie_to_sit", "sit_to_stand"): "lie_to_stand"}


def initial_posture_for(placement: str, reference_given: bool) -> str:
    """The posture a monitor starts in when it is not told (``initial_posture="auto"``). Our choice.

    A chest accelerometer alone cannot tell standing still from sitting upright: the monitor believes
    standing only on evidence (a walk of SIT_WALK_MIN_STEPS steps, or a sit→stand that walking
    confirms; standing without either reverts to sitting after STAND_CONFIRM_S). At the start there
    is no such evidence, so a chest starts seated (a patient is also seated while seven sensors are
    strapped on). A given reference (or ``reference="start"``) is a standing period (the thesis's Eq
    14), and at the pelvis a level decides within seconds: those start standing. Thighs, when they
    send, find the posture by their first level (no event; ~4 s: their own quiet reference, then
    THIGH_HOLD_S). Either way the posture is only assumed until a walk of SIT_WALK_MIN_STEPS, a
    strong transition of either kind or a level says it. UCI chest, nothing handed
    (benchmarks/activity.py): the first minute of every subject, seated, read standing before.
    """
    return "sitting" if placement == "chest" and not reference_given else "standing"


class Posture:
    """The posture (``assumed`` until evidenced), the transitions, and the sit→stand evidence that
    waits for a walk: a weak sit→stand (``pending_sit_stand``: instant, walking deadline), excursions
    not accepted (``excursions``: instant, t2) and the first step of a walk that overrode sitting
    without an event (``overridden_onset``). ``line``: the samples a change relabels."""

    def __init__(self, initial_posture: str, *, assumed: bool, placement: str, line: DelayLine,
                 still: Stillness) -> None:
        self.posture = initial_posture
        self.assumed = assumed
        self.transitions: list[tuple[float, str]] = []
        self.stand_deadline = math.inf  # standing from a sit→stand must see walking before this, and
        self.start_unconfirmed = initial_posture == "standing" and placement == "chest"  # at the start
        self.pending_sit_stand: tuple[float, float] | None = None
        self.excursions: deque[tuple[float, float]] = deque(maxlen=8)
        self.overridden_onset = math.nan
        self._line = line
        self._still = still

    def start(self, t: float) -> None:
        """The first sample of an upright start at the chest (``start_unconfirmed``): a walk must follow
        within STAND_CONFIRM_S."""
        self.start_unconfirmed = False
        self.stand_deadline = t + STAND_CONFIRM_S

    def relabel(self, t_from: float, posture: str) -> None:
        """The samples still in the delay line from ``t_from`` on are in ``posture``."""
        self._line.relabel(t_from, posture=posture)

    def add_transition(self, t: float, kind: str, posture: str, *, walked: bool = False) -> None:
        """Record an event; a sit→stand not yet followed by a walk must see one within 60 s.

        Stand→sit then sit→lie within MERGE_S (MERGE_MOVING_S without a still moment between) is one
        stand→lie at the first instant, lie→sit then sit→stand one lie→stand (HAPT's six transitions;
        the thesis names four). The first event may have been published already: the merged one
        replaces it, with its stamp; the samples still held from its instant on take the new posture
        (a lie→stand published over samples still labelled sitting was hapt user 20's "sitting" after
        "lie_to_stand").
        """
        last = self.transitions[-1] if self.transitions else None
        gap = math.inf if last is None else t - last[0]
        moving = self._still.longest_still < MERGE_STILL_S
        since = t
        if (gap <= MERGE_S or (gap <= MERGE_MOVING_S and moving)) and (last[1], kind) in _MERGED:
            self.transitions[-1] = (last[0], _MERGED[(last[1], kind)])
            if self._line.last_emitted_transition == last:
                self._line.last_emitted_transition = self.transitions[-1]
            since = last[0]  # one movement from its first instant: no sitting between a lie→stand's halves
        else:
            self.transitions.append((t, kind))
        self._still.reset_moment()
        self.posture = posture
        self.assumed = False
        self.pending_sit_stand = None  # older than this event: it cannot follow it
        self.excursions.clear()
        self.relabel(since, posture)
        unconfirmed = kind == "sit_to_stand" and not walked
        self.stand_deadline = t + STAND_CONFIRM_S if unconfirmed else math.inf

    def stand_up_before_walking(self, onset: float, run: list[float]) -> bool:
        """A seated person who walks off stood up first: take the excursion next to the onset.

        Our addition to §7.2.5/§7.2.6 (Fig 27 only lets an upright trunk walk): the event keeps the
        excursion's instant; the posture switches at the instant or, if that has left the delay
        line, now. ``run``: the walk's steps. Returns whether a sit→stand was added.
        """
        seated = self.posture == "sitting" or onset == self.overridden_onset
        if not seated or len(run) < SIT_WALK_MIN_STEPS:
            return False
        for instant, t2 in reversed(self.excursions):
            if onset - WALK_ONSET_GAP_S <= t2 <= onset + ONSET_OVERLAP_S:
                self.excursions.clear()
                self.overridden_onset = math.nan
                self.add_transition(instant, "sit_to_stand", "standing", walked=True)
                self.relabel(min(instant, onset - 0.5 * MIN_STEP_S), "standing")
                return True
        return False

    def forget_evidence(self) -> None:
        """Sensor handling: no weak sit→stand, excursion or overridden walk waits any longer."""
        self.pending_sit_stand = None
        self.excursions.clear()
        self.overridden_onset = math.nan

    def expire(self, t: float, walking: bool, thighs: bool) -> None:
        """Each sample after the detectors: a weak sit→stand no walk followed is dropped; standing from a
        sit→stand never walked on is taken as still seated (unless the thighs tell the posture)."""
        if self.pending_sit_stand is not None and t > self.pending_sit_stand[1]:
            self.pending_sit_stand = None  # no walking followed: the weak sit→stand is dropped
        if t > self.stand_deadline and not walking:
            self.stand_deadline = math.inf
            if self.posture == "standing" and not thighs:
                self.posture = "sitting"  # stood up but never walked: taken as still seated
