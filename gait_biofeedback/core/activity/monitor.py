"""Trunk activity monitor: posture, transitions, walking modality and steps (thesis ch. 7).

Spec: gait.md §3 (thesis §7.2.3–7.2.6, Fig 27). One trunk accelerometer (chest or pelvis); the same
sensor's gyro, if given, only helps find the upright reference (reference.py).

Pipeline per sample (``ActivityMonitor.update``), all on Python floats:
  raw acc → ×scale, rotate into the body frame (x forward, y up, z right) → GA = 0.25 Hz elliptic
  low-pass per axis → trunk inclination θ = arccos(GA_v/g) (Eq 54) → three detectors:
  A) lying: θ crossing 70° confirmed by a static second lying (§7.2.4);
  B) sit/stand: a θ excursion peaking above 20°, bounded by θ minima, ΔY gate, ∫SVM sign (§7.2.5);
  C) walking: ≥ 3 successive SVM peaks within a step duration, trunk upright (§7.2.6); level vs
     stairs from the trunk's vertical displacement at step frequency, up vs down from the lean beyond
     the wearer's level walking or, until that is known, along the forward axis (our replacement of
     the thesis's variance of GA_v and ∫GA_f, see ``_modality``).

Delay: every state describes the sample ``DELAY_S`` = 3 s before the newest input, and labels are
final when emitted (walking needs 3 steps, ≤ 2.6 s, before it is confirmed; the level/stairs window
is centred on the emitted sample). Transition *events* are appended when confirmed, about 1 s
after the trunk settles (typically 2–4 s after the instant); their time is the estimated instant
and the posture label switches at the instant when that is still inside the delay line, otherwise
at confirmation.

Units: m/s² are assumed (``units="g"`` accepted). The input is rescaled so that the static norm of
the reference period is 1 g (gait.md §3.7 "g: the sensor's static norm"); a norm far from 1 g in
the declared unit raises ``UnitMismatchWarning``. Mounting: the mean acceleration of an upright
standing reference period defines "up" (Eq 14); without one it is found in the stream
(``reference="auto"``: the first quiet period, checked by the first walking bout, see
:mod:`~gait_biofeedback.core.activity.reference`) or the first ``reference_s`` seconds are used
(``reference="start"``, the thesis); until then the monitor outputs its initial posture, no
locomotion and ``calibrated=False``.

Placement: ``chest`` (the thesis) or ``pelvis`` (lower back, waist), where posture is a level on θ
(the pelvis tilts back when seated) instead of the chest's excursion detector; see PELVIS_*.

Posture consistency (our additions to §7.2.5, thresholds chosen on UCI dev subjects 1–7 only):
a sit→stand needs the posture sitting, a stand→sit standing (unless the posture is only assumed, see
``initial_posture_for``); stand→sit and an immediate sit→stand need strong evidence (|ΔY| ≥ 0.7 thigh
and |∫SVM score| ≥ 0.4 m/s); a weaker sit→stand is reported only if a walking bout (3 peaks) starts
within 10 s (event keeps its instant, posture switches at confirmation); standing entered by a
sit→stand without a walk of SIT_WALK_MIN_STEPS within 60 s reverts to sitting; walking overrides a
seated/lying posture after 8 steps, and a θ excursion ending from 5 s before to 2 s after the first
step of such a walk (whatever its ΔY) names the sit→stand; a lean held (leaky) in [25°, 70°) for
30 s without walking ⇒ sitting; lie-to-sit needs θ 10° below the lying threshold (hysteresis); while
the sensor is handled (θ > 110°, pelvis 120°, while moving) nothing is detected and the last posture is kept.

Numbers the thesis does not give (gait.md §3.7) are chosen here; each constant says where from.
"""

from __future__ import annotations

import bisect
import math
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from gait_biofeedback.core.activity.reference import CHEST_REREFERENCE_RAD, REREFERENCE_RAD, UprightFinder
from gait_biofeedback.core.activity.signal import (
    STANDARD_GRAVITY,
    Biquad,
    UnitMismatchWarning,
    clip_acos,
    gravity_lowpass_ba,
    group_delay_s,
    mounting_from_reference,
    scale_to_si,
    step_lowpass_ba,
    vertical_displacement_sections,
)
from gait_biofeedback.core.activity.steps import (
    MAX_STEP_S,
    MIN_STEP_S,
    STEP_LOWPASS_HZ,
    STEP_PEAK_RELEASE,
    STEP_PEAK_THRESHOLD,
    SvmPeaks,
)
from gait_biofeedback.core.activity.thigh import THIGH_HOLD_S, THIGH_SIT_RAD, THIGH_STAND_RAD, ThighInputs
from gait_biofeedback.core.activity.transition import SitStandWindow, analyse_sit_stand
from gait_biofeedback.core.stamps import NS_PER_S, s_to_ns, sample_stamps

__all__ = [
    "INITIAL_POSTURES",
    "LOCOMOTIONS",
    "POSTURES",
    "TRANSITIONS",
    "ActivityMonitor",
    "ActivityState",
    "UnitMismatchWarning",
    "check_forward_axis",
    "classify_activity",
]

POSTURES = ("standing", "sitting", "lying")
INITIAL_POSTURES = ("auto", *POSTURES)  # auto: see initial_posture_for
LOCOMOTIONS = ("none", "level", "upstairs", "downstairs")
REFERENCES = ("auto", "start")  # upright reference found in the stream (reference.py), or the first seconds
TRANSITIONS = ("sit_to_stand", "stand_to_sit", "sit_to_lie", "lie_to_sit", "stand_to_lie", "lie_to_stand")
PLACEMENTS = ("chest", "pelvis")  # chest / sternum (the thesis), or pelvis / lower back / waist

DELAY_S = 3.0  # label delay: ≥ 3 steps at the slowest step duration (2 × 1.3 s) + peak latency
# --- given by the thesis --------------------------------------------------------------------------
LYING_THRESHOLD_RAD = math.radians(70.0)  # [T §7.2.4]
SIT_STAND_CANDIDATE_RAD = math.radians(20.0)  # [T §7.2.5]
THIGH_FRACTION = 0.5  # reject |ΔY| < 50 % of thigh length [T §7.2.5]
MIN_SUCCESSIVE_PEAKS = 3  # [T §7.2.6]
# --- chosen (not given by the thesis, gait.md §3.7) -----------------------------------------------
DEFAULT_THIGH_LENGTH_M = 0.42  # adult thigh (greater trochanter–knee) when the user gives none
EXCURSION_HYSTERESIS_RAD = math.radians(5.0)  # θ peak/valley confirmation (well above GA noise)
VALLEY_FLAT_S = 1.0  # a θ valley is also confirmed when θ stops falling (by 0.5°) for 1 s
VALLEY_FLAT_STEP_RAD = math.radians(0.5)
MAX_EXCURSION_S = 10.0  # longer "transitions" are not analysed (buffer is 14 s)
MAX_SIT_STAND_S = 5.0  # [t1, t2] longer than this is not a StSi/SiSt (healthy 1.5–3.5 s; slow ≤ ~5 s);
# chosen on UCI: longer windows gave |ΔY| of 0.7–1.4 m from integration drift while standing
MAX_HEIGHT_FRACTION = 2.0  # |ΔY| > 2 thigh lengths is integration drift, not a transition (choice)
UPRIGHT_WALKING_RAD = math.radians(30.0)  # "small threshold" rejecting peaks of a non-upright trunk
STATIC_WINDOW_S = 1.0  # lying confirmation: one static second ...
STATIC_STD = 0.5  # ... with std(|a|) < 0.5 m/s² (≈ 0.05 g) ...
HANDLING_THETA_RAD = math.radians(110.0)  # a chest turned beyond 110° = the sensor is being handled
HANDLING_SETTLE_S = 5.0
LYING_STATIC_BEFORE_S = 10.0  # ... at most 10 s before a lie-to-sit crossing
LYING_HYSTERESIS_RAD = math.radians(10.0)  # lie-to-sit confirmed below 60° (not tuned: a trunk resting
# near 70° flickered lying/sitting every 1–2 s, UCI subject 8 at the end of its recording)
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
HISTORY_S = 14.0
# --- chosen on the UCI development subjects 1–7 (benchmarks/activity.py; 8–15 are held out) ---------
# The thesis's gates (|ΔY| ≥ 50 % thigh, sign of ∫SVM) let 1–36 false transitions per UCI subject
# through: double-integrated ΔY of an uncalibrated 12-bit sensor scatters by ±0.3 m while seated or
# standing still. On dev, the false candidates that passed had |ΔY| 0.21–0.32 m and |∫SVM score|
# 0.02–0.4 m/s, the true sit→stand 0.28–0.76 m and 0.23–1.25 m/s; the simulator's 0.42 m, 0.7–0.8 m/s.
STRONG_THIGH_FRACTION = 0.7  # "strong" transition: |ΔY| ≥ 0.7 thigh (0.29 m at the default 0.42 m) ...
STRONG_SVM_SCORE = 0.4  # ... and |∫SVM score| ≥ 0.4 m/s. Stand→sit must be strong (no other cue)
CONFIRM_WALK_S = 10.0  # a weaker sit→stand counts only if a walking bout starts ≤ 10 s after t2
# (dev: the two true sit→stand below the strong gate were followed by walking after 1–8 s)
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
SIT_LEAN_RAD = math.radians(25.0)  # trunk lean held ≥ 25° (and < 70°) without walking ...
SIT_LEAN_HOLD_S = 30.0  # ... for 30 s ⇒ sitting (standing is upright). Dev: flags 0 % of standing
# samples and 0–89 % of sitting ones (20° or 10 s flagged up to 35 % of one subject's standing)
# --- the pelvis placement, chosen on hapt_waist users 16-30 (benchmarks/activity.py) ------------------
# A waist or lower-back sensor tilts with the pelvis: seated θ held 7-56° (median 21°), standing 0-3°
# (after the standing reference), while the chest's stand/sit excursion and ΔY are too small to see
# (0/61 sit-stand transitions found). Posture is therefore a level with hysteresis on θ.
PELVIS_SIT_RAD = math.radians(12.0)  # θ held above this ⇒ sitting (dev: 11-14° alike, 10° flickers)
PELVIS_STAND_RAD = math.radians(8.0)  # θ held below this (or walking) ⇒ standing
PELVIS_HOLD_S = 3.0  # the new level must hold this long: a pause at a stair landing with the pelvis
# tilted is no seat (hapt users 16-22, with the gyro: false transitions 32 at 2 s, 20 at 3 s and 4 s, the
# same 77/85 found; 1 s gave 1.7× the false transitions of 2 s; confirmed on 23-30: 68 → 46, 78 → 79) ...
PELVIS_STEADY_RAD = math.radians(2.0)  # ... and θ must be steady (range over the last 1 s) when confirmed
PELVIS_HANDLING_RAD = math.radians(120.0)  # the pelvis lies back further than the chest: hapt lying θ up to
# 102°, 113° passing through while lying down (user22_run2; at 110° detection paused: its stand→lie 6 s
# late). Users 16-22: 77 → 79 of 85 found, 22 → 21 false; 23-30: 79 of 92 either way, 46 → 47 false
MERGE_S = 5.0  # stand→sit then sit→lie (lie→sit then sit→stand) within 5 s is one stand→lie (lie→stand) ...
MERGE_MOVING_S = 10.0  # ... and within 10 s if the wearer was never still (STATIC_*, θ steady) for 2 s in
MERGE_STILL_S = 2.0  # between: getting up, people sit on the bed's edge a few seconds, moving, before they
# stand. Chosen on hapt users 23-30, the only half whose lie→stand sat that long (7-8 s: 79/92 found at
# 5 s, 81 at 10 s; false 46 → 42); 16-22 unchanged (77/85). The simulator's 5 s of sitting still between
# lie→sit and sit→stand stay two events
LEAN_RECOVERY = 4.0  # leaky hold: a second upright takes back 4 s (≥ 80 % of the time leaning)


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


def check_forward_axis(axis: np.ndarray) -> np.ndarray:
    """The axis as a float array; ValueError unless it is a finite non-zero 3-vector."""
    vector = np.asarray(axis, dtype=float)
    if vector.shape != (3,) or not np.all(np.isfinite(vector)) or not np.any(vector):
        raise ValueError(f"forward axis must be a finite non-zero 3-vector, got {axis!r}")
    return vector


@dataclass(frozen=True)
class ActivityState:
    """What the ``activity_monitor`` node publishes (posture, modality, last transition, steps, θ)."""

    stamp_ns: int  # the sample this state describes (input stamp − DELAY_S)
    posture: str  # standing | sitting | lying
    locomotion: str  # none | level | upstairs | downstairs
    trunk_inclination: float  # rad, θ of Eq 54 (causal GA; READING: GA_v/|GA|, see update)
    step_count: int  # steps with a time ≤ t since start
    last_transition: str | None  # one of TRANSITIONS
    last_transition_ns: int | None  # estimated instant of last_transition (a stamp, rounded to 1 ns)
    calibrated: bool  # False until the upright reference is known (reference.py, or the first reference_s s)

    @property
    def t(self) -> float:
        """The described sample's stamp in seconds."""
        return self.stamp_ns / NS_PER_S


class _RunningRange:
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


class _Ring:
    """Fixed-size history of (t, f, v, l) body-frame samples for the window analysis."""

    def __init__(self, size: int) -> None:
        self.size = size
        self.data = np.zeros((size, 4))
        self.count = 0

    def push(self, t: float, f: float, v: float, lat: float) -> None:
        self.data[self.count % self.size] = (t, f, v, lat)
        self.count += 1

    def since(self, t_start: float) -> np.ndarray:
        n = min(self.count, self.size)
        idx = (np.arange(self.count - n, self.count)) % self.size
        rows = self.data[idx]
        return rows[rows[:, 0] >= t_start]


class ActivityMonitor:
    """Streaming chest activity monitor: ``update(stamp_ns, acc) -> ActivityState | None``.

    ``acc``: one 3-vector (sensor axes, any mounting). Returns the state of the sample ``DELAY_S``
    before (``None`` until the delay line is full); call ``flush()`` at the end for the remaining
    states. Internally the detectors work on the stamps in float seconds (``stamp_ns / 1e9``).
    ``initial_posture`` "auto": :func:`initial_posture_for`; an assumed posture gives way to the first
    strong transition of either kind and to the first level (pelvis, thighs), which sets it without an
    event.
    """

    def __init__(
        self,
        rate_hz: float,
        *,
        units: str = "m/s2",
        reference_acc: np.ndarray | None = None,
        reference_s: float = 2.0,
        reference: str = "auto",
        align: bool = True,
        forward_axis: np.ndarray | None = None,
        thigh_length_m: float = DEFAULT_THIGH_LENGTH_M,
        initial_posture: str = "auto",
        placement: str = "chest",
    ) -> None:
        if placement not in PLACEMENTS:
            raise ValueError(f"placement must be one of {PLACEMENTS}, got {placement!r}")
        if not 20.0 <= rate_hz <= 200.0:
            raise ValueError(f"rate_hz must be in [20, 200], got {rate_hz}")
        if initial_posture not in INITIAL_POSTURES:
            raise ValueError(f"initial_posture must be one of {INITIAL_POSTURES}")
        # an assumed posture (auto) gives way to the first strong transition of either kind (see _judge)
        self._posture_assumed = initial_posture == "auto"
        if initial_posture == "auto":
            given = reference_acc is not None or reference == "start"  # the thesis's standing period
            initial_posture = initial_posture_for(placement, given)
        if reference not in REFERENCES:
            raise ValueError(f"reference must be one of {REFERENCES}, got {reference!r}")
        self.rate_hz = float(rate_hz)
        self.units = units
        self.align = align
        self.forward_axis = None if forward_axis is None else check_forward_axis(forward_axis)
        self.min_height_change = THIGH_FRACTION * thigh_length_m
        self.max_height_change = MAX_HEIGHT_FRACTION * thigh_length_m
        self.strong_height_change = STRONG_THIGH_FRACTION * thigh_length_m
        self.posture = initial_posture
        self.placement = placement
        self._handling_rad = PELVIS_HANDLING_RAD if placement == "pelvis" else HANDLING_THETA_RAD
        self._level: tuple[str, float] | None = None  # pelvis/thighs: (posture the level points to, since)
        # the thighs' mean inclination (rad) at the next sample, set by the caller before each update
        # (ActivityStream, from ThighTilt); None: no thigh data, the trunk decides sitting vs standing
        self.thigh_inclination: float | None = None
        self._level_source = ""  # "thigh" or "pelvis": what the level state below follows
        self._level_value = math.nan  # the level's value at the previous sample ...
        self._middle_t = -math.inf  # ... and when it last crossed the middle of the two levels
        self._n_reference = max(1, round(reference_s * rate_hz))
        self._ref_sum = [0.0, 0.0, 0.0]
        self._ref_count = 0
        self._rot: list[float] | None = None
        self._gb, self._ga = gravity_lowpass_ba(rate_hz)
        self._gravity = [Biquad(self._gb, self._ga) for _ in range(3)]
        step_b, step_a = step_lowpass_ba(rate_hz, STEP_LOWPASS_HZ)
        self._step_filter = Biquad(step_b, step_a)
        # event times are corrected by the causal filters' group delays (GA near DC ≈ 0.27 s; step
        # low-pass at a typical 1.8 Hz step frequency ≈ 0.08 s)
        self._ga_delay = group_delay_s(self._gb, self._ga, 0.05, rate_hz)
        self._step_delay = group_delay_s(step_b, step_a, 1.8, rate_hz)
        self._history = _Ring(int(HISTORY_S * rate_hz))
        self._delay_n = round(DELAY_S * rate_hz)
        self._pending: deque[list] = deque()  # [t, posture, walking, theta, stamp_ns, calibrated]
        self._stairs_n = round(STAIRS_WINDOW_S * rate_hz)
        self._stairs_ring: deque[tuple[float, float, float, float]] = deque()
        # Σ displacement, Σ displacement², Σ acceleration, Σ acceleration² (the same band), Σ lean along
        # body x, along z
        self._stairs_sum = [0.0] * 6
        self._displaced = [0.0, 0.0]  # the last two displacements (their second difference: the acceleration)
        self._displacement = [Biquad(b, a) for b, a in vertical_displacement_sections(rate_hz)]
        self._wearer_history: deque[float] = deque()  # per-second displacement std while walking
        self._wearer_sorted: list[float] = []  # the same values, sorted (running quantile)
        self._wearer_t = -math.inf
        self._level_lean: deque[tuple[float, float]] = deque()  # per-second window lean while walking level
        self._level_lean_sum = [0.0, 0.0]
        self._forward_cos_sin = (1.0, 0.0)  # trunk forward in the body frame's horizontal (x, z) plane
        self._static_n = round(STATIC_WINDOW_S * rate_hz)
        self._static_ring: deque[float] = deque()
        self._static_sum = [0.0, 0.0]
        self._still_s = 0.0  # how long the wearer has been still (STATIC_*, θ steady) up to now ...
        self._longest_still = 0.0  # ... and the longest such moment since the last transition
        self._theta_range = _RunningRange(1.0)  # θ over the last second (steady: PELVIS_STEADY_RAD)
        self.transitions: list[tuple[float, str]] = []
        # diagnostics (bounded): (t_peak, window or None, decision) of the latest stand/sit candidates
        self.candidate_log: deque[tuple[float, SitStandWindow | None, str]] = deque(maxlen=256)
        self._pending_sit_stand: tuple[float, float] | None = None  # (instant, walking deadline)
        self._excursions: deque[tuple[float, float]] = deque(maxlen=8)  # (instant, t2) not accepted
        self._overridden_onset = math.nan  # first step of a bout that overrode sitting without event
        self._handled_until = -math.inf  # sensor handling: detection paused until then
        self.handling_pauses = 0  # how often detection was paused for sensor handling
        self._stand_deadline = math.inf  # standing from a sit→stand must see walking before this, and
        self._start_unconfirmed = initial_posture == "standing" and placement == "chest"  # at the start
        self._lean_hold = 0.0  # s of trunk lean accumulated (leaky) without walking
        self._lean_t = -math.inf
        self._prime = reference_acc is not None  # GA starts from the first sample, not the reference
        auto = reference == "auto" and reference_acc is None
        rereference = CHEST_REREFERENCE_RAD if placement == "chest" else REREFERENCE_RAD
        self._finder = UprightFinder(rate_hz, reference_s, rereference_rad=rereference) if auto else None
        # (stamp s, source, rad from the reference it replaced or nan) of each reference taken
        self.reference_log: list[tuple[float, str, float]] = []
        if reference_acc is not None:
            self.reference_log.append((0.0, "given", math.nan))
        self.steps: list[float] = []
        self._emitted_steps = 0
        self._emitted_transitions = 0
        self._last_emitted_transition: tuple[float, str] | None = None
        self._theta_prev = 0.0
        # θ excursion tracker (zig-zag with hysteresis and a flat-valley rule)
        self._rising = True
        self._ext_value = 0.0
        self._ext_t = 0.0
        self._flat_ref = 0.0
        self._flat_t = 0.0
        self._valley: tuple[float, float] = (0.0, 0.0)  # (θ, t) of the last confirmed valley
        self._candidate: tuple[float, float, float] | None = None  # (t_valley, θ_peak, t_peak)
        # lying
        self._lying_crossing_t: float | None = None
        self._static_lying_t = -math.inf
        self._above_lying_since = math.inf
        self._sitting_up_t: float | None = None  # downward 70° crossing awaiting the hysteresis
        # steps / walking
        self._peaks = SvmPeaks(STEP_PEAK_THRESHOLD, STEP_PEAK_RELEASE)
        self._last_peak_t = -math.inf
        self._run: list[float] = []
        self.walking = False
        if reference_acc is not None:
            ref = np.asarray(reference_acc, dtype=float)
            self._calibrate(ref.reshape(-1, 3).mean(axis=0))

    # ---------------------------------------------------------------- calibration
    def _calibrate(self, mean_acc: np.ndarray) -> None:
        scale = scale_to_si(float(np.linalg.norm(mean_acc)), self.units)
        rot = mounting_from_reference(mean_acc, self.forward_axis) if self.align else np.eye(3)
        self._rot = [float(v) for v in (rot * scale).ravel()]
        body = (rot * scale) @ mean_acc
        for biquad, value in zip(self._gravity, body, strict=True):
            biquad.reset_steady(float(value))
        self._theta_prev = clip_acos(body[1] / float(np.linalg.norm(body)))
        self._ext_value = self._flat_ref = self._theta_prev
        self._valley = (self._theta_prev, 0.0)

    def _prime_filters(self, t: float, f: float, v: float, lat: float) -> None:
        """Start GA at the first sample (no start-up transient from the reference posture to the
        current one, which looked like a θ excursion and produced false transitions at t ≈ 0)."""
        self._prime = False
        for biquad, value in zip(self._gravity, (f, v, lat), strict=True):
            biquad.reset_steady(value)
        norm = math.sqrt(f * f + v * v + lat * lat)
        theta = clip_acos(v / norm) if norm > 0.0 else 0.0
        self._theta_prev = self._ext_value = self._flat_ref = theta
        self._ext_t = self._flat_t = t
        self._valley = (theta, t)

    @property
    def posture_assumed(self) -> bool:
        """The posture is the start's assumption (``initial_posture="auto"``), not yet evidenced."""
        return self._posture_assumed

    @property
    def calibrated(self) -> bool:
        return self._rot is not None

    def set_forward_axis(self, forward_axis: np.ndarray) -> None:
        """The trunk's forward direction in sensor axes (e.g. from the chest's sensor-to-segment
        calibration).

        It only decides upstairs vs downstairs (the sign of the forward lean), and only until the
        wearer's level walking is known (``_modality``): "up" stays the
        reference period's, so θ, steps and transitions are unaffected and nothing restarts. The
        up/down label is formed when a state is emitted (DELAY_S after its sample, from the window
        centred on it), so states from DELAY_S before this call on use the new axis. Before the
        reference period ends the axis is only stored (``mounting_from_reference`` uses it as its
        forward hint). Raises ValueError for a non-3-vector or an axis nearly vertical for the mounting.
        """
        forward = check_forward_axis(forward_axis)
        if self._rot is None:
            self.forward_axis = forward
            return
        body = np.array(self._rot).reshape(3, 3) @ forward
        if math.hypot(body[0], body[2]) < 0.3 * float(np.linalg.norm(body)):
            raise ValueError(f"forward axis {forward.tolist()} is nearly vertical for this mounting")
        heading = math.atan2(body[2], body[0])
        self.forward_axis = forward
        self._forward_cos_sin = (math.cos(heading), math.sin(heading))

    def keep_mounting(self, previous: ActivityMonitor) -> None:
        """Take the upright reference (sensor mounting) and forward axis of the monitor this one
        replaces after a gap: the sensor is still on the same trunk, and a reference taken again
        while the wearer walks would be wrong. GA then starts from the first sample (as with a given
        ``reference_acc``)."""
        if previous._rot is None:
            return
        self._rot = list(previous._rot)
        finder = previous._finder
        if finder is not None:
            finder = UprightFinder(self.rate_hz, finder.quiet_s, reference=finder.reference,
                                   rereference_rad=finder.rereference_rad)
        self._finder = finder
        self.forward_axis = previous.forward_axis
        self._forward_cos_sin = previous._forward_cos_sin
        self._prime = True

    def keep_wearer_history(self, previous: ActivityMonitor) -> None:
        """Carry the wearer's walking history (displacement, level walking's lean, whether standing
        was confirmed) over from the monitor this one replaces (a restart after a gap), so the
        wearer's stairs threshold and up/down reference do not start again."""
        self._wearer_history = deque(previous._wearer_history)
        self._wearer_sorted = list(previous._wearer_sorted)
        self._level_lean = deque(previous._level_lean)
        self._level_lean_sum = list(previous._level_lean_sum)
        self._start_unconfirmed = False
        self._stand_deadline = previous._stand_deadline
        self._posture_assumed = previous._posture_assumed

    # ---------------------------------------------------------------- per sample
    def update(self, stamp_ns: int, acc, gyro=None) -> ActivityState | None:
        """Feed one sample (its stamp, acceleration 3-vector, angular velocity 3-vector or None);
        return the state of stamp − DELAY_S. The gyro only helps find the upright reference
        (:class:`~gait_biofeedback.core.activity.reference.WearerWindow`); the detectors are the thesis's,
        on the accelerometer.

        READING of Eq 54: θ = arccos(GA_v/|GA|) rather than GA_v/g. Both are the angle between the
        trunk's vertical axis and gravity when still; dividing by |GA| removes the step-frequency
        ripple the weak 2nd-order GA filter leaves on GA_v (−16 dB at 2 Hz: ±0.6 m/s² → ±20° of
        spurious θ with /g while walking briskly).
        """
        t = stamp_ns / NS_PER_S
        if self._start_unconfirmed:
            self._start_unconfirmed = False
            self._stand_deadline = t + STAND_CONFIRM_S
        ax, ay, az = float(acc[0]), float(acc[1]), float(acc[2])
        rot = self._rot
        if self._finder is not None and self._find_reference(t, ax, ay, az, gyro):
            rot = self._rot
        if rot is None and self._finder is not None:
            self._pending.append([t, self.posture, False, self._theta_prev, stamp_ns, False])
            return self._emit()
        if rot is None:
            self._ref_sum[0] += ax
            self._ref_sum[1] += ay
            self._ref_sum[2] += az
            self._ref_count += 1
            if self._ref_count >= self._n_reference:
                self._calibrate(np.array(self._ref_sum) / self._ref_count)
                self._flat_t = self._ext_t = t
                self._valley = (self._theta_prev, t)
                self.reference_log.append((t, "start", math.nan))
            theta = self._theta_prev
            self._pending.append([t, self.posture, False, theta, stamp_ns, self._rot is not None])
            return self._emit()
        f = rot[0] * ax + rot[1] * ay + rot[2] * az
        v = rot[3] * ax + rot[4] * ay + rot[5] * az
        lat = rot[6] * ax + rot[7] * ay + rot[8] * az
        if self._prime:
            self._prime_filters(t, f, v, lat)
        gf = self._gravity[0].step(f)
        gv = self._gravity[1].step(v)
        gl = self._gravity[2].step(lat)
        inv_norm = 1.0 / math.sqrt(gf * gf + gv * gv + gl * gl)
        theta = clip_acos(gv * inv_norm)
        self._history.push(t, f, v, lat)
        magnitude = math.sqrt(f * f + v * v + lat * lat)
        self._update_static(magnitude)
        self._theta_range.push(t, theta)
        still = self._is_static() and self._theta_range.spread < PELVIS_STEADY_RAD
        self._still_s = self._still_s + 1.0 / self.rate_hz if still else 0.0
        self._longest_still = max(self._longest_still, self._still_s)
        self._update_stairs_window(
            (f * gf + v * gv + lat * gl) * inv_norm - STANDARD_GRAVITY, gf * inv_norm, gl * inv_norm)
        svm = self._step_filter.step(magnitude - STANDARD_GRAVITY)
        if theta > self._handling_rad and not self._is_static():
            self.handling_pauses += t >= self._handled_until
            self._handled_until = t + HANDLING_SETTLE_S
        if t < self._handled_until:
            self._hold_during_handling(t, theta)
            self._pending.append([t, self.posture, False, theta, stamp_ns, self._rot is not None])
            return self._emit()
        self._update_steps(t, svm, theta)
        self._update_lying(t, theta)
        thigh = self.thigh_inclination
        if thigh is not None:
            self._update_level(t, "thigh", thigh, THIGH_SIT_RAD, THIGH_STAND_RAD, THIGH_HOLD_S)
        elif self.placement == "pelvis":
            self._update_level(t, "pelvis", theta, PELVIS_SIT_RAD, PELVIS_STAND_RAD, PELVIS_HOLD_S)
        else:
            self._update_excursion(t, theta)
            self._update_lean(t, theta)
        if self._pending_sit_stand is not None and t > self._pending_sit_stand[1]:
            self._pending_sit_stand = None  # no walking followed: the weak sit→stand is dropped
        if t > self._stand_deadline and not self.walking:
            self._stand_deadline = math.inf
            if self.posture == "standing" and thigh is None:
                self.posture = "sitting"  # stood up but never walked: taken as still seated
        if self.walking and t - self._wearer_t >= 1.0:
            self._remember_walking(t)
        self._theta_prev = theta
        self._pending.append([t, self.posture, self.walking, theta, stamp_ns, True])
        return self._emit()

    def _find_reference(self, t: float, ax: float, ay: float, az: float, gyro) -> bool:
        """Feed the :class:`UprightFinder`; True when the mounting changed at this sample.

        The first quiet period (or walking bout, if that comes first) calibrates; a walking bout then
        checks a quiet reference and replaces it beyond its ``rereference_rad``, after which the finder
        stops. A replacement restarts the detectors as after sensor handling (the θ they tracked was
        measured from the wrong "up") and takes the bout's steps as a walk in progress.
        """
        finder = self._finder
        found = finder.update(t, ax, ay, az, gyro)
        if found is None:
            return False
        if finder.done:
            self._finder = None
        if found == "confirmed":
            self.reference_log.append((t, "walking confirms quiet", finder.angle))
            return False
        old = None if self._rot is None else np.array(self._rot).reshape(3, 3)
        self._calibrate(finder.reference)
        self._prime = True
        self.reference_log.append((t, found, finder.angle))
        if found == "quiet":
            return True
        if old is not None:
            rows = self._history.data
            rows[:, 1:] = rows[:, 1:] @ (np.array(self._rot).reshape(3, 3) @ np.linalg.inv(old)).T
            self._hold_during_handling(t, 0.0)
        self._adopt_walk(finder.walk_steps)
        return True

    def _adopt_walk(self, steps: list[float]) -> None:
        """The finder's walking bout becomes the monitor's walk in progress (steps counted)."""
        self._run = list(steps)
        self._last_peak_t = steps[-1]
        if not self.walking:
            self.walking = True
            self.steps.extend(s for s in steps if not self.steps or s > self.steps[-1])
            self._stand_deadline = math.inf
            self._relabel(steps[0] - 0.5 * MIN_STEP_S, walking=True)

    def _hold_during_handling(self, t: float, theta: float) -> None:
        """The sensor is being put on or adjusted: keep the last posture, detect nothing.

        Our addition (gait.md §3 has no such state): a worn chest sensor does not turn beyond
        θ = 110° while moving (lying still head-down is allowed); UCI subjects 2, 4, 6, 8, 10, 11,
        13, 14 do so in their first 45 s (strap being fastened), which produced false sit→stand,
        walking and lying. Detection restarts 5 s after the last such sample with the walking,
        excursion, lying and lean detectors cleared; the posture and the 60 s walk deadline of
        a sit→stand are kept. (A criterion on |a| > 3.5 g was tried and dropped: the simulator's
        walking reaches it.)
        """
        if self.walking:
            self._end_walking()
        self._run = []
        self._peaks.reset()
        self._candidate = None
        self._excursions.clear()
        self._pending_sit_stand = None
        self._lying_crossing_t = self._sitting_up_t = None
        self._lean_hold = 0.0
        self._overridden_onset = math.nan
        self._reset_excursion(t, theta)
        self._reset_level(t, self._level_source)
        # on resume, a θ beyond 70° is a fresh crossing into lying (or out of it)
        self._theta_prev = LYING_THRESHOLD_RAD + 0.01 if self.posture == "lying" else 0.0

    def flush(self) -> list[ActivityState]:
        """States of the samples still in the delay line (end of a recording)."""
        out = []
        while self._pending:
            out.append(self._make_state(self._pending.popleft()))
        return out

    # ---------------------------------------------------------------- output
    def _emit(self) -> ActivityState | None:
        if len(self._pending) <= self._delay_n:
            return None
        return self._make_state(self._pending.popleft())

    def _make_state(self, rec: list) -> ActivityState:
        t, posture, walking, theta, stamp_ns, calibrated = rec
        while self._emitted_steps < len(self.steps) and self.steps[self._emitted_steps] <= t:
            self._emitted_steps += 1
        while (
            self._emitted_transitions < len(self.transitions)
            and self.transitions[self._emitted_transitions][0] <= t
        ):
            self._last_emitted_transition = self.transitions[self._emitted_transitions]
            self._emitted_transitions += 1
        last = self._last_emitted_transition
        return ActivityState(
            stamp_ns=stamp_ns,
            posture=posture,
            locomotion=self._modality() if walking else "none",
            trunk_inclination=theta,
            step_count=self._emitted_steps,
            last_transition=last[1] if last else None,
            last_transition_ns=s_to_ns(last[0]) if last else None,
            calibrated=calibrated,
        )

    def _modality(self) -> str:
        """Level vs stairs (the trunk's vertical displacement) and up vs down (mean forward lean).

        Our replacement of the thesis's variance of GA_v [T §7.2.6], which read 61.8 % of the
        walking samples of ``hapt_waist`` right (a waist sensor sways no more on stairs): every step
        on stairs lifts or drops the whole body by a riser, so the trunk's vertical displacement at
        step frequency (acceleration along GA, integrated twice, slow drift removed) has about
        twice the amplitude of slow level walking's. The body rises and falls alike at the chest and
        the pelvis, and the displacement needs no upright reference and no forward axis. Stairs: the
        displacement referred to STAIRS_REFERENCE_RAD_S above STAIRS_DISPLACEMENT_M and above
        STAIRS_WEARER_RATIO × the wearer's usual walking (see there).

        Up vs down: the window's trunk direction more than UPSTAIRS_LEVEL_LEAN_RAD from the wearer's
        level walking once LEVEL_LEAN_MIN_N s of it are known; before, the thesis's lean along the
        forward axis. READING: the thesis integrates GA_f over the bout and uses one threshold; the
        mean over the centred window is that integral divided by the window length. With x forward, a forward
        lean gives GA_f = −g·sin(lean) (gait.md §3.2), so we test the lean −GA_f/g: upstairs = the
        trunk leans further forward than the upright reference.
        """
        n = len(self._stairs_ring)
        if n == 0 or self._referred_displacement() <= self._stairs_threshold:
            return "level"
        lean_x, lean_z = self._stairs_sum[4] / n, self._stairs_sum[5] / n
        known = len(self._level_lean)
        if known >= LEVEL_LEAN_MIN_N:
            level_x, level_z = (v / known for v in self._level_lean_sum)
            steeper = math.hypot(lean_x - level_x, lean_z - level_z) > math.sin(UPSTAIRS_LEVEL_LEAN_RAD)
        else:
            c, s = self._forward_cos_sin
            steeper = c * lean_x + s * lean_z > math.sin(UPSTAIRS_LEAN_RAD)
        return "upstairs" if steeper else "downstairs"

    def _referred_displacement(self) -> float:
        """σ_d·min(1, ω_ref/ω) (m) over the stairs window, ω = √(σ_a/σ_d) (see STAIRS_REFERENCE_RAD_S)."""
        n = len(self._stairs_ring)
        d1, d2, a1, a2 = (v / n for v in self._stairs_sum[:4])
        var_d, var_a = d2 - d1 * d1, a2 - a1 * a1
        if var_d <= 0.0 or var_a <= 0.0:
            return 0.0
        sigma_d = math.sqrt(var_d)
        omega = math.sqrt(math.sqrt(var_a) / sigma_d)
        return sigma_d * min(1.0, STAIRS_REFERENCE_RAD_S / omega)

    def _remember_walking(self, t: float) -> None:
        """One value per second of walking into the wearer's history; the stairs threshold follows."""
        self._wearer_t = t
        history, ordered = self._wearer_history, self._wearer_sorted
        value = self._referred_displacement()
        history.append(value)
        bisect.insort(ordered, value)
        if len(history) > DISPLACEMENT_HISTORY_N:
            del ordered[bisect.bisect_left(ordered, history.popleft())]
        if value <= self._stairs_threshold:
            n = len(self._stairs_ring)
            lean = (self._stairs_sum[4] / n, self._stairs_sum[5] / n)
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

    def _relabel(self, t_from: float, *, posture: str | None = None, walking: bool | None = None) -> None:
        for rec in reversed(self._pending):
            if rec[0] < t_from:
                break
            if posture is not None:
                rec[1] = posture
            if walking is not None:
                rec[2] = walking

    # ---------------------------------------------------------------- running windows
    def _update_static(self, magnitude: float) -> None:
        ring, sums = self._static_ring, self._static_sum
        m = magnitude - STANDARD_GRAVITY
        ring.append(m)
        sums[0] += m
        sums[1] += m * m
        if len(ring) > self._static_n:
            old = ring.popleft()
            sums[0] -= old
            sums[1] -= old * old

    def _is_static(self) -> bool:
        n = len(self._static_ring)
        if n < self._static_n:
            return False
        mean = self._static_sum[0] / n
        return self._static_sum[1] / n - mean * mean < STATIC_STD**2

    def _update_stairs_window(self, vertical: float, up_f: float, up_l: float) -> None:
        """Running sums of the vertical displacement and acceleration at step frequency (from
        ``vertical``, the acceleration along GA less g) and of the leans −GA_f/|GA|, −GA_l/|GA| (unit
        direction); the lean along the trunk's forward axis is combined from the last two in
        ``_modality``."""
        ring = self._stairs_ring
        for section in self._displacement:
            vertical = section.step(vertical)
        before, last = self._displaced
        acceleration = (vertical - 2.0 * last + before) * self.rate_hz**2  # the band-passed input
        self._displaced = [last, vertical]
        row = (vertical, acceleration, -up_f, -up_l)
        ring.append(row)
        self._add_to_stairs_sums(row, 1.0)
        if len(ring) > self._stairs_n:
            self._add_to_stairs_sums(ring.popleft(), -1.0)

    def _add_to_stairs_sums(self, row: tuple[float, float, float, float], sign: float) -> None:
        d, a, x, z = row
        sums = self._stairs_sum
        sums[0] += sign * d
        sums[1] += sign * d * d
        sums[2] += sign * a
        sums[3] += sign * a * a
        sums[4] += sign * x
        sums[5] += sign * z

    # ---------------------------------------------------------------- detectors
    def _add_transition(self, t: float, kind: str, posture: str, *, walked: bool = False) -> None:
        """Record an event; a sit→stand not yet followed by a walk must see one within 60 s.

        Stand→sit then sit→lie within MERGE_S (MERGE_MOVING_S without a still moment between) is one
        stand→lie at the first instant, lie→sit then sit→stand one lie→stand (HAPT's six transitions;
        the thesis names four). The first event may have been published already: the merged one
        replaces it, with its stamp.
        """
        merged = {("stand_to_sit", "sit_to_lie"): "stand_to_lie",
                  ("lie_to_sit", "sit_to_stand"): "lie_to_stand"}
        last = self.transitions[-1] if self.transitions else None
        gap = math.inf if last is None else t - last[0]
        moving = self._longest_still < MERGE_STILL_S
        if (gap <= MERGE_S or (gap <= MERGE_MOVING_S and moving)) and (last[1], kind) in merged:
            self.transitions[-1] = (last[0], merged[(last[1], kind)])
            if self._last_emitted_transition == last:
                self._last_emitted_transition = self.transitions[-1]
        else:
            self.transitions.append((t, kind))
        self._still_s = self._longest_still = 0.0
        self.posture = posture
        self._posture_assumed = False
        self._pending_sit_stand = None  # older than this event: it cannot follow it
        self._excursions.clear()
        self._relabel(t, posture=posture)
        unconfirmed = kind == "sit_to_stand" and not walked
        self._stand_deadline = t + STAND_CONFIRM_S if unconfirmed else math.inf

    def _update_lying(self, t: float, theta: float) -> None:
        """Sit-to-lie / lie-to-sit: θ crossing 70°, direction from dθ/dt, static check [T §7.2.4].

        READINGs: θ rising through 70° is sit-to-lie (GA_v falling), θ falling is lie-to-sit. The
        static period must show gravity on the trunk's horizontal plane: we accept the frontal axis
        (supine/prone, as the thesis) and also the lateral axis (side-lying), i.e. θ > 70° while
        static. The instant is the crossing minus the GA filter's group delay. Our addition: a
        lie-to-sit is confirmed only once θ is 10° below the threshold (hysteresis), so a trunk
        resting near 70° does not flicker between lying and sitting.
        """
        lying_now = theta > LYING_THRESHOLD_RAD
        prev_lying = self._theta_prev > LYING_THRESHOLD_RAD
        if lying_now and not prev_lying:
            self._above_lying_since = t
        if lying_now and t - self._above_lying_since >= STATIC_WINDOW_S and self._is_static():
            self._static_lying_t = t
        if lying_now and not prev_lying and self.posture != "lying":
            self._lying_crossing_t = t
            self._candidate = None
        elif not lying_now and self._lying_crossing_t is not None:
            self._lying_crossing_t = None  # never static while above 70°: unknown movement
        if self._lying_crossing_t is not None and self._static_lying_t >= self._lying_crossing_t:
            kind = "stand_to_lie" if self.posture == "standing" else "sit_to_lie"
            self._add_transition(self._lying_crossing_t - self._ga_delay, kind, "lying")
            self._lying_crossing_t = None
        if self.posture != "lying" or lying_now:
            self._sitting_up_t = None
        elif prev_lying and t - self._static_lying_t <= LYING_STATIC_BEFORE_S:
            self._sitting_up_t = t
        if self._sitting_up_t is not None and theta < LYING_THRESHOLD_RAD - LYING_HYSTERESIS_RAD:
            # a trunk that rested between 60° and 70° for long sat up later than its 70° crossing
            crossing = self._sitting_up_t if t - self._sitting_up_t <= LYING_STATIC_BEFORE_S else t
            self._add_transition(crossing - self._ga_delay, "lie_to_sit", "sitting")
            self._sitting_up_t = None
            self._reset_excursion(t, theta)

    def _reset_excursion(self, t: float, theta: float) -> None:
        self._rising = False
        self._ext_value = self._flat_ref = theta
        self._ext_t = self._flat_t = t
        self._candidate = None

    def _update_excursion(self, t: float, theta: float) -> None:
        """Peaks and valleys of θ; a peak in [20°, 70°) is a stand/sit candidate [T §7.2.5].

        READING: the thesis's candidate is θ crossing 20°; we take any excursion whose peak exceeds
        20°, so that a transition starting from a forward-leaning sitting posture (θ already
        > 20°) is also a candidate. ΔY and the walking check reject the rest.
        """
        if self.posture == "lying" or theta > LYING_THRESHOLD_RAD:
            self._reset_excursion(t, theta)
            return
        if self._rising:
            if theta > self._ext_value:
                self._ext_value, self._ext_t = theta, t
            elif theta < self._ext_value - EXCURSION_HYSTERESIS_RAD:
                if self._ext_value >= SIT_STAND_CANDIDATE_RAD:
                    self._candidate = (self._valley[1], self._ext_value, self._ext_t)
                self._rising = False
                self._ext_value = self._flat_ref = theta
                self._ext_t = self._flat_t = t
            return
        if theta < self._ext_value:
            self._ext_value, self._ext_t = theta, t
        if theta < self._flat_ref - VALLEY_FLAT_STEP_RAD:
            self._flat_ref, self._flat_t = theta, t
        if theta > self._ext_value + EXCURSION_HYSTERESIS_RAD or t - self._flat_t > VALLEY_FLAT_S:
            self._valley = (self._ext_value, self._ext_t)
            if self._candidate is not None:
                self._analyse_candidate(t)
            self._rising = True
            self._ext_value = self._flat_ref = theta
            self._ext_t = self._flat_t = t

    def _analyse_candidate(self, t: float) -> None:
        t_valley, _, t_peak = self._candidate
        self._candidate = None
        if t - t_valley > MAX_EXCURSION_S:
            t_valley = t - MAX_EXCURSION_S
        rows = self._history.since(t_valley - 1.0)
        window = analyse_sit_stand(rows[:, 0], rows[:, 1:], self.rate_hz, t_peak)
        decision = self._judge(window)
        self.candidate_log.append((t_peak, window, decision))
        if decision == "stand_to_sit":
            self._add_transition(window.instant, "stand_to_sit", "sitting")
        elif decision == "sit_to_stand":
            self._add_transition(window.instant, "sit_to_stand", "standing")
        elif decision == "sit_to_stand?":
            self._pending_sit_stand = (window.instant, window.t2 + CONFIRM_WALK_S)
        elif window is not None:
            self._excursions.append((window.instant, window.t2))
            if self.walking and self._run and self._run[0] == self._overridden_onset:
                self._stand_up_before_walking(self._run[0])

    def _stand_up_before_walking(self, onset: float) -> bool:
        """A seated person who walks off stood up first: take the excursion next to the onset.

        Our addition to §7.2.5/§7.2.6 (Fig 27 only lets an upright trunk walk): the event keeps the
        excursion's instant; the posture switches at the instant or, if that has left the delay
        line, now. Returns whether a sit→stand was added.
        """
        seated = self.posture == "sitting" or onset == self._overridden_onset
        if not seated or len(self._run) < SIT_WALK_MIN_STEPS:
            return False
        for instant, t2 in reversed(self._excursions):
            if onset - WALK_ONSET_GAP_S <= t2 <= onset + ONSET_OVERLAP_S:
                self._excursions.clear()
                self._overridden_onset = math.nan
                self._add_transition(instant, "sit_to_stand", "standing", walked=True)
                self._relabel(min(instant, onset - 0.5 * MIN_STEP_S), posture="standing")
                return True
        return False

    def _judge(self, window: SitStandWindow | None) -> str:
        """Thesis gates (§7.2.5) then the posture-consistency gates chosen on UCI dev data.

        Returns the decision: ``stand_to_sit``, ``sit_to_stand``, ``sit_to_stand?`` (weak: waits for
        walking) or why it was rejected.
        """
        if window is None or window.t2 - window.t1 > MAX_SIT_STAND_S:
            return "no window"
        height = abs(window.delta_height_m)
        if not self.min_height_change <= height <= self.max_height_change:
            return "ΔY"  # thesis: |ΔY| < 50 % thigh is bowing / an unknown movement
        if (window.svm_score < 0.0) != (window.delta_height_m < 0.0):
            return "sign"  # choice: ∫SVM (thesis) and the sign of ΔY (its "alternative method") agree
        steps_inside = sum(1 for s in self._run if window.t1 <= s <= window.t2)
        steps_inside += sum(1 for s in self.steps[-8:] if window.t1 <= s <= window.t2)
        if steps_inside >= MIN_SUCCESSIVE_PEAKS:
            return "walking"  # a walking bout, not a postural transition
        strong = height >= self.strong_height_change and abs(window.svm_score) >= STRONG_SVM_SCORE
        if window.svm_score < 0.0:
            # consistency: one can only sit down from standing; a weak stand→sit has no later cue
            # that could confirm it (sitting still looks like standing still), so it is rejected
            if self.posture != "standing" and not self._posture_assumed:
                return "not standing"
            return "stand_to_sit" if strong else "weak"
        if self.posture != "sitting" and not self._posture_assumed:
            return "not sitting"
        return "sit_to_stand" if strong else "sit_to_stand?"

    def _update_level(self, t: float, source: str, value: float, sit: float, stand: float, hold: float
                      ) -> None:
        """Sitting while ``value`` is held above ``sit`` for ``hold`` s, standing below ``stand`` or
        while walking: the pelvis placement (value = θ, see PELVIS_*; the thesis's §7.2.5 detector is
        for the chest) and the thighs (value = their mean inclination, see ``thigh.py``). Our rule.
        For the pelvis θ must also be steady when the level is confirmed. The event's instant is where
        the value last crossed the middle of the two levels (a symmetric movement's middle) within the
        hold before the level was left, else where it was left; less the GA filter's delay. A change
        of source (the thighs start or stop sending) starts the level state again."""
        if source != self._level_source:
            self._reset_level(t, source)
        middle = 0.5 * (sit + stand)
        previous, self._level_value = self._level_value, value
        if (previous - middle) * (value - middle) <= 0.0 and previous != value:
            self._middle_t = t
        if self.posture == "lying":
            self._level = None
            return
        if self.walking or value < stand:
            target = "standing"
        elif value > sit:
            target = "sitting"
        elif self._level is None and self._posture_assumed:
            return  # between the two levels: no evidence for the assumed posture either way
        else:
            target = self._level[0] if self._level else self.posture
        if target == self.posture and not self._posture_assumed:
            self._level = None
            return
        if self._level is None or self._level[0] != target:
            self._level = (target, t)
            return
        steady = source != "pelvis" or self._theta_range.spread < PELVIS_STEADY_RAD
        if not self.walking and (t - self._level[1] < hold or not steady):
            return
        since = self._level[1]
        instant = (self._middle_t if since - hold <= self._middle_t <= since else since) - self._ga_delay
        self._level = None
        if self._posture_assumed:  # the first reading of the level: a posture found, not a transition
            self.posture, self._posture_assumed = target, False
            self._relabel(since, posture=target)
            return
        kind = "sit_to_stand" if target == "standing" else "stand_to_sit"
        self._add_transition(instant, kind, target, walked=True)  # the level is the evidence: no deadline

    def _reset_level(self, t: float, source: str) -> None:
        self._level_source = source
        self._level = None
        self._level_value = math.nan
        self._middle_t = t

    def _update_lean(self, t: float, theta: float) -> None:
        """A trunk lean held in [25°, 70°) for 30 s without walking ⇒ sitting (no event).

        Thesis §7.2.6 rejects walking with a non-upright trunk, i.e. standing is upright; the
        converse used here (a long-held lean is not standing) is our choice, tuned on UCI dev data.
        The hold is leaky: each second outside the band takes back LEAN_RECOVERY seconds, so a
        seated person who sits up now and then for a moment still accumulates the hold.
        """
        dt = t - self._lean_t
        self._lean_t = t
        if self.walking or not 0.0 < dt < 1.0:
            self._lean_hold = 0.0
        elif SIT_LEAN_RAD <= theta < LYING_THRESHOLD_RAD:
            self._lean_hold += dt
            if self._lean_hold >= SIT_LEAN_HOLD_S and self.posture == "standing":
                self.posture = "sitting"
                self._posture_assumed = False
                self._pending_sit_stand = None
                self._relabel(t, posture="sitting")
        else:
            self._lean_hold = max(0.0, self._lean_hold - LEAN_RECOVERY * dt)

    def _end_walking(self) -> None:
        self.walking = False
        self._relabel(self._last_peak_t + 0.5 * MIN_STEP_S, walking=False)
        self._run = []
        self._overridden_onset = math.nan

    def _update_steps(self, t: float, svm: float, theta: float) -> None:
        """SVM peaks → steps and walking bouts [T §7.2.6, Table 16(b) "low threshold + rejection"]."""
        if self.walking and t - self._last_peak_t > MAX_STEP_S:
            self._end_walking()
        peak = self._peaks.update(t, svm, theta)
        if peak is None:
            return
        t_peak = peak[0] - self._step_delay
        if t_peak - self._last_peak_t < MIN_STEP_S:
            return
        if peak[1] > UPRIGHT_WALKING_RAD:
            self._run = []
            self._last_peak_t = t_peak
            return
        if t_peak - self._last_peak_t > MAX_STEP_S:
            self._run = []
        self._last_peak_t = t_peak
        self._run.append(t_peak)
        if self.walking:
            self.steps.append(t_peak)
        elif len(self._run) >= MIN_SUCCESSIVE_PEAKS:
            self.walking = True
            self.steps.extend(self._run)
            pending = self._pending_sit_stand
            if pending is not None and self.posture == "sitting" and self._run[0] <= pending[1]:
                # the event stands; standing itself needs a walk of SIT_WALK_MIN_STEPS within a minute
                self._add_transition(pending[0], "sit_to_stand", "standing")
            self._pending_sit_stand = None
            self._relabel(self._run[0] - 0.5 * MIN_STEP_S, walking=True)
        if not (self.walking and len(self._run) >= SIT_WALK_MIN_STEPS):
            return
        self._stand_deadline = math.inf  # a real walk (not a seated wearer's few peaks) confirms standing
        assumed, self._posture_assumed = self._posture_assumed, False
        if self.posture != "standing":
            # an assumed seat may have been a standing wearer's bow before the walk: no event from it
            if not assumed and self._stand_up_before_walking(self._run[0]):
                return
            if self.posture == "sitting" and not assumed:
                self._overridden_onset = self._run[0]  # a stand-up analysed later may still name it
            self.posture = "standing"  # walking implies upright (Fig 27); no event is invented
            self._relabel(self._run[0] - 0.5 * MIN_STEP_S, posture="standing")


def classify_activity(
    acc: np.ndarray,
    rate_hz: float,
    *,
    units: str = "m/s2",
    reference: slice | tuple[int, int] | str = "auto",
    reference_s: float = 2.0,
    align: bool = True,
    forward_axis: np.ndarray | None = None,
    thigh_length_m: float = DEFAULT_THIGH_LENGTH_M,
    initial_posture: str = "auto",
    placement: str = "chest",
    thighs: Mapping[str, np.ndarray] | None = None,
    gyro: np.ndarray | None = None,
) -> dict:
    """Batch entry point: the streaming monitor run over ``acc`` (N×3), labels per sample.

    ``reference``: sample range of an upright standing period (re-orients any mounting), or
    ``"auto"`` (found in the stream, see :mod:`~gait_biofeedback.core.activity.reference`), or
    ``"start"`` (the first 2 s, as the thesis). Returns ``{"posture": (N,) str, "locomotion": (N,) str,
    "transitions": [(t, kind)], "steps": [t], "trunk_inclination": (N,) rad,
    "reference": [(t, source, rad from the one replaced)]}``, t from 0 at sample 0. ``thighs``: thigh
    accelerometers (N×3 each, the same samples' times) that tell sitting from standing, as
    ``ActivityStream`` does with the ``thighs`` it hears. ``gyro``: the trunk sensor's angular velocity
    (N×3 rad/s), which tells a sensor not yet worn from a still wearer (the upright reference).
    """
    acc = np.asarray(acc, dtype=float)
    reference_acc, mode = None, "auto"
    if isinstance(reference, str):
        mode = reference
    else:
        sl = reference if isinstance(reference, slice) else slice(*reference)
        reference_acc = acc[sl].mean(axis=0)
    monitor = ActivityMonitor(
        rate_hz,
        units=units,
        reference_acc=reference_acc,
        reference=mode,
        reference_s=reference_s,
        align=align,
        forward_axis=forward_axis,
        thigh_length_m=thigh_length_m,
        initial_posture=initial_posture,
        placement=placement,
    )
    states: list[ActivityState] = []
    update = monitor.update
    thigh_rows = {seg: np.asarray(a, dtype=float).tolist() for seg, a in (thighs or {}).items()}
    inputs = ThighInputs(list(thigh_rows), rate_hz, reference_s)
    rates = [None] * len(acc) if gyro is None else np.asarray(gyro, dtype=float).tolist()
    for k, (stamp_ns, sample, rate) in enumerate(zip(sample_stamps(len(acc), rate_hz).tolist(), acc.tolist(),
                                                     rates, strict=True)):
        if thigh_rows:
            for seg, rows in thigh_rows.items():
                inputs.add(seg, stamp_ns, rows[k])
            monitor.thigh_inclination = inputs.inclination_at(stamp_ns, stamp_ns)
        state = update(stamp_ns, sample, rate)
        if state is not None:
            states.append(state)
    states.extend(monitor.flush())
    return {
        "posture": np.array([s.posture for s in states]),
        "locomotion": np.array([s.locomotion for s in states]),
        "transitions": list(monitor.transitions),
        "steps": list(monitor.steps),
        "trunk_inclination": np.array([s.trunk_inclination for s in states]),
        "reference": list(monitor.reference_log),
    }
