"""The joint headings' kernels (issue 46): compiled with numba and run as plain Python (the twin), on a
simulated walk's orientations with faults, give the same numbers bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from gait_biofeedback.batch import SCENARIOS, simulate
from gait_biofeedback.batch import quaternion as quat
from gait_biofeedback.core import jit
from gait_biofeedback.core.joints import _heading_kernel as hk
from gait_biofeedback.core.joints import relative_heading
from gait_biofeedback.core.joints.axis_heading import AxisHeadingEstimator
from gait_biofeedback.core.joints.relative_heading import RelativeHeadingEstimator

pytest.importorskip("numba")


@pytest.fixture(scope="module")
def samples():
    """(stamp ns, q₁, ω₁, a₁, q₂, ω₂, a₂) rows of a 30 s walk's pelvis (proximal) and left thigh, the
    thigh's world turned by 40° and then, from 15 s over 2 s, by 30° more (a magnetometer's heading
    correction); faults: 0.5 s of both dropped (a segment gone), a NaN rate, a repeated stamp, a stamp
    0.4 s ahead and, near the end, the stamps 2 s back (a restart)."""
    walk = simulate(SCENARIOS["walk"](duration=30.0, seed=2, segments=("pelvis", "left_thigh")))
    a, b = walk.imu["pelvis"], walk.imu["left_thigh"]
    t_ns = np.round(a.t * 1e9).astype(np.int64)
    turn = np.radians(40.0) + np.radians(30.0) * np.clip((a.t - 15.0) / 2.0, 0.0, 1.0)
    q1 = walk.truth.sensor_orientation["pelvis"]
    q2 = quat.multiply(quat.from_axis_angle([0.0, 0.0, 1.0], -turn),
                       walk.truth.sensor_orientation["left_thigh"])
    gyr1 = a.gyr.copy()
    gyr1[900, 1] = np.nan
    t_ns[2000:] += 400_000_000
    t_ns[2600:] -= 2_400_000_000
    keep = np.ones(len(t_ns), dtype=bool)
    keep[1200:1250] = False
    rows = [(int(t_ns[k]), *(tuple(v[k]) for v in (q1, gyr1, a.acc, q2, b.gyr, b.acc)))
            for k in np.flatnonzero(keep)]
    return [*rows[:1500], rows[1499], *rows[1500:]]


def _run(make, samples, magnetic):
    est = make()
    if isinstance(est, AxisHeadingEstimator):
        est.set_axes((0.0, 0.0, 1.0), (0.1, 0.2, 0.97))
    out = [tuple(est.update(*row, magnetic=magnetic)) for row in samples]
    return out, np.array(est._f, dtype=float), np.array(est._i, dtype=np.int64), est.state


@pytest.mark.parametrize("estimator", [RelativeHeadingEstimator, AxisHeadingEstimator])
@pytest.mark.parametrize("magnetic", [(False, False), (True, True)])
def test_compiled_and_plain_python_kernels_agree_bit_for_bit(samples, monkeypatch, estimator, magnetic):
    assert hasattr(relative_heading._kernels().step, "py_func"), "numba compiled the kernel"
    compiled = _run(estimator, samples, magnetic)
    for name in ("step", "add_row", "axis_step", "delta", "coherence", "_norm", "_wrap", "_turned_back",
                 "_vertical_correction", "_turn_worlds", "_restart", "_rotate", "_centre_force", "_coherence",
                 "_add_product"):
        monkeypatch.setattr(hk, name, jit.plain(hk, name))
    twin = relative_heading._kernels(python=True)  # the module's functions, now the plain ones
    monkeypatch.setattr(relative_heading, "_kernels", lambda: twin)
    plain = _run(estimator, samples, magnetic)
    assert compiled[0] == plain[0]  # delta, established, coherence, state of every sample: ==, not approx
    np.testing.assert_array_equal(compiled[1], plain[1])
    np.testing.assert_array_equal(compiled[2], plain[2])
    assert any(e[1] for e in compiled[0]), "the estimate was established"
    assert compiled[2][hk.HAS_MIDDLE] == 1



@pytest.fixture(scope="module")
def faulty_walk():
    """(segment, stamp ns, q, ω, a, recovering, magnetic, received ns) of a 40 s walk's seven joint
    segments in arrival order, with faults: the left shank dropped for 1 s (a segment gone), a NaN rate
    of the right thigh, the right foot's stamps 0.5 s ahead for 3 s (a stamp jump: misaligned), the
    pelvis recovering for 0.3 s, the left thigh's world turned by 40° and read as magnetic."""
    from gait_biofeedback.core.joints.stream import STREAM_SEGMENTS

    walk = simulate(SCENARIOS["walk"](duration=40.0, seed=4, segments=STREAM_SEGMENTS))
    t_ns = np.round(walk.imu["pelvis"].t * 1e9).astype(np.int64)
    out = []
    for k in range(len(t_ns)):
        for seg in STREAM_SEGMENTS:
            imu, q = walk.imu[seg], walk.truth.sensor_orientation[seg][k]
            if seg == "left_shank" and 1500 <= k < 1600:
                continue
            if seg == "left_thigh":
                q = quat.multiply(quat.from_axis_angle([0.0, 0.0, 1.0], np.radians(40.0)), q)
            gyr = tuple(imu.gyr[k])
            if seg == "right_thigh" and k == 900:
                gyr = (np.nan, *gyr[1:])
            ns = int(t_ns[k]) + (500_000_000 if seg == "right_foot" and 2000 <= k < 2300 else 0)
            out.append((seg, ns, q, gyr, tuple(imu.acc[k]), seg == "pelvis" and 2500 <= k < 2530,
                        seg == "left_thigh", int(t_ns[k])))
    return out, walk.truth.mounting


def _stream_run(rows, mounting):
    from gait_biofeedback.core.joints.stream import JointAnglesParams, JointAngleStream

    stream = JointAngleStream(JointAnglesParams(offset_window_s=2.0))
    stream.set_calibration(dict(mounting))
    stream.set_calibration(dict(mounting), from_ns=25_000_000_000)  # a second one, 25 s in
    out = []
    for seg, ns, q, gyr, acc, recovering, magnetic, received in rows:
        out += stream.add(seg, ns, q, gyr, acc, recovering=recovering, magnetic=magnetic,
                          received_ns=received)
    out += stream.flush(force=True)
    return ([(s.ns, s.angles, {k: v.tolist() for k, v in s.sensor_quats.items()}, s.recovering, s.no_heading)
             for s in out], [np.array(e._f) for e in stream.headings.values()])


def test_the_streams_instant_kernel_compiled_and_plain_agree_bit_for_bit(faulty_walk, monkeypatch):
    """One kernel call per synchronised instant (the six joints' headings, the chain, the angles, the
    still test): compiled and as plain Python, the same instants, angles and turned orientations, ==."""
    assert hasattr(relative_heading._kernels().instant, "py_func"), "numba compiled the kernel"
    compiled, f_compiled = _stream_run(*faulty_walk)
    for name in ("step", "add_row", "axis_step", "delta", "coherence", "_norm", "_wrap", "_turned_back",
                 "_vertical_correction", "_turn_worlds", "_restart", "_rotate", "_centre_force", "_coherence",
                 "_add_product", "instant", "segment_angles", "_multiply", "_upright"):
        monkeypatch.setattr(hk, name, jit.plain(hk, name))
    twin = relative_heading._kernels(python=True)
    monkeypatch.setattr(relative_heading, "_kernels", lambda: twin)
    from gait_biofeedback.core.joints import stream as stream_module

    monkeypatch.setattr(stream_module, "_kernels", lambda: twin)
    plain, f_plain = _stream_run(*faulty_walk)
    assert compiled == plain
    for a, b in zip(f_compiled, f_plain, strict=True):
        np.testing.assert_array_equal(a, b)
    assert not compiled[-1][4], "every joint's heading was established by the end"
    assert any(s[3] for s in compiled), "some instants were recovering"
    assert sum(1 for s in compiled if s[1]) > 3000
