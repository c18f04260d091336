"""StreamSequencer: reorder window, duplicates, late samples, bad stamps, real gaps and restarts."""

from __future__ import annotations

import pytest

from gait_biofeedback.core.sequencer import StreamSequencer

MS = 1_000_000


def _run(stamps_ms, **options):
    seq = StreamSequencer(**options)
    out = []
    for k, ms in enumerate(stamps_ms):
        out += seq.push(round(ms * MS), k)
    out += seq.flush()
    return seq, out


def test_in_order_samples_come_out_after_the_window_and_flush_releases_the_rest():
    seq = StreamSequencer(window=0.03)
    released = [len(seq.push(k * 10 * MS, k)) for k in range(10)]
    assert released == [0, 0, 0, 1, 1, 1, 1, 1, 1, 1], "30 ms = 3 samples held at 100 Hz"
    assert seq.holding == 3 and [r.payload for r in seq.flush()] == [7, 8, 9]


def test_samples_out_of_order_within_the_window_are_resequenced():
    stamps = [0, 10, 20, 40, 30, 50, 60, 70, 90, 80, 100]
    seq, out = _run(stamps)
    assert [r.stamp_ns // MS for r in out] == sorted(stamps)
    assert seq.counts == {"duplicates": 0, "late": 0, "bad_stamps": 0, "gaps": 0, "restarts": 0}


def test_duplicates_and_late_samples_are_dropped_and_counted():
    seq, out = _run([0, 10, 20, 30, 40, 50, 50, 60, 70, 80, 20, 90, 100])
    assert [r.stamp_ns // MS for r in out] == [0, 10, 20, 30, 40, 50, 60, 70, 80, 90, 100]
    assert seq.counts["duplicates"] == 1 and seq.counts["late"] == 1
    assert "later than the 30 ms reorder window" in seq.last_dropped


@pytest.mark.parametrize("offset_ms", [-500, 500])
def test_one_stamp_off_by_half_a_second_is_dropped_and_the_stream_goes_on(offset_ms):
    stamps = [10 * k for k in range(30)]
    stamps[15] += offset_ms
    seq, out = _run(stamps)
    assert [r.stamp_ns // MS for r in out] == [10 * k for k in range(30) if k != 15]
    assert seq.counts["bad_stamps"] == 1 and seq.counts["restarts"] == seq.counts["gaps"] == 0
    # measured from the newest sample before it (stamped 140 ms): 150 ± 500 ms is 10 ± 500 ms off
    side = "ahead of" if offset_ms > 0 else "behind"
    assert f"1 sample(s) stamped {abs(10 + offset_ms) / 1000:.3f} s {side} the stream" in seq.last_dropped


def test_a_real_gap_is_released_with_its_length():
    stamps = [10 * k for k in range(20)] + [2190 + 10 * k for k in range(20)]
    seq, out = _run(stamps)
    assert [r.stamp_ns // MS for r in out] == stamps, "no sample lost"
    (first,) = [r for r in out if r.gap_s]
    assert first.stamp_ns == 2190 * MS and first.gap_s == pytest.approx(2.0)
    assert seq.counts["gaps"] == 1 and seq.counts["bad_stamps"] == 0


def test_a_restart_goes_on_from_the_new_time_base():
    stamps = [5000 + 10 * k for k in range(20)] + [10 * k for k in range(20)]  # a recording looped
    seq, out = _run(stamps)
    assert [r.stamp_ns // MS for r in out] == stamps
    (first,) = [r for r in out if r.restart_s]
    assert first.stamp_ns == 0 and first.restart_s == pytest.approx(5.19)
    assert seq.counts["restarts"] == 1


def test_a_slow_stream_is_not_taken_for_jumps():
    stamps = [0, 480, 1010, 1500, 1990, 2520, 3000, 3470, 4010, 4500]  # ~2 Hz, irregular
    seq, out = _run(stamps)
    assert [r.stamp_ns // MS for r in out] == stamps and not any(seq.counts.values())
