"""The orientation stream's array function equals its per-sample path, bit for bit (issue 46).

:meth:`SegmentOrientationTracker.update_batch` against :meth:`~SegmentOrientationTracker.update` (with
:meth:`~SegmentOrientationTracker.add_mag` in between) on the same samples, for every filter and the
cases the stream's control logic acts on: the released samples, which call released each, the notices,
the counts and the ``/diagnostics`` state at every status, and after the final flush. Also the
filter's ``update_batch`` (the numba kernel's loop and its pure-Python twin) against ``update``, and
the bulk orientation encoder against :func:`~gait_biofeedback.wire.cdr.pack_imu`.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from gait_biofeedback.core.jit import plain
from gait_biofeedback.core.orientation.filters import ALGORITHMS
from gait_biofeedback.core.orientation.filters import _inertial_kernel as ik
from gait_biofeedback.core.orientation.stream import OrientationBatch, OrientationParams

CASES = ("clean", "reordered", "nan", "holes", "no_mag", "faults")


def _stream(walking, case: str, seconds: float = 12.0):
    """(stamps ns, gyr, acc, mag stamps, mag, mag_before) of one segment of the walking trial, spoilt."""
    series = walking.imu["left_shank"]
    n = round(seconds * 100)
    ns = (1_700_000_000_000_000_000 + np.round(series.t[:n] * 1e9)).astype(np.int64)
    gyr, acc, mag = series.gyr[:n].copy(), series.acc[:n].copy(), series.mag[:n].copy()
    rng = np.random.default_rng(7)
    order = np.arange(n)
    if case == "reordered":
        for k in rng.choice(np.arange(200, n - 2), 40, replace=False):
            order[k], order[k + 1] = order[k + 1], order[k]
    keep = np.ones(n, bool)
    if case in ("holes", "faults"):
        keep[400:408] = False  # bridged
        keep[700:760] = False  # a dropout: re-acquired
        keep[rng.choice(np.arange(900, n), 10, replace=False)] = False
    if case in ("nan", "faults"):
        gyr[rng.choice(np.arange(150, n), 12, replace=False), 1] = np.nan
        acc[300, 2] = np.inf
        mag[rng.choice(np.arange(n), 15, replace=False), 0] = np.nan
    if case == "faults":
        acc[500, 0] = 1e4  # out of range
        order = np.insert(order, [606, 617], order[[600, 616]])  # a late sample, a duplicate
        ns = ns.copy()
        ns[1000] += 2_000_000_000  # a single stamp that jumps
    order = order[keep[order]]
    stamps, g, a = ns[order], gyr[order], acc[order]
    if case == "no_mag":
        return stamps, g, a, None, None, None
    mag_keep = np.flatnonzero(keep)
    mag_before = np.searchsorted(mag_keep, order, side="right")  # a magnetometer message after its Imu
    mag_before[::7] -= 1  # and some before it
    mag_before = np.maximum.accumulate(np.maximum(mag_before, 0))
    return stamps, g, a, ns[mag_keep], mag[mag_keep], mag_before


def _per_sample(tracker, stamps, gyr, acc, mag_ns, mag, mag_before, start: int, stop: int, given: int):
    calls, samples, notices = [], [], []
    for i in range(start, stop):
        if mag_ns is not None:
            for k in range(given, mag_before[i]):
                tracker.add_mag(int(mag_ns[k]), mag[k])
            given = max(given, int(mag_before[i]))
        out = tracker.update(int(stamps[i]), gyr[i], acc[i])
        calls += [i - start] * len(out)
        samples += out
        if tracker.notices:
            notices.append((i - start, tracker.notices.pop()))
    if mag_ns is not None and stop == len(stamps):
        for k in range(given, len(mag_ns)):
            tracker.add_mag(int(mag_ns[k]), mag[k])
    batch = OrientationBatch.of(calls, samples)
    batch.notices = notices
    return batch, given


def _same(a: OrientationBatch, b: OrientationBatch) -> None:
    for name in ("call", "stamp_ns", "q", "gyr", "acc", "recovering", "heading"):
        x, y = getattr(a, name), getattr(b, name)
        assert x.shape == y.shape and x.tobytes() == y.tobytes(), name
    assert a.notices == b.notices


def _state(tracker) -> tuple:
    seq = tracker.sequencer
    return (tracker.report(), tracker.diagnostics(), tracker.filter.state()["q"].tobytes(), tracker._t_last,
            seq._pending, seq._released_ns, seq._newest_ns, list(seq._intervals), list(tracker._mag))


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("algorithm", sorted(ALGORITHMS))
def test_update_batch_equals_update(walking, algorithm: str, case: str) -> None:
    stamps, gyr, acc, mag_ns, mag, mag_before = _stream(walking, case)
    params = OrientationParams(algorithm=algorithm)
    one, many = params.tracker("left_shank"), params.tracker("left_shank")
    cuts = [0, 250, 251, 1000, 1013, len(stamps)]  # blocks of the pass: a status between each
    given = 0
    for start, stop in itertools.pairwise(cuts):
        expected, given_after = _per_sample(one, stamps, gyr, acc, mag_ns, mag, mag_before, start, stop,
                                            given)
        if mag_ns is None:
            got = many.update_batch(stamps[start:stop], gyr[start:stop], acc[start:stop])
        else:
            last = len(mag_ns) if stop == len(stamps) else int(mag_before[stop - 1])
            last = max(last, given)
            got = many.update_batch(stamps[start:stop], gyr[start:stop], acc[start:stop], mag_ns[given:last],
                                    mag[given:last], mag_before[start:stop] - given)
            given_after = last
        given = given_after
        _same(got, expected)
        assert _state(one) == _state(many)
    _same(OrientationBatch.of([0] * 0, many.flush(end=True)), OrientationBatch.of([], one.flush(end=True)))
    assert _state(one) == _state(many)


def test_update_batch_takes_the_array_path(walking) -> None:
    """The clean stream is filtered as arrays after its start-up (not one :meth:`update` per sample)."""
    stamps, gyr, acc, mag_ns, mag, mag_before = _stream(walking, "clean")
    tracker = OrientationParams().tracker("left_shank")
    calls = []
    update = tracker.update
    tracker.update = lambda *args: calls.append(args) or update(*args)
    tracker.update_batch(stamps, gyr, acc, mag_ns, mag, mag_before)
    assert len(calls) < 0.2 * len(stamps)


@pytest.mark.parametrize("twin", ["compiled", "python"])
def test_inertial_kernel_run_equals_steps(walking, twin: str) -> None:
    """``_inertial_kernel.run`` (numba, and the plain Python twin on lists) equals ``InertialCF.update``."""
    series = walking.imu["left_thigh"]
    n = len(series.t)
    gyr, acc, mag = series.gyr[:n], series.acc[:n], series.mag[:n].copy()
    has = np.ones(n, bool)
    has[1::5] = False
    mag[~has] = 0.0
    dt = np.full(n, 0.01)
    a, b = ALGORITHMS["inertial_cf"](100.0), ALGORITHMS["inertial_cf"](100.0)
    a.initialize(acc[0], mag[0])
    b.initialize(acc[0], mag[0])
    expected = np.array([a.update(gyr[i], acc[i], mag[i] if has[i] else None, 0.01) for i in range(n)])
    if twin == "compiled":
        q, _ = b.update_batch(gyr, acc, mag, has, dt)
    else:
        s = b._s.tolist()
        flat = [0.0] * (7 * n)
        plain(ik, "run")(np.array(s), b._p, gyr.ravel(), acc.ravel(), mag.ravel(), has, dt, flat)
        q = np.array(flat).reshape(n, 7)[:, :4]
    assert q.tobytes() == expected.tobytes()


def test_bulk_codecs_equal_the_single_message_ones(walking) -> None:
    """``orientation_messages`` gives the bytes and Stamped of ``pack_imu(*orientation_fields(...))``;
    ``decode_stamped`` with frames gives what ``decode_imu`` gives message by message."""
    from sensor_msgs.msg import Imu

    from gait_biofeedback.core.orientation.stream import OrientationSample
    from gait_biofeedback.wire.cdr import IMU_DOUBLES, Stamped, decode_imu, decode_stamped, pack_imu
    from gait_biofeedback.wire.imu import orientation_fields, orientation_messages, raw_imu_values

    rng = np.random.default_rng(3)
    n = 50
    samples = [OrientationSample(1_700_000_000_000_000_000 + 10_000_000 * k, rng.normal(size=4),
                                 rng.normal(size=3), rng.normal(size=3), bool(k % 3 == 0), bool(k % 4))
               for k in range(n)]
    raws = [Stamped(s.stamp_ns, "x", tuple(rng.normal(size=IMU_DOUBLES).tolist())) for s in samples]
    batch = OrientationBatch.of(list(range(n)), samples)
    got = orientation_messages("left_foot", batch.stamp_ns, batch.q, batch.gyr, batch.acc, batch.recovering,
                               batch.heading, np.array([r.values for r in raws]), 0.0012)
    for (data, stamped), sample, raw in zip(got, samples, raws, strict=True):
        fields = orientation_fields("left_foot", sample, raw, 0.0012)
        assert data == pack_imu(*fields) and stamped == Stamped(*fields)
    payloads = [pack_imu(s.stamp_ns, f"frame_{k % 2}", raw_imu_values((0.1, k, 2.0), (0.0, 9.8, -k)))
                for k, s in enumerate(samples)]
    frames: list[str] = []
    ns, doubles, _ = decode_stamped(payloads, Imu, IMU_DOUBLES, frames)
    for k, data in enumerate(payloads):
        assert Stamped(int(ns[k]), frames[k], tuple(doubles[k].tolist())) == decode_imu(data)
