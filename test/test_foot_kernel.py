"""The foot-trajectory stage's array function equals its stream, bit for bit, and its compiled kernels
their plain-Python twins (issue 46).

:meth:`FootTrajectoryStream.update_batch` against :meth:`~FootTrajectoryStream.update` row by row (then
:meth:`~FootTrajectoryStream.flush` after both): the strides, the row each came out at, every filter
step kept (q, r, v, biases, covariances, update, zero velocity), the counts and notices; on a simulated
walk, running-like data that only the valley rule gives stances, and the walk spoilt with NaN samples,
lost samples (interpolated), a stamp going back and a gap over ``max_gap_s``; both detectors, the
gait-scaled test on and off. Then the array function on a short walk with every kernel swapped for its
plain-Python twin (:func:`gait_biofeedback.core.jit.plain`): the same bits as compiled.
"""

from __future__ import annotations

import numpy as np
import pytest

from gait_biofeedback.batch import SCENARIOS, simulate
from gait_biofeedback.core import jit
from gait_biofeedback.core.spatial import _kalman_kernel, _zero_velocity_kernel, kalman, zero_velocity
from gait_biofeedback.core.spatial.stream import FootTrajectoryParams, FootTrajectoryStream

pytest.importorskip("numba")

RATE_HZ = 100.0
CASES = ("clean", "running", "nan", "lost", "back", "gap")


@pytest.fixture(scope="module")
def walk():
    """A 16 s simulated walk of the left foot at 100 Hz (standing, then walking)."""
    return simulate(SCENARIOS["walk"](16.0, seed=2, segments=("left_foot",))).imu["left_foot"]


def _running(seconds: float = 8.0) -> tuple[np.ndarray, np.ndarray]:
    """1.5 s at rest, then a foot turning at 4 rad/s (noisy, shocks of 3 g) that only nearly stops
    once per cycle (0.2 rad/s at its stillest): no window of the fixed rule is quiet, the valley rule
    finds the stances."""
    rng = np.random.default_rng(3)
    n = round(seconds * RATE_HZ)
    gyr = np.tile([0.0, 4.0, 0.0], (n, 1)) + rng.normal(0.0, 0.3, (n, 3))
    acc = np.tile([0.0, 0.0, 9.81], (n, 1)) + rng.normal(0.0, 2.0, (n, 3))
    acc[200::70, 2] += 30.0
    for d in range(190, n - 10, 70):
        gyr[d - 2:d + 3] = np.outer([0.8, 0.5, 0.2, 0.5, 0.8], [0.0, 1.0, 0.0])
    rest = 150
    gyr[:rest] = rng.normal(0.0, 0.01, (rest, 3))
    acc[:rest] = rng.normal(0.0, 0.02, (rest, 3)) + np.array([0.0, 0.0, 9.81])
    return gyr, acc


def _input(walk, case: str, seconds: float = 16.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(stamps ns, gyr, acc) of one case."""
    if case == "running":
        gyr, acc = _running()
    else:
        n = round(seconds * RATE_HZ)
        gyr, acc = walk.gyr[:n].copy(), walk.acc[:n].copy()
    stamps = 1_700_000_000_000_000_000 + np.arange(len(gyr), dtype=np.int64) * 10_000_000
    keep = np.ones(len(gyr), bool)
    if case == "nan":
        gyr[[310, 640, 641, 900], 1] = np.nan
        acc[1200, 2] = np.inf
    if case == "lost":
        lost = [k for k in (300, 420, 705, 706, 1010, 1300, 1301, 1302) if k < len(keep)]
        keep[lost] = False  # 1, 1, 2, 1 and 3 samples lost: interpolated
    if case == "back":
        stamps[900:] -= 3_000_000_000  # the clock went back 3 s: a restart
    if case == "gap":
        stamps[800:] += 400_000_000  # 0.4 s missing, over max_gap_s: a restart
    return stamps[keep], gyr[keep], acc[keep]


def _steps(stream: FootTrajectoryStream) -> dict[str, np.ndarray]:
    kept = stream.kept
    none = np.full((15, 15), np.nan)  # no transition after a filter's last step
    return {"q": np.array([s.q for s in kept]), "r": np.array([s.r for s in kept]),
            "v": np.array([s.v for s in kept]), "b": np.array([s.b for s in kept]),
            "p_prior": np.array([s.p_prior for s in kept]), "p_post": np.array([s.p_post for s in kept]),
            "dx": np.array([s.dx for s in kept]), "zv": np.array([s.zero_velocity for s in kept]),
            "phi": np.array([none if s.phi is None else s.phi for s in kept]),
            "q_noise": np.array([none if s.q_noise is None else s.q_noise for s in kept]),
            "index": np.array(stream.index)}


def _by_rows(params, stamps, gyr, acc):
    stream = FootTrajectoryStream(RATE_HZ, params, keep_all=True)
    out = [(k, stride) for k in range(len(stamps))
           for stride in stream.update(int(stamps[k]), gyr[k], acc[k])]
    return stream, out + [(len(stamps), stride) for stride in stream.flush()]


def _by_array(params, stamps, gyr, acc):
    stream = FootTrajectoryStream(RATE_HZ, params, keep_all=True)
    one_by_one = []
    update = stream.update
    stream.update = lambda *row: one_by_one.append(row) or update(*row)
    out = stream.update_batch(stamps, gyr, acc)
    assert len(one_by_one) < 0.2 * len(stamps), "most rows went through the compiled runs"
    return stream, out + [(len(stamps), stride) for stride in stream.flush()]


def _assert_same(a, b):
    (stream_a, strides_a), (stream_b, strides_b) = a, b
    assert [(k, repr(s)) for k, s in strides_a] == [(k, repr(s)) for k, s in strides_b]
    assert stream_a.counts == stream_b.counts
    assert [vars(n) for n in stream_a.notices.pop()] == [vars(n) for n in stream_b.notices.pop()]
    steps_a, steps_b = _steps(stream_a), _steps(stream_b)
    for name, value in steps_a.items():
        np.testing.assert_array_equal(value, steps_b[name], err_msg=name)


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize(("detector", "adaptive_scale"), [("suh", 0.065), ("shoe", 0.0)])
def test_the_array_function_equals_the_stream_bit_for_bit(walk, case, detector, adaptive_scale):
    params = FootTrajectoryParams(detector=detector, adaptive_scale=adaptive_scale, acc_shock=30.0)
    stamps, gyr, acc = _input(walk, case)
    rows, array = _by_rows(params, stamps, gyr, acc), _by_array(params, stamps, gyr, acc)
    _assert_same(rows, array)
    stream, strides = rows
    counts = stream.counts
    assert len(strides) >= (4 if case == "running" else 8), "strides closed"
    assert counts["restarts"] == (case in ("back", "gap"))
    assert counts["skipped"] == (5 if case == "nan" else 0)
    assert counts["interpolated"] == {"nan": 5, "lost": 8}.get(case, 0)  # a skipped sample is lost too
    if case == "running":  # the fixed rule finds no stance after the rest: the valley rule does
        assert not zero_velocity.detect_zero_velocity(gyr[200:], acc[200:], RATE_HZ, params.gyro_limit,
                                                      params.jerk_limit, params.window_s, detector).any()
        assert all(k - s.foot_flat >= 45 for k, s in strides[:-1]), "valleys decided valley_gap_s late"


def _plain_kernels(monkeypatch) -> None:
    """Every kernel function of both modules back to plain Python; the streams load those."""
    for module in (_kalman_kernel, _zero_velocity_kernel):
        for name in dir(module):
            if hasattr(getattr(module, name), "py_func"):
                monkeypatch.setattr(module, name, jit.plain(module, name))
    twin_kalman, twin_detector = kalman.kernels(python=True), zero_velocity.detector_kernels(python=True)
    monkeypatch.setattr(kalman, "kernels", lambda: twin_kalman)
    monkeypatch.setattr(zero_velocity, "detector_kernels", lambda: twin_detector)


@pytest.mark.parametrize(("detector", "adaptive_scale"), [("suh", 0.065), ("shoe", 0.0)])
def test_the_compiled_kernels_equal_their_python_twins(walk, monkeypatch, detector, adaptive_scale):
    """3.1 s of the walk (1.2 s standing, then 2 strides) with a lost sample: the compiled array
    function and its plain-Python twin give the same bits."""
    params = FootTrajectoryParams(detector=detector, adaptive_scale=adaptive_scale, acc_shock=30.0)
    stamps, gyr, acc = (x[np.r_[450:650, 651:760]] for x in _input(walk, "clean"))
    compiled = _by_array(params, stamps, gyr, acc)
    assert hasattr(_kalman_kernel.foot_run, "py_func") and hasattr(_zero_velocity_kernel.run, "py_func")
    _plain_kernels(monkeypatch)
    assert not hasattr(_kalman_kernel.foot_step, "py_func")
    twin = _by_array(params, stamps, gyr, acc)
    _assert_same(compiled, twin)
    assert len(compiled[1]) >= 2 and compiled[0].counts["interpolated"] == 1


@pytest.fixture(scope="module")
def two_feet():
    """(side, stamps ns, q, gyr, acc) of both feet of a 30 s simulated walk, orientations from the truth."""
    sim = simulate(SCENARIOS["walk"](30.0, seed=4, segments=("left_foot", "right_foot")))
    out = []
    for side in ("left", "right"):
        imu = sim.imu[f"{side}_foot"]
        stamps = 1_700_000_000_000_000_000 + np.round(imu.t * 1e9).astype(np.int64)
        q = sim.truth.sensor_orientation[f"{side}_foot"]
        out.append((side, stamps, q, imu.gyr.copy(), imu.acc.copy()))
    return out


@pytest.mark.parametrize("case", ["clean", "faults"])
def test_the_gait_stream_s_array_function_equals_its_rows(two_feet, case):
    """GaitEventStream.update_batch of each foot against update row by row (left foot, then right): the
    events and strides (with provisional and smoothed spatial values, revisions) and the rows they came
    out at, counts and notices. Faults: NaN rows, a recovering stretch, lost samples, the left foot's
    clock 2 s back (a reset of events and trajectory) and a 0.5 s gap in the right foot's."""
    from gait_biofeedback.core.gait.stream import GaitEventsParams, GaitEventStream

    feet = []
    for side, stamps, q, gyr, acc in two_feet:
        stamps, gyr, recovering = stamps.copy(), gyr.copy(), np.zeros(len(stamps), bool)
        keep = np.ones(len(stamps), bool)
        if case == "faults":
            gyr[[900, 1700], 0] = np.nan
            recovering[1200:1230] = True
            keep[[1500, 2200, 2201]] = False
            if side == "left":
                stamps[2000:] -= 2_000_000_000
            else:
                stamps[1800:] += 500_000_000
        feet.append((side, stamps[keep], q[keep], recovering[keep], gyr[keep], acc[keep]))
    params = GaitEventsParams(use_standing_reference=True)
    by_rows, by_array = GaitEventStream(params), GaitEventStream(params)
    rows_out, array_out = [], []
    for side, stamps, q, recovering, gyr, acc in feet:
        for k in range(len(stamps)):
            events, cycles = by_rows.update(side, int(stamps[k]), tuple(q[k].tolist()), bool(recovering[k]),
                                            tuple(gyr[k].tolist()), tuple(acc[k].tolist()))
            rows_out += [(side, k, repr(x)) for x in events + cycles]
        events, cycles = by_array.update_batch(side, stamps, q, recovering, gyr, acc)
        array_out += sorted([(side, k, repr(x)) for k, x in events + cycles], key=lambda row: row[1])
    assert array_out == rows_out
    assert by_rows.counts == by_array.counts
    assert [vars(n) for n in by_rows.notices.pop()] == [vars(n) for n in by_array.notices.pop()]
    for side in ("left", "right"):
        assert by_rows.feet[side].counts == by_array.feet[side].counts
    counts = by_rows.counts
    assert sum(c["spatial_provisional"] for c in counts.values()) > 5, "provisional values asked of the foot"
    assert sum(c["spatial_strides"] for c in counts.values()) > 20
    if case == "faults":
        assert counts["left"]["resets"] >= 1 and by_rows.feet["left"].counts["restarts"] == 1
        assert by_rows.feet["right"].counts["interpolated"] >= 3
