"""JCS convention of core/joint_angles.py: round trips and hand-derived physical poses (gait.md §1.8)."""

import numpy as np
import pytest

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.joints.angles import (
    JOINT_NAMES,
    angles_from_relative_rotation,
    joint_angles_from_segments,
    relative_rotation_from_angles,
)

DEG = np.pi / 180.0
X, Y, Z = np.eye(3)


def _deg(angles):
    return np.array([float(a) for a in angles]) / DEG


def _pose(v_from, v_to):
    """Distal-segment rotation (in the proximal frame) that moves direction v_from onto v_to."""
    return quat.from_two_vectors(np.asarray(v_from, float), np.asarray(v_to, float))


def test_joint_names_order_and_count():
    assert len(JOINT_NAMES) == 18
    assert JOINT_NAMES[:3] == ("left_hip_flexion", "left_hip_adduction", "left_hip_internal_rotation")
    assert JOINT_NAMES[6:9] == (
        "left_ankle_dorsiflexion", "left_ankle_inversion", "left_ankle_internal_rotation"
    )
    assert JOINT_NAMES[9] == "right_hip_flexion"


@pytest.mark.parametrize("joint", ["hip", "knee", "ankle"])
@pytest.mark.parametrize("side", ["left", "right"])
def test_round_trip(joint, side):
    rng = np.random.default_rng(3)
    fe, aa, ie = rng.uniform(-1.4, 1.4, 200), rng.uniform(-1.3, 1.3, 200), rng.uniform(-3.0, 3.0, 200)
    q = relative_rotation_from_angles(joint, side, fe, aa, ie)
    back = angles_from_relative_rotation(joint, side, q)
    np.testing.assert_allclose(back[0], fe, atol=1e-9)
    np.testing.assert_allclose(back[1], aa, atol=1e-9)
    np.testing.assert_allclose(back[2], ie, atol=1e-9)


@pytest.mark.parametrize("side", ["left", "right"])
def test_rotation_about_plus_z_is_knee_extension_but_hip_flexion_and_dorsiflexion(side):
    q = quat.from_axis_angle(Z, 30 * DEG)
    np.testing.assert_allclose(_deg(angles_from_relative_rotation("knee", side, q)), [-30, 0, 0], atol=1e-9)
    np.testing.assert_allclose(_deg(angles_from_relative_rotation("hip", side, q)), [30, 0, 0], atol=1e-9)
    np.testing.assert_allclose(_deg(angles_from_relative_rotation("ankle", side, q)), [30, 0, 0], atol=1e-9)


def test_hip_flexion_moves_the_knee_forward():
    q = relative_rotation_from_angles("hip", "right", 40 * DEG, 0.0, 0.0)
    knee_direction = quat.rotate(q, -Y)  # thigh's distal direction in the pelvis frame
    assert knee_direction[0] > 0.6  # anterior


def test_toes_up_is_dorsiflexion():
    q = _pose(X, [np.cos(15 * DEG), np.sin(15 * DEG), 0.0])
    np.testing.assert_allclose(_deg(angles_from_relative_rotation("ankle", "left", q)), [15, 0, 0], atol=1e-9)


@pytest.mark.parametrize(("side", "medial_z"), [("right", -1.0), ("left", 1.0)])
def test_knee_moved_medially_is_hip_adduction_on_both_sides(side, medial_z):
    # thigh long axis tilted so the knee lies 12 deg medial of the hip
    distal = [0.0, -np.cos(12 * DEG), medial_z * np.sin(12 * DEG)]
    q = _pose(-Y, distal)
    np.testing.assert_allclose(_deg(angles_from_relative_rotation("hip", side, q)), [0, 12, 0], atol=1e-9)


@pytest.mark.parametrize(("side", "medial_z"), [("right", -1.0), ("left", 1.0)])
def test_ankle_moved_medially_is_knee_adduction_varus(side, medial_z):
    distal = [0.0, -np.cos(8 * DEG), medial_z * np.sin(8 * DEG)]
    q = _pose(-Y, distal)
    np.testing.assert_allclose(_deg(angles_from_relative_rotation("knee", side, q)), [0, 8, 0], atol=1e-9)


@pytest.mark.parametrize(("side", "lateral_z"), [("right", 1.0), ("left", -1.0)])
def test_toes_turned_outward_is_external_rotation(side, lateral_z):
    toes = [np.cos(15 * DEG), 0.0, lateral_z * np.sin(15 * DEG)]
    q = _pose(X, toes)
    np.testing.assert_allclose(_deg(angles_from_relative_rotation("ankle", side, q)), [0, 0, -15], atol=1e-9)


@pytest.mark.parametrize(("side", "medial_z"), [("right", -1.0), ("left", 1.0)])
def test_sole_facing_medially_is_inversion(side, medial_z):
    sole_normal = [0.0, -np.cos(10 * DEG), medial_z * np.sin(10 * DEG)]
    q = _pose(-Y, sole_normal)
    np.testing.assert_allclose(_deg(angles_from_relative_rotation("ankle", side, q)), [0, 10, 0], atol=1e-9)


@pytest.mark.parametrize(("side", "medial_z"), [("right", -1.0), ("left", 1.0)])
def test_shank_front_turned_medially_is_knee_internal_rotation(side, medial_z):
    front = [np.cos(20 * DEG), 0.0, medial_z * np.sin(20 * DEG)]
    q = _pose(X, front)
    np.testing.assert_allclose(_deg(angles_from_relative_rotation("knee", side, q)), [0, 0, 20], atol=1e-9)


def test_joint_angles_from_segments_uses_world_orientations():
    rng = np.random.default_rng(1)
    pelvis = quat.normalize(rng.normal(size=(5, 4)))
    thigh = quat.multiply(pelvis, relative_rotation_from_angles("hip", "left", 0.3, -0.1, 0.2))
    shank = quat.multiply(thigh, relative_rotation_from_angles("knee", "left", 0.9, 0.05, -0.1))
    out = joint_angles_from_segments({"pelvis": pelvis, "left_thigh": thigh, "left_shank": shank})
    np.testing.assert_allclose(out["left_hip_flexion"], 0.3, atol=1e-9)
    np.testing.assert_allclose(out["left_hip_adduction"], -0.1, atol=1e-9)
    np.testing.assert_allclose(out["left_knee_flexion"], 0.9, atol=1e-9)
    np.testing.assert_allclose(out["left_knee_internal_rotation"], -0.1, atol=1e-9)
    assert "left_ankle_dorsiflexion" not in out


def test_unknown_joint_or_side_raises():
    with pytest.raises(ValueError, match="unknown joint"):
        angles_from_relative_rotation("elbow", "left", quat.IDENTITY)
    with pytest.raises(ValueError, match="unknown side"):
        relative_rotation_from_angles("hip", "middle", 0.0, 0.0, 0.0)
