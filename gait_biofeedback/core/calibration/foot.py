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

MIN_STANDING_S = 0.2


def leading_standing(gyr: np.ndarray, acc: np.ndarray, rate_hz: float, max_s: float = 5.0,
                     gyr_tol: float = 0.05, acc_tol: float = 0.5) -> int:
    """Number of leading quiet samples: ‖ω‖ < ``gyr_tol`` rad/s and ‖a‖ within ``acc_tol`` m/s² of the
    median norm of the first 0.1 s (not of a window that may already hold walking)."""
    n = min(len(gyr), round(max_s * rate_hz))
    g = np.linalg.norm(gyr[:n], axis=1)
    a = np.linalg.norm(acc[:n], axis=1)
    reference = np.nanmedian(a[: max(1, round(0.1 * rate_hz))])
    moving = ~(g < gyr_tol) | ~(np.abs(a - reference) < acc_tol)
    return int(np.argmax(moving)) if moving.any() else n


def foot_calibration(gyr: np.ndarray, acc: np.ndarray, rate_hz: float, segment: str = "left_foot",
                     standing_s: float = 5.0) -> np.ndarray:
    """Rotation r (segment → sensor, ``q_segment = q_sensor ⊗ r``) of a foot IMU from a recording that
    starts with quiet standing (at most ``standing_s`` s used) followed by walking. Raises ValueError
    with the calibration's message when it cannot be computed."""
    from gait_biofeedback.core.calibration.sensor_to_segment import calibrate_segment

    gyr = np.asarray(gyr, dtype=float)
    acc = np.asarray(acc, dtype=float)
    n = leading_standing(gyr, acc, rate_hz, max_s=standing_s)
    if n < MIN_STANDING_S * rate_hz:
        raise ValueError(f"foot calibration needs ≥ {MIN_STANDING_S:g} s of quiet standing at the start; "
                         f"found {n / rate_hz:.2f} s: start the recording with the patient standing still")
    walking = gyr[n:][np.all(np.isfinite(gyr[n:]), axis=1)]
    result = calibrate_segment(segment, acc[:n], gyr[:n], walking, rate_hz, "walking")
    if not result.valid:
        raise ValueError(f"foot calibration failed: {result.message}")
    return quat.normalize(result.rotation)
