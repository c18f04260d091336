"""The attitude of a sensor again after its stream was silent (a radio dropout, a reconnect).

After a gap the filter's attitude is stale: the segment moved while nothing came. One accelerometer
sample is a poor restart while the patient walks (the segment's own acceleration tilts it by tens of
degrees, and a slow inclination correction then takes seconds to remove it). Instead the first
``recover_s`` s after the gap are gathered and :func:`attitude_after_gap` finds the attitude of their
first sample:

- the gyro (bias-corrected with the filter's estimate) is integrated over the window, so every
  sample's accelerometer and magnetometer vector can be expressed in the first sample's frame;
- their mean over the window points up: the mean specific force over a time T is gravity plus
  the velocity change over T divided by T (the idea of the inertial-frame low-pass of Laidig &
  Seel 2023 §3.2, here as a mean over a window instead of a decaying filter). Over an arbitrary
  second of walking a foot's velocity changes by up to 4 m/s (a 20° tilt; on the simulator's demo
  walk a 1 s window left the feet 9° off); over one whole stride it is nil (2.6°). So when the
  motion is cyclic the mean is taken over exactly one period, found as the lag at which the signal
  repeats (:func:`_one_period`); otherwise (standing, sitting) over the window;
- with a magnetometer, the mean field gives the heading (TRIAD, thesis Eq 9);
- without a magnetometer the heading is the one the segment had before the gap (READING: over a
  gap of a few seconds a walking segment's heading changes little; a turn during the gap is not
  recoverable without a magnetometer).

The filter then restarts from that attitude at the first sample and runs over the window.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.orientation.filters.startup import attitude_from_vectors

GRAVITY = 9.81
MIN_PERIOD_S = 0.5  # shortest stride searched for
MIN_OVERLAP_S = 0.25  # a lag is compared over at least this much data
PERIODIC = 0.3  # relative difference below which the motion repeats at that lag


def _heading(q: np.ndarray) -> tuple[float, int]:
    """Heading (rad, about world up) of the sensor axis that is the most horizontal in ``q``, and
    which axis that is."""
    axes = quat.rotate(np.asarray(q)[None, :], np.eye(3))
    k = int(np.argmin(np.abs(axes[:, 2])))
    return float(np.arctan2(axes[k, 1], axes[k, 0])), k


def _one_period(t: np.ndarray, gyr: np.ndarray, acc: np.ndarray) -> int:
    """How many of the first samples make one period of a cyclic motion (a stride), or all of them.

    The lag between ``MIN_PERIOD_S`` and the window's length less ``MIN_OVERLAP_S`` whose average
    squared difference of the (gyro, acc/g) signal with itself is smallest, relative to the
    signal's variance; if that is above ``PERIODIC``, the motion is not cyclic and every sample is
    used.
    """
    x = np.hstack([gyr, acc / GRAVITY])
    n = len(t)
    dt = float(np.median(np.diff(t))) if n > 1 else 1.0
    spread = float(np.mean(np.sum((x - x.mean(axis=0)) ** 2, axis=1)))
    best, period = np.inf, n
    for lag in range(max(1, round(MIN_PERIOD_S / dt)), n - round(MIN_OVERLAP_S / dt)):
        d = float(np.mean(np.sum((x[lag:] - x[:-lag]) ** 2, axis=1)))
        if d < best:
            best, period = d, lag
    return period if spread > 0 and best < PERIODIC * spread else n


def attitude_after_gap(t: Sequence[float], gyr: np.ndarray, acc: np.ndarray, mag: np.ndarray | None,
                       gyro_bias: np.ndarray, before: np.ndarray | None) -> np.ndarray:
    """Sensor→world attitude (w, x, y, z) of the first of the samples ``t`` (s), ``gyr`` (rad/s),
    ``acc``, ``mag`` (N, 3; rows of NaN where no magnetometer sample; None: none) gathered after a
    gap; ``before``: the attitude before the gap (gives the heading without a magnetometer)."""
    t = np.asarray(t, dtype=float)
    gyr = np.asarray(gyr, dtype=float) - np.asarray(gyro_bias, dtype=float)
    q_rel = np.empty((len(t), 4))
    q_rel[0] = (1.0, 0.0, 0.0, 0.0)
    for k in range(1, len(t)):
        q_rel[k] = quat.integrate_gyro(q_rel[k - 1], gyr[k], t[k] - t[k - 1])
    acc = np.asarray(acc, dtype=float)
    n = _one_period(t, gyr, acc)
    up = quat.rotate(q_rel[:n], acc[:n]).mean(axis=0)
    field = None
    if mag is not None:
        have = np.isfinite(mag).all(axis=1)
        if have.sum() >= max(3, len(t) // 2):
            field = quat.rotate(q_rel[have], np.asarray(mag, dtype=float)[have]).mean(axis=0)
    q0 = attitude_from_vectors(up, field)
    if field is None and before is not None:
        heading_before, axis = _heading(before)
        axes = quat.rotate(q0[None, :], np.eye(3))
        turn = heading_before - float(np.arctan2(axes[axis, 1], axes[axis, 0]))
        q0 = quat.multiply(quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), turn), q0)
    return quat.canonical(quat.normalize(q0))
