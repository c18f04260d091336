"""The hips' common heading from the calibrated medio-lateral axes (issue 14): a known turn of the
thigh's world recovered on the simulator's walk, the estimator's waiting and restarts, the stream's
hips published without motion and named on /diagnostics while a joint waits, the standing offset
never taken while sitting, and the real qmt walk (skipped without ../shared/data)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import shared_data

from gait_biofeedback.batch import SCENARIOS, simulate
from gait_biofeedback.batch import quaternion as quat
from gait_biofeedback.core.joints.axis_heading import AxisHeadingEstimator
from gait_biofeedback.core.joints.stream import JointAnglesParams, JointAngleStream
from gait_biofeedback.core.stamps import seconds_to_ns

Z = np.array([0.0, 0.0, 1.0])
HIP = ("pelvis", "left_thigh")


@pytest.fixture(scope="module")
def walk():
    return simulate(SCENARIOS["walk"](duration=12.0, seed=2, segments=HIP))


def _run(estimator, walk, q_thigh, start=0):
    t_ns = seconds_to_ns(walk.truth.t).tolist()
    out = []
    for k in range(start, len(t_ns)):
        out.append(estimator.update(t_ns[k], walk.truth.sensor_orientation["pelvis"][k], (0.0, 0.0, 0.0),
                                    (0.0, 0.0, 9.81), q_thigh[k], (0.0, 0.0, 0.0), (0.0, 0.0, 9.81)))
    return out


def test_a_turned_thigh_world_is_recovered_within_the_hip_s_mean_rotation(walk):
    """The thigh sensor's world is turned by −70° (a 6D filter's own heading); with the true mounting
    axes the estimate is that turn up to the simulated hip's internal rotation averaged over 5 s
    (its curve, kinematics._HIP_INTERNAL, runs −4…+3°: mean under 1°), one second after the start."""
    turn = math.radians(70.0)
    q_thigh = quat.multiply(quat.from_axis_angle(Z, -turn), walk.truth.sensor_orientation["left_thigh"])
    estimator = AxisHeadingEstimator()
    estimator.set_axes(*(quat.rotate(walk.truth.mounting[s], Z) for s in HIP))
    out = _run(estimator, walk, q_thigh)
    rate = walk.config.rate_hz
    established = [e.established for e in out]
    assert not any(established[: int(0.95 * rate)]) and all(established[int(1.05 * rate):])
    error = np.degrees([math.remainder(e.delta - turn, 2 * math.pi) for e in out[int(1.05 * rate):]])
    assert np.max(np.abs(error)) < 1.7, np.max(np.abs(error))  # measured 0.85°
    assert out[-1].coherence > 0.99


def test_without_axes_it_waits_and_new_axes_restart_it(walk):
    q_thigh = walk.truth.sensor_orientation["left_thigh"]
    estimator = AxisHeadingEstimator()
    assert not _run(estimator, walk, q_thigh)[-1].established
    assert estimator.state == "waiting for a calibration"
    axes = [quat.rotate(walk.truth.mounting[s], Z) for s in HIP]
    estimator.set_axes(*axes)
    assert not estimator.established and estimator.state == "converging"
    estimator.set_axes(axes[0], None)  # the thigh not calibrated
    assert estimator.axes is None and estimator.state == "waiting for a calibration"


def test_time_going_back_restarts_the_average_but_keeps_the_axes(walk):
    q_thigh = walk.truth.sensor_orientation["left_thigh"]
    estimator = AxisHeadingEstimator()
    estimator.set_axes(*(quat.rotate(walk.truth.mounting[s], Z) for s in HIP))
    assert _run(estimator, walk, q_thigh)[-1].established
    replay = _run(estimator, walk, q_thigh)  # the recording again from its start: 12 s back
    assert not replay[0].established and estimator.axes is not None
    assert replay[-1].established


def _still_poses(first: str, walk) -> tuple[list, JointAngleStream]:
    """Still for 3 s in ``first`` ('sit': both hips and knees flexed 90°, the thighs horizontal;
    'stand': the walk's first standing pose, truth orientations), then standing still 5 s; the stream
    calibrated with the true mountings from the start."""
    from gait_biofeedback.core.joints.angles import relative_rotation_from_angles

    segments = ("pelvis", "left_thigh", "left_shank", "right_thigh", "right_shank")
    stream = JointAngleStream(JointAnglesParams(offset_window_s=2.0), segments=segments)
    stream.set_calibration({s: walk.truth.mounting[s] for s in segments})
    standing = {s: walk.truth.segment_orientation[s][0] for s in segments}
    sitting = dict(standing)
    for side in ("left", "right"):
        hip = relative_rotation_from_angles("hip", side, math.pi / 2, 0.0, 0.0)
        knee = relative_rotation_from_angles("knee", side, math.pi / 2, 0.0, 0.0)
        sitting[f"{side}_thigh"] = quat.multiply(standing["pelvis"], hip)
        sitting[f"{side}_shank"] = quat.multiply(sitting[f"{side}_thigh"], knee)
    out = []
    for k in range(800):
        pose = sitting if (first == "sit" and k < 300) else standing
        for seg in segments:
            q = quat.multiply(pose[seg], quat.conjugate(walk.truth.mounting[seg]))
            out += stream.add(seg, k * 10_000_000, q, (0.0, 0.0, 0.0), (0.0, 0.0, 9.81))
    return out + stream.flush(force=True), stream


@pytest.fixture(scope="module")
def legs_walk():
    return simulate(SCENARIOS["walk"](duration=4.0, seed=2, segments=("pelvis", "left_thigh", "left_shank",
                                                                       "right_thigh", "right_shank")))


def test_hips_are_published_standing_still_and_knees_are_named_while_they_wait(legs_walk):
    """Without motion the knees' joint-centre heading never establishes: their angles are left out
    and heading_status names them; the hips' axis heading establishes after 1 s of samples."""
    out, stream = _still_poses("stand", legs_walk)
    assert "left_hip_flexion" in out[-1].angles and "left_knee_flexion" not in out[-1].angles
    assert "left_hip_flexion" not in out[90].angles  # 0.9 s: not yet
    waiting, values = stream.heading_status()
    assert waiting == ["left_knee", "right_knee"]  # no feet calibrated: no ankles
    assert values["left_knee_heading"] == "collecting motion"
    assert values["left_hip_heading"].startswith("ok, δ 0.0°")


def test_the_standing_offset_is_never_taken_sitting(legs_walk):
    """Calibrated while sitting still 3 s, then standing still: the offset (2 s of still samples) comes
    from the standing, so sitting reads the 90° of hip flexion it is and standing 0°. Taken while
    sitting (the hips' heading is established after 1 s), the standing would read −90°."""
    out, _ = _still_poses("sit", legs_walk)
    hip = {round(a.ns / 1e7): math.degrees(a.angles["left_hip_flexion"]) for a in out
           if "left_hip_flexion" in a.angles}
    assert hip[250] == pytest.approx(90.0, abs=1e-6)
    assert hip[799] == pytest.approx(0.0, abs=1e-6)


def test_qmt_hip_heading_holds_on_a_real_walk():
    """qmt's real 6D walk (no truth): with the calibration the walking protocol finds (standing
    45.4–48.4 s, walk 48.4–68.9 s), the hips' axis heading stays within ±15° of its median from 56 s
    to the end (measured: left ±11.7°, right ±4.2°, the 6D filters' drift); the joint-centre one moved
    by 80° there."""
    path = shared_data("qmt_fullbody", "full_body_example_data.mat")
    from gait_biofeedback.batch import calibrate_session, import_qmt_fullbody, track_orientation

    rec = import_qmt_fullbody(path)
    segs = ("pelvis", "left_thigh", "right_thigh")
    tracked = {s: track_orientation(rec.imu[s]) for s in segs}
    data = {s: rec.imu[s] for s in segs} | {s: rec.imu[s] for s in ("left_shank", "right_shank")}
    cal = calibrate_session(data, (45.39, 48.39), (48.39, 68.89), "walking",
                            orientations={s: track_orientation(rec.imu[s])[1] for s in data})
    t, q_pelvis, _ = tracked["pelvis"]
    for side in ("left", "right"):
        thigh = f"{side}_thigh"
        assert cal.segments[thigh].valid and cal.segments["pelvis"].valid
        estimator = AxisHeadingEstimator()
        estimator.set_axes(*(quat.rotate(cal.segments[s].rotation, Z) for s in ("pelvis", thigh)))
        q_thigh = tracked[thigh][1]
        delta = np.array([estimator.update(ns, q_pelvis[k], (0.0,) * 3, (0.0,) * 3, q_thigh[k], (0.0,) * 3,
                                           (0.0,) * 3).delta
                          for k, ns in enumerate(seconds_to_ns(t).tolist())])
        late = np.degrees(delta[t >= 56.0])
        spread = np.abs(np.degrees(np.angle(np.exp(1j * np.radians(late - np.median(late))))))
        assert np.max(spread) < 15.0, (side, np.max(spread))
