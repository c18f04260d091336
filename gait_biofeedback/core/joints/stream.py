"""The live joint-angle stream, shared by the ``joint_angles`` node and the offline analysis.

Segment samples are synchronised by their exact stamps (int ns: the IMUs are sampled together), each
joint's two sensors are put in one world heading by its
:class:`~gait_biofeedback.core.joints.relative_heading.RelativeHeadingEstimator` (issue 14), then
turned into clinical joint angles by :class:`~gait_biofeedback.core.joints.angles.JointAngleCalculator`
(thesis Eq 17, ISB JCS of gait.md §1.8, standing offset of §1.9). The stage's parameters are
:class:`JointAnglesParams`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.body import StickFigureDimensions
from gait_biofeedback.core.in_force import InForceQueue
from gait_biofeedback.core.joints import _heading_kernel as hk
from gait_biofeedback.core.joints.alignment import StampAlignment
from gait_biofeedback.core.joints.angles import (
    JOINT_SLOTS,
    JOINT_TABLE,
    JOINTS,
    JointAngleCalculator,
    segment_pair,
)
from gait_biofeedback.core.joints.axis_heading import AxisHeadingEstimator
from gait_biofeedback.core.joints.relative_heading import (
    POSITION_WINDOW_S,
    TIME_CONSTANT_S,
    HeadingBank,
    RelativeHeadingEstimator,
    _kernels,
)
from gait_biofeedback.core.params import param
from gait_biofeedback.core.segments import SIDES

HEADING_SOURCES: tuple[str, ...] = ("kinematic", "filters")
HIP_HEADING_SOURCES: tuple[str, ...] = ("segment_axes", "joint_centre")


@dataclass(frozen=True)
class JointAnglesParams(StickFigureDimensions):
    """Parameters of the joint-angle stage (node ``joint_angles``, and ``analyze``); the body
    dimensions draw the ``skeleton``."""

    max_wait_s: float = param(0.1, "longest wait for a stamp's missing segments before it is published "
                              "without them (live only)", "s", low=0.0, high=5.0)
    remove_standing_offset: bool = param(True, "subtract the mean angles of the first still standing after "
                                         "each calibration (gait.md §1.9)")
    offset_window_s: float = param(2.0, "still standing averaged for the standing offset", "s",
                                   low=0.1, high=30.0)
    still_gyro: float = param(0.2, "every segment below this angular rate counts as still", "rad/s",
                              low=0.01, high=5.0)
    skeleton_every: int = param(5, "publish the skeleton markers every this many samples (0 = never)",
                                "samples", low=0, high=10000)
    diagnostics_period_s: float = param(1.0, "period of the /diagnostics status", "s", low=0.1, high=60.0)
    heading: str = param("kinematic", "common heading of a joint's two sensors: 'kinematic' = from the "
                         "joint's own accelerations (6D sensors or a disturbed magnetometer), 'filters' = "
                         "trust the filters' shared magnetometer heading", choices=HEADING_SOURCES)
    heading_time_constant_s: float = param(TIME_CONSTANT_S, "averaging time of the kinematic heading (it "
                                           "follows the filters' heading drift this fast)", "s", low=0.5,
                                           high=120.0)
    heading_position_window_s: float = param(POSITION_WINDOW_S, "motion collected before a joint's centre is "
                                             "estimated (its angles are published once the heading is "
                                             "established)", "s", low=2.0, high=120.0)
    hip_heading: str = param("segment_axes", "kinematic heading of the hips: 'segment_axes' = the pelvis' "
                             "and thigh's calibrated medio-lateral axes agree on average (robust on real "
                             "sensors; the hip's slow internal rotation is held at its standing value), "
                             "'joint_centre' = the hip centre's acceleration seen by both sensors",
                             choices=HIP_HEADING_SOURCES)
    standing_max_tilt_rad: float = param(0.52, "a still instant counts as standing for the standing offset "
                                         "only when every calibrated thigh and shank is within this of "
                                         "vertical",
                                         "rad", low=0.05, high=1.5)


STREAM_SEGMENTS: tuple[str, ...] = JOINT_SLOTS
"""Segments the joint-angle stream synchronises (the chest takes no part in a joint)."""


@dataclass(frozen=True)
class SyncedAngles:
    """One emitted instant: stamp (ns), the angles (rad, offset removed; empty when no joint had both
    segments), the sensor→world orientations present, the calibration rotations in force, and the
    segments whose orientation was being re-acquired after a dropout (its angles are doubtful)."""

    ns: int
    angles: dict[str, float]
    sensor_quats: dict[str, np.ndarray]
    rotations: dict[str, np.ndarray]
    recovering: tuple[str, ...] = ()
    no_heading: tuple[str, ...] = ()
    """Joints (e.g. 'left_knee') left out because their kinematic heading is not established yet."""


class JointAngleStream:
    """Synchronise segment samples by exact stamp, then :class:`JointAngleCalculator` (one per calibration).

    Sync: a stamp is emitted when every calibrated segment has it, when a newer stamp is complete, or
    (only with a clock, :meth:`flush` ``now``) ``max_wait_s`` s after its first sample arrived; the
    missing segments are counted in :attr:`missing_counts`. Stamps are emitted in order.
    Calibrations: :meth:`set_calibration` with ``from_ns`` > 0 takes effect at the first emitted stamp
    ``>= from_ns`` (every consumer of a calibration then switches at the same sample, whenever the
    calibration message arrived); ``from_ns = 0`` takes effect at once and drops the pending stamps.
    Samples are ignored while no calibration is in force or waiting. Each calibration starts a new
    calculator and, with ``remove_standing_offset``, a new standing-offset collection of
    ``offset_window_s`` s of still samples (every segment present with |ω| < ``still_gyro`` rad/s).
    A sample marked ``recovering`` (its orientation re-acquired after a dropout, or its segment's stamps
    off the others': :attr:`alignment`) names its segment in the instant's
    :attr:`SyncedAngles.recovering` and never counts as still.
    Heading (``heading`` = 'kinematic'): every synchronised instant, calibrated or not, updates each
    joint's heading estimator (recovering samples are left out); the sensor orientations are then turned
    about the vertical down each leg's chain (pelvis, thigh, shank, foot) into the pelvis sensor's world
    (:attr:`SyncedAngles.sensor_quats`), and a joint whose heading is not established is left out
    (:attr:`SyncedAngles.no_heading`), from the standing offset too: a joint established only after
    the offset was taken has none. Before a calibration, an instant waits for the segments seen in the
    last second.
    """

    def __init__(self, params: JointAnglesParams | None = None,
                 segments: tuple[str, ...] = STREAM_SEGMENTS) -> None:
        p = params or JointAnglesParams()
        self.params = p
        self.segments = tuple(segments)
        self.max_wait_s = p.max_wait_s
        self.remove_offset = p.remove_standing_offset
        self.offset_window_s = p.offset_window_s
        self.still_gyro = p.still_gyro
        self.calculator: JointAngleCalculator | None = None
        self._waiting: InForceQueue[JointAngleCalculator] = InForceQueue()
        self.pending: dict[int, _Instant] = {}
        self._seen: dict[str, int] = {}
        self._magnetic: dict[str, bool] = {}  # segment → its newest sample's heading is magnetic
        self.headings: dict[str, RelativeHeadingEstimator] = {
            f"{side}_{joint}": self._heading_estimator(joint)
            for side in SIDES for joint in JOINTS} if p.heading == "kinematic" else {}
        self._axes_of: JointAngleCalculator | None = None  # the calculator whose axes the hips have
        self.first_arrival: dict[int, float] = {}
        self.missing_counts: dict[str, int] = {s: 0 for s in self.segments}
        self.recovering_count = 0  # emitted instants with a recovering segment
        self.alignment = StampAlignment()
        if not set(self.segments) <= set(JOINT_SLOTS):
            raise ValueError(f"the joint-angle stream takes segments of {JOINT_SLOTS}, not {self.segments}")
        self._k = _kernels()
        self._slot = {seg: k for k, seg in enumerate(JOINT_SLOTS)}
        self._joint_names = tuple(f"{side}_{joint}" for side in SIDES for joint in JOINTS)
        self._bank = (HeadingBank([self.headings[name] for name in self._joint_names]) if self.headings
                      else None)
        self._rot = np.zeros((len(JOINT_SLOTS), 4))
        self._flags = np.zeros(len(JOINT_SLOTS), dtype=np.int64)
        self._limb = [hk.LIMB if seg.endswith(("_thigh", "_shank")) else 0 for seg in JOINT_SLOTS]
        self._out_q = np.zeros((len(JOINT_SLOTS), 4))
        self._out_angles = np.zeros(3 * len(JOINT_TABLE))
        self._codes = np.zeros(len(JOINT_TABLE), dtype=np.int64)
        self._least = math.cos(p.standing_max_tilt_rad)

    def _heading_estimator(self, joint: str) -> RelativeHeadingEstimator:
        p = self.params
        if joint == "hip" and p.hip_heading == "segment_axes":
            return AxisHeadingEstimator(p.heading_time_constant_s)
        return RelativeHeadingEstimator(p.heading_time_constant_s,
                                        position_window_s=p.heading_position_window_s)

    def _give_axes(self, rotations: dict[str, np.ndarray]) -> None:
        """The calibrated medio-lateral axes (sensor coordinates) to the hips' axis estimators."""
        for name, estimator in self.headings.items():
            if isinstance(estimator, AxisHeadingEstimator):
                side, joint = name.split("_", 1)
                estimator.set_axes(*(tuple(quat.rotate(rotations[s], _Z)) if s in rotations else None
                                     for s in segment_pair(side, joint)))

    def _new_calculator(self, rotations: dict[str, np.ndarray]) -> JointAngleCalculator:
        calculator = JointAngleCalculator(rotations)
        if self.remove_offset:
            calculator.collect_offset(self.offset_window_s)
        return calculator

    def set_calibration(self, rotations: dict[str, np.ndarray], from_ns: int = 0) -> None:
        """A new calibration (segment → r, valid segments only), in force from stamp ``from_ns``."""
        calculator = self._new_calculator(rotations)
        if from_ns <= 0:
            self.calculator = calculator
            self._waiting.clear()
            self.pending.clear()
            self.first_arrival.clear()
            return
        self._waiting.put(int(from_ns), calculator)

    @property
    def active(self) -> bool:
        """A calibration is in force or waiting for its first stamp."""
        return self.calculator is not None or bool(self._waiting)

    def _wanted(self, ns: int) -> list[str]:
        calculator = self.calculator or self._waiting.first()
        if calculator is None:
            return [s for s, seen in self._seen.items() if ns - seen < 1_000_000_000]
        return [s for s in self.segments if s in calculator.rotations]

    def add(self, segment: str, ns: int, q: np.ndarray, gyr: tuple, acc: tuple,
            arrival: float | None = None, recovering: bool = False,
            magnetic: bool = False, received_ns: int | None = None) -> list[SyncedAngles]:
        """One sample (sensor→world q, bias-corrected rate rad/s, specific force m/s²) of ``segment`` at
        stamp ``ns``; the instants ready now. ``magnetic``: its heading came from a magnetometer (the
        joint headings then follow that filter's heading corrections at once). ``received_ns``: when it
        was received (default: ``arrival``; offline, its log time): a segment whose stamps leave the
        other segments' is marked as recovering (:mod:`.alignment`)."""
        if segment not in self.segments or not (self.active or self.headings):
            return []
        if received_ns is None and arrival is not None:
            received_ns = round(arrival * 1e9)
        if received_ns is not None and not recovering and self.alignment.add(segment, ns, received_ns):
            recovering = True
        self._seen[segment] = max(ns, self._seen.get(segment, ns))
        self._magnetic[segment] = bool(magnetic)
        instant = self.pending.get(ns)
        if instant is None:
            instant = self.pending[ns] = _Instant()
        instant[segment] = bool(recovering)
        instant.values[self._slot[segment]] = (*q, *gyr, *acc)
        self.first_arrival.setdefault(ns, arrival if arrival is not None else math.inf)
        return self.flush(arrival)

    def flush(self, now: float | None = None, force: bool = False) -> list[SyncedAngles]:
        """Emit the stamps that are complete, older than a complete one, waited ``max_wait_s`` s by
        ``now`` (same clock as the arrivals), or all of them with ``force`` (end of a recording)."""
        if not self.pending:
            return []
        stamps = sorted(self.pending)
        wanted = self._wanted(stamps[-1])
        pending, n_wanted = self.pending, len(wanted)
        complete = [ns for ns in stamps
                    if len(pending[ns]) >= n_wanted and all(s in pending[ns] for s in wanted)]
        newest_complete = complete[-1] if complete else None
        out = []
        for ns in stamps:
            done = force or ns in complete or (newest_complete is not None and ns < newest_complete)
            timed_out = now is not None and now - self.first_arrival[ns] > self.max_wait_s
            if not (done or timed_out):
                break
            emitted = self._emit(ns, self.pending.pop(ns), wanted)
            self.first_arrival.pop(ns, None)
            if emitted is not None:
                out.append(emitted)
        return out

    def _emit(self, ns: int, samples: _Instant, wanted: list[str]) -> SyncedAngles | None:
        """One instant: the calibration due, then one kernel call (:func:`._heading_kernel.instant`: the
        joints' headings stepped, the chain turned, the angles decomposed, whether it is still)."""
        for calculator in self._waiting.due(ns):
            self.calculator = calculator
        calculator = self.calculator
        if calculator is not self._axes_of and calculator is not None:
            self._axes_of = calculator
            self._give_axes(calculator.rotations)
            self._rot[:] = 0.0
            for k, seg in enumerate(JOINT_SLOTS):
                if seg in calculator.rotations:
                    self._rot[k] = calculator.rotations[seg]
        if calculator is None and self._bank is None:
            return None
        flags = self._flags
        calibrated = calculator.rotations if calculator is not None else {}
        for k, seg in enumerate(JOINT_SLOTS):
            if seg in samples:
                flags[k] = (_PRESENT | (hk.RECOVERING if samples[seg] else 0)
                            | (hk.MAGNETIC if self._magnetic.get(seg, False) else 0)
                            | (hk.CALIBRATED if seg in calibrated else 0) | self._limb[k])
            else:
                flags[k] = 0
        values = samples.values.tolist() if self._bank is not None and self._bank.plain else samples.values
        result = self._instant(ns, values, True)
        if result & hk.ROWS_PENDING:
            result = self._instant(ns, values, False)
        if calculator is None:
            return None
        for seg in wanted:
            if seg not in samples:
                self.missing_counts[seg] += 1
        out_q = self._out_q.copy()
        quats = {s: out_q[self._slot[s]] for s in samples}
        recovering = tuple(s for s, r in samples.items() if r)
        self.recovering_count += bool(recovering)
        still = not recovering and len(samples) == len(wanted) and bool(result & hk.QUIET)
        no_heading = tuple(name for j, name in enumerate(self._joint_names) if result >> j & 1)
        usable = (result >> hk.ANGLES_AT) & ~result
        angles = calculator.correct(ns, calculator.named(usable, self._out_angles.tolist()), still)
        return SyncedAngles(ns, angles, quats, calculator.rotations, recovering, no_heading)

    def _instant(self, ns: int, values: np.ndarray | list, steps: bool) -> int:
        """The kernel on this instant's samples (a ring grown when full); the estimators' results taken."""
        while True:
            bank = self._bank or _NO_HEADINGS
            result = self._k.instant(bank.f, bank.i, bank.ring, bank.p, bank.row, bank.kind, JOINT_TABLE,
                                     values, self._flags, self._rot, self._out_q, self._out_angles,
                                     self._codes, steps, ns, self.still_gyro, self._least)
            if result != hk.NEED_ROOM:
                break
            bank.grow()
        if steps and self._bank is not None and self._codes.any():
            for estimator, code in zip(self._bank.estimators, self._codes.tolist(), strict=True):
                if code:
                    estimator._took(code)
        return result

    def heading_status(self) -> tuple[list[str], dict[str, str]]:
        """(joints of the calibration in force whose two sensors have no common heading yet, so that
        their angles are not published; per joint: its estimator's state and δ in degrees), for
        /diagnostics."""
        rotations = self.calculator.rotations if self.calculator is not None else {}
        waiting, values = [], {}
        for name, estimator in self.headings.items():
            if not all(s in rotations for s in segment_pair(*name.split("_", 1))):
                continue
            values[f"{name}_heading"] = (f"{estimator.state}, δ {math.degrees(estimator.delta):.1f}°"
                                         if estimator.established else estimator.state)
            if not estimator.established:
                waiting.append(name)
        return waiting, values


class _Instant(dict):
    """The samples of one stamp: segment → recovering, their values (q, ω, a) in ``values``, one slot a
    row (:data:`~gait_biofeedback.core.joints.angles.JOINT_SLOTS`)."""

    def __init__(self) -> None:
        super().__init__()
        self.values = np.zeros((len(JOINT_SLOTS), hk.SAMPLE_WIDTH))


_PRESENT = hk.PRESENT
_NO_HEADINGS = SimpleNamespace(  # heading 'filters': no estimators, state arrays the kernel never reads
    f=np.zeros((len(JOINT_TABLE), hk.N_FLOAT)), i=np.zeros((len(JOINT_TABLE), hk.N_INT), dtype=np.int64),
    ring=np.zeros((len(JOINT_TABLE), hk.RING_WIDTH)), p=np.zeros((len(JOINT_TABLE), hk.N_PARAM)),
    row=np.zeros((len(JOINT_TABLE), hk.ROW_WIDTH)), kind=np.full(len(JOINT_TABLE), -1, dtype=np.int64))
_Z = np.array([0.0, 0.0, 1.0])
