"""The body's segments as a tree of frame transforms (``/tf``, the Foxglove live view).

Each segment's anatomical frame (ISB axes, :mod:`gait_biofeedback.core.segments`) is a child of the
segment it hangs from: ``world → pelvis → {chest, <side>_thigh → <side>_shank → <side>_foot}``. A
child's rotation in its parent is the joint's relative rotation ``q_rel = conj(q_proximal) ⊗
q_distal`` rebuilt from the published clinical angles
(:func:`~gait_biofeedback.core.joints.angles.relative_rotation_from_angles`, the inverse of the
decomposition of gait.md §1.8), its translation the fixed joint offset of the rigid-link model of
:mod:`gait_biofeedback.core.joints.skeleton` (hip centres at ±``hip_width_m``/2 along the pelvis z,
knee at (0, −thigh, 0) in the thigh, ankle at (0, −shank, 0) in the shank). So the legs drawn are
exactly the angles the clinician sees (standing offset removed: quiet standing draws straight legs).

The pelvis is ``q_pelvis = q_sensor ⊗ r`` (thesis Eq 17) in ``world`` at the origin's vertical,
lifted so that the lowest sole point (heel = ankle + R_foot (0, −ankle_height, 0), toe = ankle +
R_foot (foot_length, −ankle_height, 0)) of the feet drawn touches z = 0 (ENU, z up): the pelvis rises
and falls with the legs. Without a whole leg it stands at the standing hip height. The chest is
``conj(q_pelvis) ⊗ q_chest`` at the pelvis origin (its own filter's heading: with 6D filters it can
turn about the vertical relative to the pelvis as that heading drifts).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.body import BodyDimensions
from gait_biofeedback.core.joints.angles import (
    JOINT_NAMES,
    angle_signs,
    joint_angle_names,
    relative_rotation_from_angles,
)
from gait_biofeedback.core.segments import SIDES, WORLD_FRAME

BODY_FRAMES: tuple[tuple[str, str], ...] = (
    ("pelvis", WORLD_FRAME),
    ("chest", "pelvis"),
    ("left_thigh", "pelvis"),
    ("left_shank", "left_thigh"),
    ("left_foot", "left_shank"),
    ("right_thigh", "pelvis"),
    ("right_shank", "right_thigh"),
    ("right_foot", "right_shank"),
)
"""(child frame, parent frame) of every segment, a parent before its children."""
FRAME_INDEX = {child: k for k, (child, _) in enumerate(BODY_FRAMES)}
_ANGLE_INDEX = {name: k for k, name in enumerate(JOINT_NAMES)}
_CHAIN = (("hip", "thigh"), ("knee", "shank"), ("ankle", "foot"))


def body_transforms(pelvis_q: np.ndarray, angles: np.ndarray, chest_q: np.ndarray | None = None,
                    body: BodyDimensions | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(translations (N, 8, 3) m, rotations (N, 8, 4) w, x, y, z, present (N, 8) bool) of the
    :data:`BODY_FRAMES` in their parents at N instants (module docstring).

    ``pelvis_q`` (N, 4): the pelvis segment→world orientation; ``angles`` (N, 18) rad in
    :data:`~gait_biofeedback.core.joints.angles.JOINT_NAMES` order, NaN where a joint has no angles
    (its distal segment and those below it are then absent); ``chest_q`` (N, 4) the chest
    segment→world orientation, NaN rows (or None) where there is none. A NaN pelvis: nothing present.
    """
    body = body or BodyDimensions()
    pelvis_q = np.atleast_2d(np.asarray(pelvis_q, dtype=float))
    angles = np.atleast_2d(np.asarray(angles, dtype=float))
    n = len(pelvis_q)
    if angles.shape != (n, len(JOINT_NAMES)):
        raise ValueError(f"angles has shape {angles.shape}, expected ({n}, {len(JOINT_NAMES)})")
    trans = np.zeros((n, len(BODY_FRAMES), 3))
    rot = np.zeros((n, len(BODY_FRAMES), 4))
    rot[..., 0] = 1.0
    present = np.zeros((n, len(BODY_FRAMES)), dtype=bool)
    has_pelvis = np.isfinite(pelvis_q).all(axis=1)
    pelvis = np.where(has_pelvis[:, None], pelvis_q, quat.IDENTITY)
    pelvis = pelvis / np.linalg.norm(pelvis, axis=1, keepdims=True)
    rot[:, 0], present[:, 0] = pelvis, has_pelvis
    if chest_q is not None:
        chest_q = np.atleast_2d(np.asarray(chest_q, dtype=float))
        has_chest = has_pelvis & np.isfinite(chest_q).all(axis=1)
        chest = np.where(has_chest[:, None], chest_q, quat.IDENTITY)
        k = FRAME_INDEX["chest"]
        chest = chest / np.linalg.norm(chest, axis=1, keepdims=True)
        rot[:, k] = quat.multiply(quat.conjugate(pelvis), chest)
        present[:, k] = has_chest
    lengths = {"thigh": body.thigh_length_m, "shank": body.shank_length_m}
    lowest = np.full(n, np.inf)  # the lowest sole point of the whole legs, pelvis origin at z = 0
    for side in SIDES:
        sign = 1.0 if side == "right" else -1.0
        offset = np.array([0.0, 0.0, sign * body.hip_width_m / 2])
        above, parent_q, point = has_pelvis, pelvis, quat.rotate(pelvis, offset)
        for joint, part in _CHAIN:
            k = FRAME_INDEX[f"{side}_{part}"]
            columns = [_ANGLE_INDEX[name] for name in joint_angle_names(side, joint)]
            values = angles[:, columns]
            here = above & np.isfinite(values).all(axis=1)
            values = np.where(here[:, None], values, 0.0)
            rel = relative_rotation_from_angles(joint, side, values[:, 0], values[:, 1], values[:, 2])
            trans[:, k] = offset
            rot[:, k], present[:, k] = rel, here
            parent_q = quat.multiply(parent_q, rel)
            if part in lengths:
                offset = np.array([0.0, -lengths[part], 0.0])
                point = point + quat.rotate(parent_q, offset)
            above = here
        for sole in ((0.0, -body.ankle_height_m, 0.0), (body.foot_length_m, -body.ankle_height_m, 0.0)):
            z = (point + quat.rotate(parent_q, np.array(sole)))[:, 2]
            lowest = np.where(above, np.minimum(lowest, z), lowest)
    standing = body.thigh_length_m + body.shank_length_m + body.ankle_height_m
    trans[:, 0, 2] = np.where(np.isfinite(lowest), -lowest, standing)
    return trans, rot, present


def angle_rows(angles: Sequence[dict[str, float]]) -> np.ndarray:
    """(N, 18) rad in :data:`JOINT_NAMES` order of N name → angle mappings, NaN where a name is absent."""
    out = np.full((len(angles), len(JOINT_NAMES)), np.nan)
    index = _ANGLE_INDEX
    for i, named in enumerate(angles):
        if len(named) == len(JOINT_NAMES) and tuple(named) == JOINT_NAMES:
            out[i] = tuple(named.values())
            continue
        for name, value in named.items():
            k = index.get(name)
            if k is not None:
                out[i, k] = value
    return out


def world_poses(trans: np.ndarray, rot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(positions (N, 8, 3), segment→world orientations (N, 8, 4)) of the frames of
    :func:`body_transforms`, composed down the tree (for drawing and checking)."""
    pos, q = np.zeros_like(trans), np.zeros_like(rot)
    for k, (_, parent) in enumerate(BODY_FRAMES):
        if parent == WORLD_FRAME:
            pos[:, k], q[:, k] = trans[:, k], rot[:, k]
            continue
        j = FRAME_INDEX[parent]
        pos[:, k] = pos[:, j] + quat.rotate(q[:, j], trans[:, k])
        q[:, k] = quat.multiply(q[:, j], rot[:, k])
    return pos, q


Vector = tuple[float, float, float]
Quaternion = tuple[float, float, float, float]


Frames = tuple[list[Vector], list[Quaternion], list[bool]]


def body_transforms_at(pelvis_q: Quaternion, angles: Mapping[str, float], chest_q: Quaternion | None = None,
                       body: BodyDimensions | None = None) -> Frames:
    """:func:`body_transforms` of one instant in plain floats (a live message at a time: ~40 µs, where
    the array form costs ~1 ms for one row): translations, rotations and present flags of the 8
    :data:`BODY_FRAMES`. ``angles``: name → rad (a name absent or NaN: no angles for its joint)."""
    body = body or BodyDimensions()
    trans: list[Vector] = [(0.0, 0.0, 0.0)] * len(BODY_FRAMES)
    rot: list[Quaternion] = [(1.0, 0.0, 0.0, 0.0)] * len(BODY_FRAMES)
    present = [False] * len(BODY_FRAMES)
    if not all(math.isfinite(v) for v in pelvis_q):
        return trans, rot, present
    norm = math.sqrt(sum(v * v for v in pelvis_q))
    pelvis = tuple(v / norm for v in pelvis_q)
    rot[0], present[0] = pelvis, True
    if chest_q is not None and all(math.isfinite(v) for v in chest_q):
        norm = math.sqrt(sum(v * v for v in chest_q))
        k = FRAME_INDEX["chest"]
        rot[k] = _mul(_conj(pelvis), tuple(v / norm for v in chest_q))
        present[k] = True
    lengths = {"thigh": body.thigh_length_m, "shank": body.shank_length_m}
    lowest = math.inf
    nan = math.nan
    for side, chain in _LEGS:
        offset = (0.0, 0.0, (1.0 if side == "right" else -1.0) * body.hip_width_m / 2)
        chain_q, point, whole = pelvis, _rotate(pelvis, offset), True
        for k, part, (flexion, adduction, rotation), (s_a, s_b, s_c) in chain:
            a, b, c = angles.get(flexion, nan), angles.get(adduction, nan), angles.get(rotation, nan)
            if not (math.isfinite(a) and math.isfinite(b) and math.isfinite(c)):
                whole = False
                break
            rel = _cardan_zxy(s_a * a, s_b * b, s_c * c)
            trans[k], rot[k], present[k] = offset, rel, True
            chain_q = _mul(chain_q, rel)
            if part in lengths:
                offset = (0.0, -lengths[part], 0.0)
                point = _add(point, _rotate(chain_q, offset))
        if whole:
            for sole in ((0.0, -body.ankle_height_m, 0.0), (body.foot_length_m, -body.ankle_height_m, 0.0)):
                lowest = min(lowest, point[2] + _rotate(chain_q, sole)[2])
    height = -lowest if math.isfinite(lowest) else (body.thigh_length_m + body.shank_length_m
                                                    + body.ankle_height_m)
    trans[0] = (0.0, 0.0, height)
    return trans, rot, present


_LEGS = tuple((side, tuple((FRAME_INDEX[f"{side}_{part}"], part, joint_angle_names(side, joint),
                            angle_signs(joint, side)) for joint, part in _CHAIN)) for side in SIDES)
"""Per side, per joint down the leg: (distal frame index, its part, angle names, signs)."""


def _cardan_zxy(a: float, b: float, c: float) -> Quaternion:
    """q of ``R_z(a) R_x(b) R_y(c)``."""
    qz = (math.cos(a / 2), 0.0, 0.0, math.sin(a / 2))
    qx = (math.cos(b / 2), math.sin(b / 2), 0.0, 0.0)
    qy = (math.cos(c / 2), 0.0, math.sin(c / 2), 0.0)
    return _mul(_mul(qz, qx), qy)


def _mul(p: Quaternion, q: Quaternion) -> Quaternion:
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return (pw * qw - px * qx - py * qy - pz * qz, pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx, pw * qz + px * qy - py * qx + pz * qw)


def _conj(q: Quaternion) -> Quaternion:
    return (q[0], -q[1], -q[2], -q[3])


def _rotate(q: Quaternion, v: Vector) -> Vector:
    w, x, y, z = q
    a, b, c = v
    tx, ty, tz = 2.0 * (y * c - z * b), 2.0 * (z * a - x * c), 2.0 * (x * b - y * a)
    return (a + w * tx + (y * tz - z * ty), b + w * ty + (z * tx - x * tz), c + w * tz + (x * ty - y * tx))


def _add(u: Vector, v: Vector) -> Vector:
    return (u[0] + v[0], u[1] + v[1], u[2] + v[2])
