"""Calibrated joint angles (issue 4): known poses exact through arbitrary sensor mountings, left/right
mirroring, standing-offset removal, streaming == batch, stick-figure geometry."""

from __future__ import annotations

import numpy as np
import pytest

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.body import BodyDimensions
from gait_biofeedback.core.joints.angles import (
    JOINT_NAMES,
    JointAngleCalculator,
    compute_joint_angles,
    relative_rotation_from_angles,
)
from gait_biofeedback.core.joints.skeleton import stick_figure
from gait_biofeedback.core.stamps import seconds_to_ns
from gait_biofeedback.sim.simulator import SCENARIOS, simulate

DEG = np.pi / 180.0
G = (0.0, 0.0, 9.81)  # a still sensor's specific force
RNG = np.random.default_rng(3)
MOUNTS = {s: quat.canonical(quat.normalize(RNG.normal(size=4))) for s in
          ("pelvis", "left_thigh", "left_shank", "left_foot", "right_thigh", "right_shank", "right_foot")}


UPRIGHT = quat.from_axis_angle([1, 0, 0], np.pi / 2)  # segment frames upright in ENU, facing east:
# anatomical z (right) → world -y


def _sensor_quats(segment_quats):
    """q_sensor = q_segment ⊗ conj(r) for the random mountings."""
    return {s: quat.multiply(q, quat.conjugate(MOUNTS[s])) for s, q in segment_quats.items()}


def test_known_pose_is_exact_through_the_calibration():
    pelvis = quat.from_axis_angle([0, 0, 1], 0.7)  # any heading
    segs = {"pelvis": pelvis}
    pose = {"hip": (30 * DEG, 5 * DEG, -10 * DEG), "knee": (60 * DEG, 2 * DEG, 8 * DEG),
            "ankle": (-15 * DEG, 4 * DEG, 3 * DEG)}
    for side in ("left", "right"):
        thigh = quat.multiply(pelvis, relative_rotation_from_angles("hip", side, *pose["hip"]))
        shank = quat.multiply(thigh, relative_rotation_from_angles("knee", side, *pose["knee"]))
        foot = quat.multiply(shank, relative_rotation_from_angles("ankle", side, *pose["ankle"]))
        segs.update({f"{side}_thigh": thigh, f"{side}_shank": shank, f"{side}_foot": foot})
    angles = compute_joint_angles(_sensor_quats(segs), MOUNTS)
    assert set(angles) == set(JOINT_NAMES)
    for side in ("left", "right"):
        for joint, values in pose.items():
            got = [float(v) for k, v in angles.items() if k.startswith(f"{side}_{joint}_")]
            np.testing.assert_allclose(got, values, atol=1e-9)


def test_left_right_mirroring_of_a_physical_pose():
    # Both legs abducted by 10° (feet apart, thighs swing laterally) and toes turned out by 15°: both
    # hips read adduction -10° and internal rotation -15° (ISB signs mirrored on the left).
    pelvis = quat.IDENTITY
    x_axis, y_axis = [1, 0, 0], [0, 1, 0]
    right = quat.multiply(quat.from_axis_angle(x_axis, -10 * DEG), quat.from_axis_angle(y_axis, -15 * DEG))
    left = quat.multiply(quat.from_axis_angle(x_axis, 10 * DEG), quat.from_axis_angle(y_axis, 15 * DEG))
    # right thigh: lateral = +z; rotation about +x by -10° moves its distal end (−y) toward +z: abduction;
    # rotation about +y by -15° turns its x (anterior) toward +z = laterally: external rotation
    angles = compute_joint_angles(_sensor_quats({"pelvis": pelvis, "right_thigh": right, "left_thigh": left}),
                                  MOUNTS)
    for side in ("left", "right"):
        assert angles[f"{side}_hip_adduction"] == pytest.approx(-10 * DEG, abs=1e-9)
        assert angles[f"{side}_hip_internal_rotation"] == pytest.approx(-15 * DEG, abs=1e-9)
        assert angles[f"{side}_hip_flexion"] == pytest.approx(0.0, abs=1e-9)


def test_missing_or_uncalibrated_segments_drop_only_their_joints():
    segs = {s: quat.IDENTITY for s in MOUNTS}
    partial = {s: r for s, r in MOUNTS.items() if s != "left_shank"}
    angles = compute_joint_angles(_sensor_quats(segs), partial)
    assert not any(k.startswith(("left_knee", "left_ankle")) for k in angles)
    assert "left_hip_flexion" in angles and "right_ankle_dorsiflexion" in angles


@pytest.fixture(scope="module")
def walk():
    return simulate(SCENARIOS["walk"](duration=6.0, seed=2))


def test_truth_orientations_give_true_angles_and_offset_removal(walk):
    truth = walk.truth
    sensors = {s: truth.sensor_orientation[s] for s in MOUNTS}
    plain = compute_joint_angles(sensors, truth.mounting)
    angles = compute_joint_angles(sensors, truth.mounting, standing=slice(0, 200))
    for name in JOINT_NAMES:
        np.testing.assert_allclose(plain[name], truth.joint_angles[name], atol=1e-9)
        np.testing.assert_allclose(angles[name], plain[name] - np.mean(plain[name][:200]), atol=1e-12)
        assert abs(np.mean(angles[name][:200])) < 1e-12
    offset = dict(truth.mounting)
    offset["right_shank"] = quat.multiply(offset["right_shank"], quat.from_axis_angle([0, 0, 1], 5 * DEG))
    biased = compute_joint_angles(sensors, offset)  # a 5° shank calibration error about z biases the knee
    fixed = compute_joint_angles(sensors, offset, standing=slice(0, 200))  # ... the offset removal fixes it
    k = "right_knee_flexion"
    assert np.max(np.abs(biased[k] - truth.joint_angles[k])) > 1 * DEG
    np.testing.assert_allclose(fixed[k], angles[k], atol=0.5 * DEG)


def test_streaming_calculator_equals_batch(walk):
    truth = walk.truth
    sensors = {s: truth.sensor_orientation[s] for s in MOUNTS}
    batch = compute_joint_angles(sensors, truth.mounting, standing=slice(0, 150))
    calc = JointAngleCalculator(truth.mounting)
    calc.collect_offset(1.5)
    stream = []
    for k, stamp_ns in enumerate(seconds_to_ns(truth.t).tolist()):
        stream.append(calc.update(stamp_ns, {s: q[k] for s, q in sensors.items()}))
    assert not calc.offset_pending
    for name in JOINT_NAMES:
        got = np.array([row[name] for row in stream[150:]])
        np.testing.assert_allclose(got, batch[name][150:], atol=1e-12)


def test_the_streams_float_path_gives_the_numbers_of_compute_joint_angles_bit_for_bit():
    """The stream's one-instant angles (Python floats) equal :func:`compute_joint_angles` of that
    instant exactly (random orientations and mountings: any change in the order of the operations
    shows in the last bits), and leave out the same joints when a segment is missing or uncalibrated."""
    rng = np.random.default_rng(5)
    mounting = {s: quat.normalize(rng.normal(size=4)) for s in MOUNTS if s != "right_foot"}
    calc = JointAngleCalculator(mounting)
    for k in range(1000):
        instant = {s: quat.normalize(rng.normal(size=4)) for s in MOUNTS if s != "left_shank" or k % 2}
        expected = {n: float(v) for n, v in compute_joint_angles(instant, mounting).items()}
        got = calc.raw(instant)
        assert list(got) == list(expected) and got == expected, k


def test_stick_figure_of_standing_pose():
    body = BodyDimensions(thigh_length_m=0.45, shank_length_m=0.41, hip_width_m=0.2, foot_length_m=0.15,
                          ankle_height_m=0.07)
    lines = stick_figure({s: UPRIGHT for s in MOUNTS}, body)
    ends = {seg: end for seg, _start, end in lines}
    np.testing.assert_allclose(ends["right_foot"], [0.15, -0.10, -0.45 - 0.41 - 0.07], atol=1e-12)
    np.testing.assert_allclose(ends["left_thigh"], [0.0, 0.10, -0.45], atol=1e-12)


def _knee_pose(knee_deg: float) -> dict[str, np.ndarray]:
    """Sensor orientations of a standing pose with both knees flexed by ``knee_deg`` (hip, ankle 0)."""
    segs = {"pelvis": UPRIGHT}
    for side in ("left", "right"):
        shank = quat.multiply(UPRIGHT, relative_rotation_from_angles("knee", side, knee_deg * DEG, 0.0, 0.0))
        segs.update({f"{side}_thigh": UPRIGHT, f"{side}_shank": shank, f"{side}_foot": shank})
    return _sensor_quats(segs)


def test_stream_standing_offset_restarts_at_an_incomplete_instant():
    """1.5 s still at 10° knee flexion, one instant without the pelvis, then still at 20°: the 2 s
    offset window restarts after the incomplete instant, so the offset is the 20° pose's (it reads 0
    from 2 s after that instant); before, the raw 20° is published."""
    from gait_biofeedback.core.joints.stream import JointAnglesParams, JointAngleStream

    stream = JointAngleStream(JointAnglesParams(offset_window_s=2.0, heading="filters"))
    stream.set_calibration(dict(MOUNTS))
    out = []
    for k in range(500):
        pose = _knee_pose(10.0 if k < 150 else 20.0)
        for seg, q in pose.items():
            if k == 150 and seg == "pelvis":
                continue
            out += stream.add(seg, k * 10_000_000, q, (0.0, 0.0, 0.0), G)  # |ω| = 0: every segment still
    out += stream.flush(force=True)
    assert stream.missing_counts["pelvis"] == 1
    knee = {round(a.ns / 1e7): a.angles["right_knee_flexion"] / DEG for a in out}
    assert knee[100] == pytest.approx(10.0, abs=1e-9) and knee[350] == pytest.approx(20.0, abs=1e-9)
    assert knee[351] == pytest.approx(0.0, abs=1e-9) and knee[499] == pytest.approx(0.0, abs=1e-9)


def test_stream_standing_offset_needs_every_segment_still():
    from gait_biofeedback.core.joints.stream import JointAnglesParams, JointAngleStream

    stream = JointAngleStream(JointAnglesParams(offset_window_s=1.0, still_gyro=0.2, heading="filters"))
    stream.set_calibration(dict(MOUNTS))
    out = []
    for k in range(300):
        pose = _knee_pose(10.0 if k < 100 else 20.0)
        for seg, q in pose.items():  # the left shank turns at 0.3 rad/s for the first second
            moving = seg == "left_shank" and k < 100
            out += stream.add(seg, k * 10_000_000, q, (0.3 if moving else 0.19, 0.0, 0.0), G)
    knee = {round(a.ns / 1e7): a.angles["right_knee_flexion"] / DEG for a in out}
    assert knee[199] == pytest.approx(20.0, abs=1e-9)  # collecting since k = 100
    assert knee[200] == pytest.approx(0.0, abs=1e-9) and knee[299] == pytest.approx(0.0, abs=1e-9)


def test_angles_left_out_take_no_part_in_the_standing_offset_and_get_their_own_later():
    """Standing at 10° knee flexion while the right knee is left out (its heading not established):
    the left knee's offset is the 10°, the right knee gets none (an offset from before its heading was
    known would be wrong). When it appears it reads its raw 10° until 1 s more of standing gives it
    its own offset; the left knee's offset is kept."""
    from gait_biofeedback.core.joints.angles import JointAngleCalculator, joint_angle_names

    calculator = JointAngleCalculator(dict(MOUNTS))
    calculator.collect_offset(1.0)
    pose = _knee_pose(10.0)
    right_knee = joint_angle_names("right", "knee")
    for k in range(150):
        out = calculator.update(k * 10_000_000, pose, leave_out=right_knee)
        assert not set(right_knee) & set(out)
    assert not calculator.offset_pending and "right_knee_flexion" not in calculator.offset
    first = calculator.update(150 * 10_000_000, pose)
    assert first["left_knee_flexion"] == pytest.approx(0.0, abs=1e-9)
    assert first["right_knee_flexion"] / DEG == pytest.approx(10.0, abs=1e-9)
    assert calculator.offset_pending
    for k in range(151, 252):
        out = calculator.update(k * 10_000_000, pose)
    assert not calculator.offset_pending
    assert out["right_knee_flexion"] == pytest.approx(0.0, abs=1e-9)
    assert out["left_knee_flexion"] == pytest.approx(0.0, abs=1e-9)


def test_the_streams_vertical_turn_is_the_quaternion_product():
    from gait_biofeedback.core.joints._heading_kernel import _turned_back

    def _turned(q, angle):  # the stream's turn of a segment into the pelvis sensor's world (its kernel)
        return np.array(_turned_back(*q, -angle))

    np.testing.assert_allclose(_turned(np.array([1.0, 0.0, 0.0, 0.0]), np.pi / 2),
                               [np.cos(np.pi / 4), 0.0, 0.0, np.sin(np.pi / 4)], atol=1e-15)
    for q in MOUNTS.values():
        turned = quat.multiply(quat.from_axis_angle([0.0, 0.0, 1.0], 2.5), q)
        np.testing.assert_allclose(_turned(q, 2.5), turned, atol=1e-12)
