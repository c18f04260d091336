"""The calibration's live progress (issue 48): seconds of quiet standing, then each leg's movement
cycles, counted on synthetic sensors whose truth is set by hand."""

from __future__ import annotations

import math

import numpy as np

from gait_biofeedback.core.calibration.progress import CalibrationProgress
from gait_biofeedback.core.segments import SEGMENTS

RATE = 100.0


def _feed(progress: CalibrationProgress, t0: float, seconds: float, moving: dict[str, tuple[float, int]],
          rng: np.random.Generator) -> None:
    """``seconds`` of every segment from ``t0``: still (noise) unless ``moving[segment] = (period s,
    cycles)``: then ``cycles`` periods of -2 sin(2 pi t / period) rad/s about the sensor's z axis, still
    after."""
    for k in range(round(seconds * RATE)):
        t = t0 + k / RATE
        for seg in SEGMENTS:
            gyr = rng.normal(0.0, 0.01, 3)
            acc = np.array([0.0, 0.0, 9.81]) + rng.normal(0.0, 0.02, 3)
            if seg in moving:
                period, cycles = moving[seg]
                if t - t0 < period * cycles:
                    gyr[2] += -2.0 * math.sin(2 * math.pi * (t - t0) / period)
                    acc[0] += 1.5 * math.cos(2 * math.pi * (t - t0) / period)
            progress.add(seg, round(t * 1e9), acc.tolist(), gyr.tolist())


def test_standing_seconds_then_cycles_per_leg_since_the_standing():
    rng = np.random.default_rng(1)
    progress = CalibrationProgress(SEGMENTS, standing_needed_s=3.0)
    _feed(progress, 0.0, 2.0, {}, rng)
    now = progress.progress()
    assert not now.ready and abs(now.standing_s - 1.99) < 0.02, now
    assert now.text() == "standing still: 2.0 of 3 s"
    _feed(progress, 2.0, 3.0, {}, rng)  # 5 s of standing: enough
    assert progress.progress().ready
    # hip flexion: left thigh 6 cycles of 1.2 s, right thigh 4 of 1.5 s (shanks swing along, not counted)
    _feed(progress, 5.0, 8.0, {"left_thigh": (1.2, 6), "right_thigh": (1.5, 4), "left_shank": (0.6, 12)}, rng)
    now = progress.progress()
    assert now.cycles == {"left": 6, "right": 4}, now
    assert now.text().startswith("standing done; moves since: left 6, right 4 (hip flexion needs 10")
    assert now.values()["left_cycles"] == "6" and now.values()["standing_done"] == "true"
    # a new standing as long as needed starts the count again; a short pause does not
    _feed(progress, 13.0, 1.0, {}, rng)
    assert progress.progress().cycles == {"left": 6, "right": 4}
    _feed(progress, 14.0, 3.5, {}, rng)
    assert progress.progress().cycles == {"left": 0, "right": 0}


def test_a_feet_only_kit_counts_the_feet_and_a_silent_sensor_does_not_hold_the_standing():
    rng = np.random.default_rng(2)
    progress = CalibrationProgress(SEGMENTS, standing_needed_s=3.0)
    feet = [s for s in SEGMENTS if s.endswith("foot")]
    for k in range(400):
        for seg in feet:
            progress.add(seg, round(k / RATE * 1e9), [0.0, 0.0, 9.81], rng.normal(0.0, 0.01, 3).tolist())
    now = progress.progress()
    assert now.ready and now.cycles == {"left": 0, "right": 0}
    progress.add("left_foot", round(4.0 * 1e9), [0.0, 0.0, float("nan")], [0.0, 0.0, 0.0])  # skipped
    assert progress.progress().standing_s > 3.9
