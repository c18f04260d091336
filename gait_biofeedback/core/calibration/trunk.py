"""Forward direction of the pelvis and chest sensors without a shared magnetometer heading (issue 14).

gait.md §1.7 option (b), READING: the pelvis' anatomical x is the horizontal direction the thighs'
anatomical x axes point to on average during the calibration motion (walking: the direction of
progression, the thighs swinging about it; hip flexion: the flexed thighs), expressed in the pelvis
sensor through each hip's kinematic relative heading
(:mod:`~gait_biofeedback.core.joints.relative_heading`, the pelvis proximal); the chest's x is the
pelvis' x seen through the lumbar "joint" (pelvis proximal, chest distal, joint-centre constraint as
an approximation). δ comes from the calibration's motion window alone (a walk of 8 steps is shorter than
the joint-angle stream needs to establish its own), so a motion that moves the joint centre too little
to observe it (hip flexion with a still pelvis) gives no direction, and the caller refuses the segment
with a message saying so and why. In walking, these directions only give the sign of the trunk
sensor's own anteroposterior axis (:func:`walking_axis`).
"""

from __future__ import annotations

import numpy as np
from scipy.signal import butter, filtfilt

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.joints.relative_heading import heading_rotation, window_relative_heading
from gait_biofeedback.core.segments import GRAVITY, ImuSeries
from gait_biofeedback.core.stamps import seconds_to_ns

MIN_AXIS_CLARITY = 2.0  # λ1/λ2 of the step-frequency horizontal acceleration
MIN_AXIS_POWER = 0.05  # (m/s²)², its variance along the axis: less is no walking


def _common(a: ImuSeries, b: ImuSeries) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the samples of ``a`` and ``b`` with the same stamp (the IMUs are sampled together)."""
    _, ia, ib = np.intersect1d(seconds_to_ns(a.t), seconds_to_ns(b.t), return_indices=True)
    return ia, ib


def forward_in_proximal(proximal: ImuSeries, q_proximal: np.ndarray, distal: ImuSeries,
                        q_distal: np.ndarray, x_distal: np.ndarray, motion: tuple[float, float],
                        toward_distal: bool = False) -> tuple[np.ndarray | None, str]:
    """(mean over the ``motion`` window (s) of a direction, how it was found or why not), with the
    joint's heading offset δ over that window
    (:func:`~gait_biofeedback.core.joints.relative_heading.window_relative_heading`):

    * ``toward_distal`` False: the distal's sensor vector ``x_distal`` seen in the proximal sensor
      (pelvis forward from a thigh's anatomical x);
    * True: the proximal's sensor vector ``x_distal`` seen in the distal sensor (chest forward from the
      pelvis' x).

    Not normalised (its length tells how consistent it was); None when δ is not usable."""
    ip, idist = _common(proximal, distal)
    t = proximal.t[ip]
    use = (t >= motion[0]) & (t <= motion[1])
    ip, idist, t = ip[use], idist[use], t[use]
    if len(ip) < 20:
        return None, "fewer than 20 samples of motion recorded by both sensors"
    qp, qd = np.asarray(q_proximal)[ip], np.asarray(q_distal)[idist]
    rate_hz = 1.0 / float(np.median(np.diff(t)))
    found = window_relative_heading(qp, proximal.gyr[ip], proximal.acc[ip], qd, distal.gyr[idist],
                                    distal.acc[idist], rate_hz)
    if found.problem is not None:
        return None, found.problem
    turn = heading_rotation(found.delta)
    how = f"heading coherence {found.coherence:.2f}"
    if toward_distal:
        world = quat.rotate(quat.conjugate(turn), quat.rotate(qp, x_distal))
        return quat.rotate_inverse(qd, world).mean(axis=0), how
    world = quat.rotate(turn, quat.rotate(qd, x_distal))
    return quat.rotate_inverse(qp, world).mean(axis=0), how


def walking_axis(series: ImuSeries, q: np.ndarray, motion: tuple[float, float], up: np.ndarray
                 ) -> tuple[np.ndarray | None, float, float]:
    """(anteroposterior axis ±, in sensor coordinates, or None; clarity λ1/λ2; step frequency Hz) of a
    trunk sensor over the ``motion`` window, from its own accelerations.

    READING (after the trunk-acceleration pattern of walking, Zijlstra & Hof 2003): each heel strike
    brakes and each push-off drives the trunk forward, so the anteroposterior acceleration repeats at
    the step frequency, while the mediolateral sway repeats at the stride frequency (half of it). The
    step frequency is the peak of the vertical acceleration's spectrum in 0.6–3 Hz; the horizontal
    acceleration (gravity removed with the filter's tilt, ``up``: the sensor's standing vertical),
    band-passed to 0.7–1.6 × that frequency, has its first principal axis along anteroposterior.
    The axis' sign is not known (the caller takes it from the thighs). None when the window holds no
    rhythmic walking (clarity < ``MIN_AXIS_CLARITY`` or too little acceleration)."""
    sel = (series.t >= motion[0]) & (series.t <= motion[1])
    rate = series.rate_hz
    if sel.sum() < 4 * rate:
        return None, 0.0, 0.0
    up_sensor = quat.rotate_inverse(np.asarray(q)[sel], [0.0, 0.0, 1.0])
    lin = series.acc[sel] - GRAVITY * up_sensor
    vertical = np.sum(lin * up_sensor, axis=1)
    spectrum = np.abs(np.fft.rfft(vertical - vertical.mean()))
    freq = np.fft.rfftfreq(len(vertical), 1.0 / rate)
    band = (freq >= 0.6) & (freq <= 3.0)
    step_hz = float(freq[band][np.argmax(spectrum[band])]) if band.any() else 0.0
    if step_hz <= 0.0 or 1.6 * step_hz >= 0.45 * rate:
        return None, 0.0, step_hz
    b, a = butter(2, [0.7 * step_hz / (0.5 * rate), 1.6 * step_hz / (0.5 * rate)], "band")
    lin = filtfilt(b, a, lin, axis=0)
    horizontal = lin - np.outer(lin @ up, up)
    eigval, eigvec = np.linalg.eigh(np.cov(horizontal.T))
    clarity = float(eigval[2] / max(eigval[1], 1e-12))
    if clarity < MIN_AXIS_CLARITY or eigval[2] < MIN_AXIS_POWER:
        return None, clarity, step_hz
    return eigvec[:, 2], clarity, step_hz
