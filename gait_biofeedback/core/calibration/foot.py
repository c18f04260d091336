"""Foot sensor-to-segment rotation for the batch gait-event entry point (quiet standing, then walking).

The rotation comes from the project calibration (:func:`gait_biofeedback.core.calibration.sensor_to_segment.
calibrate_segment`, thesis Eq 14–16, walking protocol) on the leading quiet standing and the walking
after it. The sign of the foot's mediolateral axis (the 180° anterior/posterior ambiguity of the PCA)
is resolved there by the shared foot pitch-shape rule (:func:`~gait_biofeedback.core.calibration.
sensor_to_segment.foot_pitch_sign`: the toes-down minimum at push-off is deeper than the toes-up maximum at IC
[T §6.4.2]), the same rule the live calibration node uses, so the batch and live paths agree.
"""

from __future__ import annotations

import numpy as np

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.calibration.windows import moving_mean, moving_std, runs

MIN_STANDING_S = 0.2
STILL_GYRO_STD = 0.05  # rad/s: spread of the gyro over 0.25 s below this is a still foot
STILL_ACC_STD = 0.2  # m/s²: spread of ‖a‖ over 0.25 s below this is a still foot
STILL_WINDOW_S = 0.25
ONSET_S = 0.1  # s before the first moving sample left out of the standing (the movement's onset)
STANCE_WINDOW_S = 0.06  # s: the window of a still stance phase's spreads
STANCE_GYRO_STD = 0.05  # rad/s
STANCE_GYRO_NORM = 0.3  # rad/s: a few °/s of bias pass, the heel and forefoot rockers' rolling does not
STANCE_ACC_STD = 0.3  # m/s²
MIN_STANCE_S = 0.15  # s of stance phases needed in place of a standing
MAX_STANCE_S = 1.0  # s: a still run this long is a standing, not a stance phase
STANCE_LIMITS = (0.2, 1.5)  # rad/s, m/s²: the standing check's RMS limits for stance phases


def standing_run(gyr: np.ndarray, acc: np.ndarray, rate_hz: float, max_s: float = 5.0) -> tuple[int, int]:
    """[start, stop) sample indices of the longest quiet run within the first ``max_s`` s.

    READING (issue 15: a per-sample ``‖ω‖ < 0.05 rad/s`` from the first sample ended real sensors'
    standing after 0–0.16 s: their noise and a bias of a few °/s exceed it, and a foot may settle in
    the first second): a sample is quiet when, over the ``STILL_WINDOW_S`` around it, the gyro's spread
    (the norm of its per-axis standard deviations, so any constant bias passes) is below
    ``STILL_GYRO_STD`` and the spread of ``‖a‖`` below ``STILL_ACC_STD``; the run stops ``ONSET_S``
    before its first moving sample (the movement's onset is not standing)."""
    gyr, acc = np.asarray(gyr, dtype=float), np.asarray(acc, dtype=float)
    n = min(len(gyr), round(max_s * rate_hz))
    if n == 0:
        return 0, 0
    w = max(2, round(STILL_WINDOW_S * rate_hz))
    g, a = gyr[:n], np.linalg.norm(acc[:n], axis=1)
    gyr_spread = np.linalg.norm(moving_std(g, w), axis=1)
    quiet = (gyr_spread < STILL_GYRO_STD) & (moving_std(a, w) < STILL_ACC_STD)
    quiet_runs = runs(quiet)
    if not quiet_runs:
        return 0, 0
    start, stop = max(quiet_runs, key=lambda r: r[1] - r[0])
    if stop < len(gyr):
        stop = max(start, stop - round(ONSET_S * rate_hz))
    return int(start), int(stop)


def stance_phases(gyr: np.ndarray, acc: np.ndarray, rate_hz: float) -> np.ndarray:
    """(N,) bool: the foot is flat and still, over the ``STANCE_WINDOW_S`` around each sample: gyro
    spread (norm of its per-axis standard deviations) below ``STANCE_GYRO_STD``, mean ``‖ω‖`` below
    ``STANCE_GYRO_NORM``, spread of ``‖a‖`` below ``STANCE_ACC_STD``; runs longer than
    ``MAX_STANCE_S`` are standing, left out."""
    w = max(2, round(STANCE_WINDOW_S * rate_hz))
    gyr_spread = np.linalg.norm(moving_std(gyr, w), axis=1)
    turning = moving_mean(np.linalg.norm(gyr, axis=1), w) >= STANCE_GYRO_NORM  # a rocker, not a flat foot
    shaken = moving_std(np.linalg.norm(acc, axis=1), w) >= STANCE_ACC_STD
    flat = (gyr_spread < STANCE_GYRO_STD) & ~turning & ~shaken
    for a, b in runs(flat):  # longer is standing, not a step's foot flat (ipol 7-5: 24° off)
        if b - a > MAX_STANCE_S * rate_hz:
            flat[a:b] = False
    return flat


def foot_calibration(gyr: np.ndarray, acc: np.ndarray, rate_hz: float, segment: str = "left_foot",
                     standing_s: float = 5.0) -> np.ndarray:
    """Rotation r (segment → sensor, ``q_segment = q_sensor ⊗ r``) of a foot IMU from a recording that
    starts with quiet standing (the longest quiet run in the first ``standing_s`` s,
    :func:`standing_run`) followed by walking.

    READING (issue 15: "a fallback when the recording starts walking: the vertical from the stance
    phases"): without ``MIN_STANDING_S`` of standing, the foot-flat moments of the walk stand in for it
    (:func:`stance_phases`): their mean acceleration is the vertical, their mean gyro the bias, and the
    standing check allows them ``STANCE_LIMITS`` (a stance rolls, and the feet are set down at slightly
    different pitches: ipol_gait's stance samples have 2–5 °/s RMS about their mean, the simulator's
    up to 1.13 m/s²). A still run over ``MAX_STANCE_S`` is a standing, left out: ipol 7-5's final
    standing (4 of its 4.2 still seconds) put the vertical 24° from its first standing's. On ipol_gait
    subjects 1–5 with each trial's standing cut off (``benchmarks/gait_events.py --walk-only``), a 0.1
    s window refused 6 of 56 feet (fast walkers' feet are not still that long), 0.08 s 3, 0.06 s 1;
    with 0.06 s the calibration came within 1.3° (median; 8.1° at most) of the standing one; on 6–9, 1
    of 48 refused, 1.5° (3.9°). Before, all were refused. Raises ValueError with the calibration's
    message when neither gives a calibration."""
    from gait_biofeedback.core.calibration.sensor_to_segment import calibrate_segment

    gyr = np.asarray(gyr, dtype=float)
    acc = np.asarray(acc, dtype=float)
    start, stop = standing_run(gyr, acc, rate_hz, max_s=standing_s)
    if stop - start >= MIN_STANDING_S * rate_hz:
        walking = gyr[stop:][np.all(np.isfinite(gyr[stop:]), axis=1)]
        result = calibrate_segment(segment, acc[start:stop], gyr[start:stop], walking, rate_hz, "walking")
        how = "foot calibration failed"
    else:
        finite = np.all(np.isfinite(gyr), axis=1) & np.all(np.isfinite(acc), axis=1)
        flat = stance_phases(gyr, acc, rate_hz) & finite
        if flat.sum() < MIN_STANCE_S * rate_hz:
            raise ValueError(f"foot calibration needs ≥ {MIN_STANDING_S:g} s of quiet standing in the first "
                             f"{standing_s:g} s, or ≥ {MIN_STANCE_S:g} s of still stance phases in the walk; "
                             f"found {(stop - start) / rate_hz:.2f} s and {flat.sum() / rate_hz:.2f} s: "
                             "start the recording with the patient standing still")
        result = calibrate_segment(segment, acc[flat], gyr[flat], gyr[finite], rate_hz, "walking",
                                   standing_limits=STANCE_LIMITS)
        how = "foot calibration from the stance phases (no standing at the start) failed"
    if not result.valid:
        raise ValueError(f"{how}: {result.message}")
    return quat.normalize(result.rotation)
