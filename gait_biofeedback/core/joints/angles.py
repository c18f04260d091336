"""Joint angles from segment orientations: the joint coordinate system (JCS) convention.

gait.md §1.8 (thesis §3.3 and Ch. 8 step 4 cite Grood & Suntay 1983 / ISB; the sequence and signs are a
READING, EXT: Wu et al. 2002). Segment anatomical frames: x anterior, y superior/proximal, z right-lateral on
BOTH legs (foot: y vertical in standing, x toward the toes, so a standing foot has the shank's frame).

Relative rotation ``q_rel = conj(q_proximal) ⊗ q_distal`` (segment→world orientations; hip: pelvis→thigh,
knee: thigh→shank, ankle: shank→foot) is decomposed as the Cardan sequence Z-X'-Y''
``R_rel = R_z(a) R_x(b) R_y(c)`` with ``b = asin(R32)``, ``a = atan2(-R12, R22)``, ``c = atan2(-R31, R33)``
(e1 = proximal z, e2 floating, e3 = distal y). Clinical signs (READING, chosen here and tested):

* flexion: ``a`` for hip flexion and ankle dorsiflexion, ``-a`` for knee flexion (a positive rotation about
  +z is knee *extension*);
* adduction (hip/knee adduction = varus, ankle inversion): ``b`` on the right, ``-b`` on the left;
* internal rotation (toes/anterior face turned medially): ``c`` on the right, ``-c`` on the left.

So adduction, inversion and internal rotation are positive on both sides: the left side's AA and IE are
mirrored because its z axis points laterally-right = medially. Gimbal lock at |b| = 90° (not met in gait).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

import numpy as np

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.segments import SIDES

JOINTS: tuple[str, ...] = ("hip", "knee", "ankle")
_ANGLE_KINDS: dict[str, tuple[str, str, str]] = {
    "hip": ("flexion", "adduction", "internal_rotation"),
    "knee": ("flexion", "adduction", "internal_rotation"),
    "ankle": ("dorsiflexion", "inversion", "internal_rotation"),
}
JOINT_NAMES: tuple[str, ...] = tuple(
    f"{side}_{joint}_{kind}" for side in SIDES for joint in JOINTS for kind in _ANGLE_KINDS[joint]
)
# (proximal, distal) segment of each joint; segment names as in segments.SEGMENTS
JOINT_SEGMENTS: dict[str, tuple[str, str]] = {
    "hip": ("pelvis", "thigh"),
    "knee": ("thigh", "shank"),
    "ankle": ("shank", "foot"),
}

_X = np.array([1.0, 0.0, 0.0])
_Y = np.array([0.0, 1.0, 0.0])
_Z = np.array([0.0, 0.0, 1.0])


def joint_angle_names(side: str, joint: str) -> tuple[str, str, str]:
    """JointState names (flexion, adduction, internal rotation) of one joint of one side."""
    _check(joint, side)
    return tuple(f"{side}_{joint}_{kind}" for kind in _ANGLE_KINDS[joint])  # type: ignore[return-value]


def segment_pair(side: str, joint: str) -> tuple[str, str]:
    """(proximal, distal) segment names of ``joint`` on ``side``, e.g. ('pelvis', 'left_thigh')."""
    _check(joint, side)
    prox, dist = JOINT_SEGMENTS[joint]
    return (prox if prox == "pelvis" else f"{side}_{prox}", f"{side}_{dist}")


def angle_signs(joint: str, side: str) -> tuple[float, float, float]:
    """Signs (flexion, adduction, internal rotation) taking the clinical angles of ``joint`` on ``side``
    to the Cardan angles (a, b, c) of ``R_z(a) R_x(b) R_y(c)`` (module docstring)."""
    return _signs(joint, side)


def _signs(joint: str, side: str) -> tuple[float, float, float]:
    _check(joint, side)
    s_fe = -1.0 if joint == "knee" else 1.0
    s_mirror = 1.0 if side == "right" else -1.0
    return s_fe, s_mirror, s_mirror


def _check(joint: str, side: str) -> None:
    if joint not in JOINTS:
        raise ValueError(f"unknown joint {joint!r}; expected one of {JOINTS}")
    if side not in SIDES:
        raise ValueError(f"unknown side {side!r}; expected one of {SIDES}")


def relative_rotation_from_angles(
    joint: str,
    side: str,
    flexion: np.ndarray | float,
    adduction: np.ndarray | float,
    internal_rotation: np.ndarray | float,
) -> np.ndarray:
    """``q_rel = conj(q_prox) ⊗ q_dist`` (..., 4) of clinical joint angles (rad), ``R_z(a) R_x(b) R_y(c)``."""
    s_fe, s_aa, s_ie = _signs(joint, side)
    a = s_fe * np.asarray(flexion, dtype=float)
    b = s_aa * np.asarray(adduction, dtype=float)
    c = s_ie * np.asarray(internal_rotation, dtype=float)
    a, b, c = np.broadcast_arrays(a, b, c)
    return quat.multiply(
        quat.multiply(quat.from_axis_angle(_Z, a), quat.from_axis_angle(_X, b)), quat.from_axis_angle(_Y, c)
    )


def angles_from_relative_rotation(
    joint: str, side: str, q_rel: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Clinical (flexion, adduction, internal_rotation) in rad of ``q_rel`` (..., 4), gait.md §1.8."""
    s_fe, s_aa, s_ie = _signs(joint, side)
    if quat._single(q_rel):  # one instant, as the stream asks: the same formulas on floats
        (_, m01, _), (_, m11, _), (m20, m21, m22) = quat.as_matrix(q_rel).tolist()
        return (s_fe * math.atan2(-m01, m11), s_aa * math.asin(min(max(m21, -1.0), 1.0)),
                s_ie * math.atan2(-m20, m22))
    m = quat.as_matrix(q_rel)
    b = np.arcsin(np.clip(m[..., 2, 1], -1.0, 1.0))
    a = np.arctan2(-m[..., 0, 1], m[..., 1, 1])
    c = np.arctan2(-m[..., 2, 0], m[..., 2, 2])
    return s_fe * a, s_aa * b, s_ie * c


def joint_angles_from_segments(orientations: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """All ``JOINT_NAMES`` angles (rad) from segment→world orientations keyed by segment name.

    Joints whose proximal or distal segment is missing are skipped.
    """
    out: dict[str, np.ndarray] = {}
    for side in SIDES:
        for joint in JOINTS:
            prox, dist = segment_pair(side, joint)
            if prox not in orientations or dist not in orientations:
                continue
            q_rel = quat.multiply(quat.conjugate(orientations[prox]), orientations[dist])
            for name, value in zip(
                joint_angle_names(side, joint), angles_from_relative_rotation(joint, side, q_rel), strict=True
            ):
                out[name] = value
    return out


# ----------------------------------------------------------------------------------------------------
# Calibrated joint angles (issue 4): sensor orientations + sensor-to-segment calibration → JOINT_NAMES


def _rotations_of(calibration: Any) -> dict[str, np.ndarray]:
    if hasattr(calibration, "rotations"):
        return calibration.rotations()
    return {s: np.asarray(r, dtype=float) for s, r in dict(calibration).items()}


def segment_orientations(segment_quats: dict[str, np.ndarray], calibration: Any) -> dict[str, np.ndarray]:
    """Segment→world ``q_segment = q_sensor ⊗ r`` (thesis Eq 17) of the calibrated segments present."""
    rotations = _rotations_of(calibration)
    return {s: quat.multiply(np.asarray(q, dtype=float), rotations[s])
            for s, q in segment_quats.items() if s in rotations}


def align_headings(segment_quats: dict[str, np.ndarray], calibration: Any,
                   standing: slice | np.ndarray) -> dict[str, np.ndarray]:
    """Sensor→world orientations re-expressed in one common world heading (batch, EXT/READING).

    Joint angles need the proximal and distal orientations in one world frame, heading included
    (gait.md §1.6). 6D filters (no magnetometer) and the qmt vendor quaternions give each sensor its own
    heading (qmt: the calibrated anatomical x axes of one leg's thigh, shank and foot point to world
    headings up to 150° apart in quiet standing). Assumption: in quiet standing every calibrated
    segment faces forward, so each sensor's world frame is rotated about the vertical by ``-ψ`` with ψ
    the world heading of its anatomical x averaged over ``standing`` (samples): all anatomical x axes
    then point along world +x at standing. Toe-out and similar standing offsets are absorbed, as by
    the standing offset removal of gait.md §1.9. Heading drift after the standing is not corrected,
    so use the standing right before the movement. Segments without a calibration are left out.
    """
    from gait_biofeedback.core.calibration.sensor_to_segment import mean_orientation

    rotations = _rotations_of(calibration)
    out: dict[str, np.ndarray] = {}
    for seg, q in segment_quats.items():
        if seg not in rotations:
            continue
        q = np.asarray(q, dtype=float)
        x_world = quat.rotate(mean_orientation(q[standing]), quat.rotate(rotations[seg], _X))
        psi = float(np.arctan2(x_world[1], x_world[0]))
        out[seg] = quat.multiply(quat.from_axis_angle(_Z, -psi), q)
    return out


def compute_joint_angles(
    segment_quats: dict[str, np.ndarray],
    calibration: Any,
    standing: slice | None = None,
) -> dict[str, np.ndarray]:
    """Batch: clinical JCS angles (rad, (N,)) of every joint whose two segments are calibrated.

    ``segment_quats``: segment → (N, 4) sensor→world; ``calibration``: a
    :class:`~gait_biofeedback.core.calibration.sensor_to_segment.SessionCalibration` (its valid
    segments) or segment → r.
    ``standing``: samples of quiet standing; READING gait.md §1.9: each angle's mean over it is
    subtracted (thesis ch. 8 step 4), so standing reads 0.
    """
    angles = joint_angles_from_segments(segment_orientations(segment_quats, calibration))
    if standing is not None:
        angles = {k: v - float(np.mean(v[standing])) for k, v in angles.items()}
    return angles


class JointAngleCalculator:
    """Streaming form of :func:`compute_joint_angles` (same code, one sample at a time).

    Standing offset: :meth:`collect_offset` starts a collection of ``duration_s`` of still samples
    (``update(..., still=False)`` restarts it); when a sample stamped at or past ``first + duration_s``
    arrives, the mean of the collected angles becomes the offset (that sample and later ones are
    corrected; earlier ones were published uncorrected). An angle that first appears after that (its
    joint was left out until its heading was known) starts a new collection of the same length; it
    adds the offsets of the angles that had none and keeps the others.
    """

    def __init__(self, calibration: Any) -> None:
        self.rotations = _rotations_of(calibration)
        self._floats = {s: np.asarray(r, dtype=float).tolist() for s, r in self.rotations.items()}
        self.offset: dict[str, float] = {}
        self._duration: float | None = None  # of the collection asked for; None = no offset removal
        self._collect_s: float | None = None
        self._first: float | None = None
        self._sums: dict[str, float] = {}
        self._counts: dict[str, int] = {}

    def collect_offset(self, duration_s: float) -> None:
        """Start (or restart) the standing-offset collection."""
        self._duration = self._collect_s = float(duration_s)
        self._first, self._sums, self._counts = None, {}, {}

    @property
    def offset_pending(self) -> bool:
        return self._collect_s is not None

    def raw(self, segment_quats: dict[str, np.ndarray]) -> dict[str, float]:
        """Angles without offset removal of one instant (segment → (4,) sensor→world):
        :func:`compute_joint_angles` of one sample, by the joint stage's kernel
        (:func:`._heading_kernel.segment_angles`: the same operations in the same order, the same
        numbers; test/test_joint_angles.py)."""
        from gait_biofeedback.core.joints import _heading_kernel as hk
        from gait_biofeedback.core.joints.relative_heading import _kernels

        q, rot = np.zeros((len(JOINT_SLOTS), 4)), np.zeros((len(JOINT_SLOTS), 4))
        flags = np.zeros(len(JOINT_SLOTS), dtype=np.int64)
        for k, seg in enumerate(JOINT_SLOTS):
            if seg in segment_quats and seg in self._floats:
                q[k], rot[k], flags[k] = segment_quats[seg], self._floats[seg], hk.PRESENT | hk.CALIBRATED
        out = np.zeros(3 * len(_JOINT_TABLE))
        return self.named(_kernels().segment_angles(JOINT_TABLE, q, flags, rot, out), out.tolist())

    @staticmethod
    def named(done: int, values: list[float]) -> dict[str, float]:
        """Angle name → value of the joints whose bit (``1 << j``, :data:`JOINT_TABLE` row j) is set in
        ``done``; ``values`` three a joint."""
        return {name: values[3 * j + m] for j, (_, _, names, _) in enumerate(_JOINT_TABLE) if done >> j & 1
                for m, name in enumerate(names)}

    def update(self, stamp_ns: int, segment_quats: dict[str, np.ndarray],
               still: bool = True, leave_out: Iterable[str] = ()) -> dict[str, float]:
        """Angles (rad) of the joints whose segments are present and calibrated, offset removed.
        ``leave_out``: angle names neither returned nor collected into the standing offset (a joint
        whose segments are not yet in one world heading: an offset from them would be wrong later)."""
        skip = set(leave_out)
        return self.correct(stamp_ns, {k: v for k, v in self.raw(segment_quats).items() if k not in skip},
                            still)

    def correct(self, stamp_ns: int, angles: dict[str, float], still: bool = True) -> dict[str, float]:
        """``angles`` (raw, rad) with the standing offset removed, collecting it while ``still`` (class
        docstring, gait.md §1.9)."""
        stamp = stamp_ns * 1e-9
        if self._collect_s is None and self._duration is not None and not angles.keys() <= self.offset.keys():
            self._collect_s = self._duration
            self._first, self._sums, self._counts = None, {}, {}
        if self._collect_s is not None:
            if not still:
                self._first, self._sums, self._counts = None, {}, {}
            elif self._first is not None and stamp >= self._first + self._collect_s - 1e-9:
                self.offset = {**{k: self._sums[k] / self._counts[k] for k in self._sums}, **self.offset}
                self._collect_s = None
            else:
                self._first = stamp if self._first is None else self._first
                for k, v in angles.items():
                    self._sums[k] = self._sums.get(k, 0.0) + v
                    self._counts[k] = self._counts.get(k, 0) + 1
        return {k: v - self.offset.get(k, 0.0) for k, v in angles.items()}


_JOINT_TABLE = tuple((*segment_pair(side, joint), joint_angle_names(side, joint), _signs(joint, side))
                     for side in SIDES for joint in JOINTS)
"""(proximal, distal, angle names, signs) of every joint, in :data:`JOINT_NAMES` order."""

JOINT_SLOTS: tuple[str, ...] = ("pelvis", "left_thigh", "left_shank", "left_foot", "right_thigh",
                                "right_shank", "right_foot")
"""The segments of the joints, in the kernel's slot order (the joint-angle stream's segments)."""

JOINT_TABLE = np.array([(JOINT_SLOTS.index(prox), JOINT_SLOTS.index(dist), *signs)
                        for prox, dist, _, signs in _JOINT_TABLE], dtype=float)
"""The kernel's joint table: a row per :data:`_JOINT_TABLE` joint, (proximal slot, distal slot, signs)."""
