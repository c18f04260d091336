"""Start-up step: static gyro bias, reference norms and initial attitude from quiet standing.

Thesis §5.3.1 / §7.2 of orientation.md: the static gyro bias is the mean gyro reading during the quiet
standing at the start of a trial, and ‖y_A,stat‖, ‖y_M,stat‖ (the references of the VST deviations,
thesis Eq 23, 48–49) are measured in the same window. The initial attitude comes from the averaged
accelerometer (+ magnetometer) by TRIAD (thesis Eq 9) with the accelerometer as the exact first vector,
so a magnetic disturbance never tilts the initial attitude.

World frame: ENU. With a magnetometer the heading is magnetic: the horizontal component of the field
points along world +y (north). Without one (6D), the heading is free and set to zero yaw (ZYX).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gait_biofeedback.core import quaternion as quat


def attitude_from_vectors(acc: np.ndarray, mag: np.ndarray | None = None) -> np.ndarray:
    """Orientation (..., 4) from specific force (+ magnetic field) vectors (..., 3), any units.

    TRIAD (thesis Eq 9) in ENU: up = acc/‖acc‖ (a static accelerometer reads +g up), east =
    mag × up normalised, north = up × east; R(q) has rows (east, north, up) in sensor coordinates.
    Without ``mag``: tilt only, yaw = 0 (thesis Eq 11 roll/pitch, written with atan2).
    """
    acc = np.asarray(acc, dtype=float)
    up = acc / np.linalg.norm(acc, axis=-1, keepdims=True)
    if mag is None:
        pitch = np.arctan2(-up[..., 0], np.hypot(up[..., 1], up[..., 2]))
        roll = np.arctan2(up[..., 1], up[..., 2])
        return quat.canonical(quat.from_euler_zyx(np.zeros_like(roll), pitch, roll))
    east = np.cross(np.asarray(mag, dtype=float), up)
    east = east / np.linalg.norm(east, axis=-1, keepdims=True)
    north = np.cross(up, east)
    return quat.from_matrix(np.stack([east, north, up], axis=-2))


MAX_STARTUP_BIAS = 0.15
"""rad/s (8.6 °/s): the largest gyro bias :func:`quiet_samples` removes before judging rest; a window
whose median rate is higher is a sensor turning, judged on its raw rate."""
BIAS_S = 0.5
"""s: the leading samples whose median rate :func:`quiet_samples` takes as the bias."""


def quiet_samples(gyr: np.ndarray, acc: np.ndarray, rate_hz: float, max_s: float = 10.0,
                  gyr_tol: float = 0.05, acc_tol: float = 0.5) -> int:
    """Number of leading samples (up to ``max_s`` seconds) during which the sensor is at rest.

    Rest = ‖ω − b‖ < ``gyr_tol`` rad/s, ``b`` the median rate of the first ``BIAS_S`` (the static gyro
    bias: issue 15, a real sensor's reaches 5 °/s, which read as motion and left the bias out exactly
    where it is largest; ``b`` = 0 when over ``MAX_STARTUP_BIAS``), and ‖a‖ within ``acc_tol`` m/s² of
    the median norm of the window. Returns 0 if the first sample moves.
    """
    n = min(len(gyr), round(max_s * rate_hz))
    if n == 0:
        return 0
    window = np.asarray(gyr[:n], dtype=float)
    bias = np.median(window[:max(1, round(BIAS_S * rate_hz))], axis=0)
    if not np.linalg.norm(bias) <= MAX_STARTUP_BIAS:
        bias = np.zeros(3)
    g = np.linalg.norm(window - bias, axis=1)
    a = np.linalg.norm(np.asarray(acc[:n], dtype=float), axis=1)
    moving = ~(g < gyr_tol) | ~(np.abs(a - np.nanmedian(a)) < acc_tol)
    return np.argmax(moving).item() if moving.any() else n


def exact_mean(rows: np.ndarray) -> np.ndarray:
    """Column means (or the mean of a vector) with correctly rounded sums (``math.fsum``).

    numpy's SIMD reductions may round differently depending on memory alignment, so the same samples
    could give means that differ in the last bit between two runs; the filters amplify such a bit
    through their discrete decisions (rest, disturbance), and the live graph and the offline path
    would then disagree. fsum makes the start-up step a function of the samples alone.
    """
    rows = np.asarray(rows, dtype=float)
    if rows.ndim == 1:
        return np.float64(math.fsum(rows.tolist()) / len(rows))
    return np.array([math.fsum(col) / len(rows) for col in rows.T.tolist()])


@dataclass(frozen=True)
class StartupCalibration:
    """Result of the quiet-standing start-up step (thesis §5.3.1)."""

    gyro_bias: np.ndarray  # rad/s, sensor frame, subtracted from every later gyro sample
    acc_norm: float  # ‖y_A,stat‖, m/s²
    mag_norm: float | None  # ‖y_M,stat‖, the magnetometer's own unit (tesla on the wire, µT in BROAD)
    q0: np.ndarray  # initial attitude (w, x, y, z)
    acc_mean: np.ndarray
    mag_mean: np.ndarray | None
    n_samples: int


def calibrate_from_rest(gyr: np.ndarray, acc: np.ndarray,
                        mag: np.ndarray | None = None) -> StartupCalibration:
    """Start-up calibration from a window of samples recorded at rest (NaN rows are ignored).

    Raises ValueError if the window holds no valid sample.
    """
    gyr = np.asarray(gyr, dtype=float).reshape(-1, 3)
    acc = np.asarray(acc, dtype=float).reshape(-1, 3)
    ok = np.isfinite(gyr).all(1) & np.isfinite(acc).all(1)
    if mag is not None:
        mag = np.asarray(mag, dtype=float).reshape(-1, 3)
        ok &= np.isfinite(mag).all(1)
    if not ok.any():
        raise ValueError("start-up window holds no finite sample")
    acc_mean = exact_mean(acc[ok])
    mag_mean = None if mag is None else exact_mean(mag[ok])
    return StartupCalibration(
        gyro_bias=exact_mean(gyr[ok]),
        acc_norm=float(exact_mean(np.linalg.norm(acc[ok], axis=1))),
        mag_norm=None if mag is None else float(exact_mean(np.linalg.norm(mag[ok], axis=1))),
        q0=attitude_from_vectors(acc_mean, mag_mean),
        acc_mean=acc_mean,
        mag_mean=mag_mean,
        n_samples=int(ok.sum()),
    )
