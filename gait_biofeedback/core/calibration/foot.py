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
from gait_biofeedback.core.calibration.walk import stance_calibration
from gait_biofeedback.core.calibration.windows import moving_std, runs

MIN_STANDING_S = 0.2
STILL_GYRO_STD = 0.05  # rad/s: spread of the gyro over 0.25 s below this is a still foot
STILL_ACC_STD = 0.2  # m/s²: spread of ‖a‖ over 0.25 s below this is a still foot
STILL_WINDOW_S = 0.25
ONSET_S = 0.1  # s before the first moving sample left out of the standing (the movement's onset)

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


def foot_calibration(gyr: np.ndarray, acc: np.ndarray, rate_hz: float, segment: str = "left_foot",
                     standing_s: float = 5.0) -> np.ndarray:
    """Rotation r (segment → sensor, ``q_segment = q_sensor ⊗ r``) of a foot IMU from a recording that
    starts with quiet standing (the longest quiet run in the first ``standing_s`` s,
    :func:`standing_run`) followed by walking.

    Without ``MIN_STANDING_S`` of standing, the foot-flat moments of the walk stand in for it
    (:func:`~.walk.stance_calibration`, issue 15). Raises ValueError with the calibration's message
    when neither gives a calibration."""
    from gait_biofeedback.core.calibration.sensor_to_segment import calibrate_segment

    gyr = np.asarray(gyr, dtype=float)
    acc = np.asarray(acc, dtype=float)
    start, stop = standing_run(gyr, acc, rate_hz, max_s=standing_s)
    if stop - start >= MIN_STANDING_S * rate_hz:
        walking = gyr[stop:][np.all(np.isfinite(gyr[stop:]), axis=1)]
        result = calibrate_segment(segment, acc[start:stop], gyr[start:stop], walking, rate_hz, "walking")
        how = "foot calibration failed"
    else:
        result = stance_calibration(segment, gyr, acc, rate_hz)
        how = "foot calibration from the stance phases (no standing at the start) failed"
    if not result.valid:
        raise ValueError(f"{how}: {result.message}")
    return quat.normalize(result.rotation)
