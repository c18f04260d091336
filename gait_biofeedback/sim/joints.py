"""The simulator's own definition of the clinical joint angles (its truth), written apart from the code
it tests (:mod:`gait_biofeedback.core.joints.angles`) and computed with SciPy's rotations.

Definition (ISB joint coordinate system, Grood & Suntay 1983 / Wu et al. 2002; gait.md §1.8): the
distal segment's orientation relative to the proximal one, ``R_rel = R_prox^T R_dist`` (segment →
world rotations, anatomical axes x anterior, y superior, z right on both legs), is the intrinsic
rotation sequence z, x', y'': ``R_rel = R_z(a) R_x(b) R_y(c)``. Clinical angles:

* flexion (hip, knee) and dorsiflexion (ankle): ``a`` at the hip and the ankle, ``-a`` at the knee
  (the shank rotating backwards about the right-pointing z is knee flexion);
* adduction (hip, knee) and inversion (ankle): ``b`` on the right leg, ``-b`` on the left (the left
  leg's z points medially);
* internal rotation: ``c`` on the right, ``-c`` on the left.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

SIDES = ("left", "right")
JOINTS = {"hip": ("pelvis", "thigh", ("flexion", "adduction", "internal_rotation")),
          "knee": ("thigh", "shank", ("flexion", "adduction", "internal_rotation")),
          "ankle": ("shank", "foot", ("dorsiflexion", "inversion", "internal_rotation"))}


def _signs(side: str, joint: str) -> np.ndarray:
    mirror = 1.0 if side == "right" else -1.0
    return np.array([-1.0 if joint == "knee" else 1.0, mirror, mirror])


def _to_wxyz(r: Rotation) -> np.ndarray:
    return np.roll(np.atleast_2d(r.as_quat()), 1, axis=-1)


def _from_wxyz(q: np.ndarray) -> Rotation:
    return Rotation.from_quat(np.roll(np.atleast_2d(q), -1, axis=-1))


def joint_rotation(side: str, joint: str, flexion: np.ndarray, adduction: np.ndarray,
                   internal_rotation: np.ndarray) -> np.ndarray:
    """Relative rotation (..., 4) (w, x, y, z) of a joint's clinical angles (rad, broadcast)."""
    angles = np.stack(np.broadcast_arrays(*(np.asarray(v, dtype=float)
                                            for v in (flexion, adduction, internal_rotation))), axis=-1)
    q = _to_wxyz(Rotation.from_euler("ZXY", angles.reshape(-1, 3) * _signs(side, joint)))
    return q.reshape((*angles.shape[:-1], 4))


def true_joint_angles(orientations: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Clinical angles (rad, (N,)) of every joint from segment → world orientations (N, 4)."""
    out: dict[str, np.ndarray] = {}
    for side in SIDES:
        for joint, (prox, dist, kinds) in JOINTS.items():
            proximal = "pelvis" if prox == "pelvis" else f"{side}_{prox}"
            relative = _from_wxyz(orientations[proximal]).inv() * _from_wxyz(orientations[f"{side}_{dist}"])
            angles = relative.as_euler("ZXY") * _signs(side, joint)
            for k, kind in enumerate(kinds):
                out[f"{side}_{joint}_{kind}"] = angles[:, k]
    return out
