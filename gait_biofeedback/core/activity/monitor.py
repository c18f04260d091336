"""Trunk activity monitor: posture, transitions, walking modality and steps (thesis ch. 7).

Spec: gait.md §3 (thesis §7.2.3–7.2.6, Fig 27). One trunk accelerometer (chest or pelvis); the same
sensor's gyro, if given, only helps find the upright reference (reference.py).

Pipeline per sample (``ActivityMonitor.update``), all on Python floats:
  raw acc → ×scale, rotate into the body frame (x forward, y up, z right) → GA = 0.25 Hz elliptic
  low-pass per axis → trunk inclination θ = arccos(GA_v/g) (Eq 54) (trunk.py: the mounting from an
  upright reference, Eq 14, given, found in the stream or the first seconds; units) → three detectors:
  A) lying: θ crossing 70° confirmed by a static second lying (§7.2.4; lying.py);
  B) sit/stand: a θ excursion peaking above 20°, bounded by θ minima, ΔY gate, ∫SVM sign (§7.2.5;
     sit_stand.py); at the pelvis (lower back, waist) and while thighs send, a level held (level.py);
  C) walking: ≥ 3 successive SVM peaks within a step duration, trunk upright (§7.2.6; walking.py); level
     vs stairs from the trunk's vertical displacement at step frequency, up vs down from the lean
     beyond the wearer's level walking or, until that is known, along the forward axis (our
     replacement of the thesis's variance of GA_v and ∫GA_f, modality.py).
The detectors share the posture and its transitions (posture.py: the consistency rules, our additions
to §7.2.5) and the delay line (output.py); this class wires them, and pauses them while the sensor
is handled (still.py ``Handling``). Until the upright reference is known the monitor outputs its
initial posture, no locomotion and ``calibrated=False``.

Delay: every state describes the sample ``DELAY_S`` = 3 s before the newest input, and labels are
final when emitted. Transition *events* are appended when confirmed, about 1 s after the trunk
settles (typically 2–4 s after the instant); their time is the estimated instant and the posture
label switches at the instant when that is still inside the delay line, otherwise at confirmation.

Numbers the thesis does not give (gait.md §3.7) are chosen in the detectors' modules; each constant
says where from.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from gait_biofeedback.core.activity.level import LeanHold, Level
from gait_biofeedback.core.activity.lying import LYING_THRESHOLD_RAD, Lying
from gait_biofeedback.core.activity.modality import Modality
from gait_biofeedback.core.activity.output import DELAY_S, ActivityState, DelayLine
from gait_biofeedback.core.activity.posture import Posture, initial_posture_for
from gait_biofeedback.core.activity.signal import STANDARD_GRAVITY, UnitMismatchWarning, clip_acos
from gait_biofeedback.core.activity.sit_stand import DEFAULT_THIGH_LENGTH_M, SitStand
from gait_biofeedback.core.activity.still import Handling, Stillness
from gait_biofeedback.core.activity.thigh import ThighInputs
from gait_biofeedback.core.activity.trunk import TrunkFrame, check_forward_axis
from gait_biofeedback.core.activity.walking import Walking
from gait_biofeedback.core.stamps import NS_PER_S, sample_stamps

__all__ = ["DELAY_S", "INITIAL_POSTURES", "LOCOMOTIONS", "POSTURES", "TRANSITIONS", "ActivityMonitor",
           "ActivityState", "UnitMismatchWarning", "check_forward_axis", "classify_activity",
           "initial_posture_for"]

POSTURES = ("standing", "sitting", "lying")
INITIAL_POSTURES = ("auto", *POSTURES)  # auto: see initial_posture_for
LOCOMOTIONS = ("none", "level", "upstairs", "downstairs")
REFERENCES = ("auto", "start")  # upright reference found in the stream (reference.py), or the first seconds
TRANSITIONS = ("sit_to_stand", "stand_to_sit", "sit_to_lie", "lie_to_sit", "stand_to_lie", "lie_to_stand")
PLACEMENTS = ("chest", "pelvis")  # chest / sternum (the thesis), or pelvis / lower back / waist


class ActivityMonitor:
    """Streaming chest activity monitor: ``update(stamp_ns, acc) -> ActivityState | None``.

    ``acc``: one 3-vector (sensor axes, any mounting). Returns the state of the sample ``DELAY_S``
    before (``None`` until the delay line is full); call ``flush()`` at the end for the remaining
    states. Internally the detectors work on the stamps in float seconds (``stamp_ns / 1e9``).
    ``initial_posture`` "auto": :func:`initial_posture_for`; an assumed posture gives way to the first
    strong transition of either kind and to the first level (pelvis, thighs), which sets it without an
    event.
    """

    def __init__(self, rate_hz: float, *, units: str = "m/s2", reference_acc: np.ndarray | None = None,
                 reference_s: float = 2.0, reference: str = "auto", align: bool = True,
                 forward_axis: np.ndarray | None = None, thigh_length_m: float = DEFAULT_THIGH_LENGTH_M,
                 initial_posture: str = "auto", placement: str = "chest") -> None:
        if placement not in PLACEMENTS:
            raise ValueError(f"placement must be one of {PLACEMENTS}, got {placement!r}")
        if not 20.0 <= rate_hz <= 200.0:
            raise ValueError(f"rate_hz must be in [20, 200], got {rate_hz}")
        if initial_posture not in INITIAL_POSTURES:
            raise ValueError(f"initial_posture must be one of {INITIAL_POSTURES}")
        # an assumed posture (auto) gives way to the first strong transition of either kind (see sit_stand)
        assumed = initial_posture == "auto"
        if assumed:
            given = reference_acc is not None or reference == "start"  # the thesis's standing period
            initial_posture = initial_posture_for(placement, given)
        if reference not in REFERENCES:
            raise ValueError(f"reference must be one of {REFERENCES}, got {reference!r}")
        self.rate_hz = float(rate_hz)
        self.placement = placement
        # the thighs' mean inclination (rad) at the next sample, set by the caller before each update
        # (ActivityStream, from ThighTilt); None: no thigh data, the trunk decides sitting vs standing
        self.thigh_inclination: float | None = None
        auto = reference == "auto" and reference_acc is None
        self._frame = frame = TrunkFrame(self.rate_hz, units=units, reference_s=reference_s, auto=auto,
                                         align=align, forward_axis=forward_axis, placement=placement)
        self._line = DelayLine(round(DELAY_S * rate_hz))
        self._still = Stillness(self.rate_hz)
        self._posture = Posture(initial_posture, assumed=assumed, placement=placement, line=self._line,
                                still=self._still)
        self._walking = Walking(self.rate_hz, self._posture, self._line)
        self._modality = Modality(self.rate_hz)
        self._sit_stand = SitStand(self.rate_hz, thigh_length_m, self._posture, self._walking)
        self._lying = Lying(self._posture, self._still, frame.ga_delay)
        self._level = Level(self._posture, self._walking, self._still, frame.ga_delay)
        self._lean = LeanHold(self._posture, self._walking)
        self._handling = Handling(placement)
        self.steps = self._walking.steps  # step times (s), corrected by the step filter's group delay
        self.transitions = self._posture.transitions  # (estimated instant s, kind) of each one confirmed
        self.reference_log = frame.reference_log  # (stamp s, source, rad from the one replaced or nan)
        # diagnostics (bounded): (t_peak, window or None, decision) of the latest stand/sit candidates
        self.candidate_log = self._sit_stand.candidate_log
        if reference_acc is not None:
            frame.reference_log.append((0.0, "given", math.nan))
            ref = np.asarray(reference_acc, dtype=float)
            frame.calibrate(ref.reshape(-1, 3).mean(axis=0))
            frame.prime = True  # GA starts from the first sample, not the reference
            self._sit_stand.start(frame.theta_prev, 0.0)

    # ---------------------------------------------------------------- what the detectors found
    @property
    def posture(self) -> str:
        return self._posture.posture

    @property
    def posture_assumed(self) -> bool:
        """The posture is the start's assumption (``initial_posture="auto"``), not yet evidenced."""
        return self._posture.assumed

    @property
    def walking(self) -> bool:
        return self._walking.walking

    @property
    def emitted_steps(self) -> int:
        """Steps counted in the states emitted so far."""
        return self._line.emitted_steps

    @property
    def forward_axis(self) -> np.ndarray | None:
        return self._frame.forward_axis

    @property
    def handling_pauses(self) -> int:
        """How often detection was paused for sensor handling."""
        return self._handling.pauses

    @property
    def calibrated(self) -> bool:
        return self._frame.rot is not None

    # ---------------------------------------------------------------- mounting
    def set_forward_axis(self, forward_axis: np.ndarray) -> None:
        """The trunk's forward direction in sensor axes (e.g. from the chest's sensor-to-segment
        calibration).

        It only decides upstairs vs downstairs (the sign of the forward lean), and only until the
        wearer's level walking is known (:meth:`Modality.label`): "up" stays the
        reference period's, so θ, steps and transitions are unaffected and nothing restarts. The
        up/down label is formed when a state is emitted (DELAY_S after its sample, from the window
        centred on it), so states from DELAY_S before this call on use the new axis. Before the
        reference period ends the axis is only stored (``mounting_from_reference`` uses it as its
        forward hint). Raises ValueError for a non-3-vector or an axis nearly vertical for the mounting.
        """
        heading = self._frame.forward_heading(forward_axis)
        if heading is not None:
            self._modality.forward_cos_sin = heading

    def keep_mounting(self, previous: ActivityMonitor) -> None:
        """Take the upright reference (sensor mounting) and forward axis of the monitor this one
        replaces after a gap: the sensor is still on the same trunk, and a reference taken again
        while the wearer walks would be wrong. GA then starts from the first sample (as with a given
        ``reference_acc``)."""
        if self._frame.keep_mounting(previous._frame):
            self._modality.forward_cos_sin = previous._modality.forward_cos_sin

    def keep_wearer_history(self, previous: ActivityMonitor) -> None:
        """Carry the wearer's walking history (displacement, level walking's lean, whether standing
        was confirmed) over from the monitor this one replaces (a restart after a gap), so the
        wearer's stairs threshold and up/down reference do not start again."""
        self._modality.keep_wearer(previous._modality)
        posture, before = self._posture, previous._posture
        posture.start_unconfirmed = False
        posture.stand_deadline = before.stand_deadline
        posture.assumed = before.assumed

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
        frame, posture = self._frame, self._posture
        if posture.start_unconfirmed:
            posture.start(t)
        ax, ay, az = float(acc[0]), float(acc[1]), float(acc[2])
        if frame.finder is not None:
            self._find_reference(t, ax, ay, az, gyro)
        rot = frame.rot
        if rot is None:
            if frame.finder is None and frame.add_start(t, ax, ay, az):
                self._sit_stand.start(frame.theta_prev, t)
            if self.thigh_inclination is not None:  # the thighs need no trunk frame (their calibration)
                self._level.thighs(t, self.thigh_inclination)
            return self._emit(t, posture.posture, False, frame.theta_prev, stamp_ns, frame.rot is not None)
        f = rot[0] * ax + rot[1] * ay + rot[2] * az
        v = rot[3] * ax + rot[4] * ay + rot[5] * az
        lat = rot[6] * ax + rot[7] * ay + rot[8] * az
        if frame.prime:
            self._sit_stand.start(frame.prime_filters(f, v, lat), t)
        gf, gv, gl = frame.gravity(f, v, lat)
        inv_norm = 1.0 / math.sqrt(gf * gf + gv * gv + gl * gl)
        theta = clip_acos(gv * inv_norm)
        self._sit_stand.history.push(t, f, v, lat)
        magnitude = math.sqrt(f * f + v * v + lat * lat)
        self._still.update(t, magnitude, theta)
        self._modality.update(
            (f * gf + v * gv + lat * gl) * inv_norm - STANDARD_GRAVITY, gf * inv_norm, gl * inv_norm)
        walking = self._walking
        svm = walking.svm(magnitude)
        if self._handling.update(t, theta, self._still):
            self._hold_during_handling(t, theta)
            return self._emit(t, posture.posture, False, theta, stamp_ns, True)
        walking.update(t, svm, theta)
        lying = self._lying.update(t, theta, frame.theta_prev)
        if lying == "crossed":
            self._sit_stand.drop_candidate()
        elif lying == "sat up":
            self._sit_stand.reset(t, theta)
        thigh = self.thigh_inclination
        if thigh is not None:
            self._level.thighs(t, thigh)
        elif self.placement == "pelvis":
            self._level.pelvis(t, theta)
        else:
            self._sit_stand.update(t, theta)
            self._lean.update(t, theta)
        posture.expire(t, walking.walking, thigh is not None)
        if walking.walking and t - self._modality.wearer_t >= 1.0:
            self._modality.remember_walking(t)
        frame.theta_prev = theta
        return self._emit(t, posture.posture, walking.walking, theta, stamp_ns, True)

    def _find_reference(self, t: float, ax: float, ay: float, az: float, gyro) -> None:
        """Feed the upright finder (:meth:`TrunkFrame.find_reference`). A walking bout that replaced a
        quiet reference restarts the detectors as after sensor handling (the θ they tracked was
        measured from the wrong "up"); a walking bout's steps become the walk in progress.
        """
        old = self._frame.rot
        found = self._frame.find_reference(t, ax, ay, az, gyro)
        if found is None or found[0] == "quiet":
            return
        if old is not None:
            rows = self._sit_stand.history.data
            change = np.array(self._frame.rot).reshape(3, 3) @ np.linalg.inv(np.array(old).reshape(3, 3))
            rows[:, 1:] = rows[:, 1:] @ change.T
            self._hold_during_handling(t, 0.0)
        self._walking.adopt(found[1])

    def _hold_during_handling(self, t: float, theta: float) -> None:
        """The sensor is being put on or adjusted (still.py ``Handling``): keep the last posture, detect
        nothing. The walking, excursion, lying, level and lean detectors are cleared; the posture and
        the 60 s walk deadline of a sit→stand are kept."""
        self._walking.pause()
        self._sit_stand.reset(t, theta)
        self._posture.forget_evidence()
        self._lying.reset()
        self._lean.hold = 0.0
        self._level.reset(t)
        # on resume, a θ beyond 70° is a fresh crossing into lying (or out of it)
        self._frame.theta_prev = LYING_THRESHOLD_RAD + 0.01 if self._posture.posture == "lying" else 0.0

    # ---------------------------------------------------------------- output
    def flush(self) -> list[ActivityState]:
        """States of the samples still in the delay line (end of a recording)."""
        return [self._state(rec) for rec in self._line.drain()]

    def _emit(self, t: float, posture: str, walking: bool, theta: float, stamp_ns: int, calibrated: bool
              ) -> ActivityState | None:
        rec = self._line.push(t, posture, walking, theta, stamp_ns, calibrated)
        return None if rec is None else self._state(rec)

    def _state(self, rec: list) -> ActivityState:
        return self._line.state(rec, self._walking.steps, self._posture.transitions, self._modality.label)


def classify_activity(acc: np.ndarray, rate_hz: float, *, units: str = "m/s2",
                      reference: slice | tuple[int, int] | str = "auto", reference_s: float = 2.0,
                      align: bool = True, forward_axis: np.ndarray | None = None,
                      thigh_length_m: float = DEFAULT_THIGH_LENGTH_M, initial_posture: str = "auto",
                      placement: str = "chest", thighs: Mapping[str, np.ndarray] | None = None,
                      gyro: np.ndarray | None = None) -> dict:
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
    monitor = ActivityMonitor(rate_hz, units=units, reference_acc=reference_acc, reference=mode,
                              reference_s=reference_s, align=align, forward_axis=forward_axis,
                              thigh_length_m=thigh_length_m, initial_posture=initial_posture,
                              placement=placement)
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
