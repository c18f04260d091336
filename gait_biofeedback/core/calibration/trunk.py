"""Forward direction of the pelvis and chest sensors without a shared magnetometer heading (issue 14).

gait.md §1.7 option (b), READING: the pelvis' anatomical x is the horizontal direction the thighs'
anatomical x axes point to on average during the calibration motion (walking: the direction of
progression, the thighs swinging about it; hip flexion: the flexed thighs), expressed in the pelvis
sensor through each hip's kinematic relative heading
(:mod:`~gait_biofeedback.core.joints.relative_heading`, the pelvis proximal); the chest's x is the
pelvis' x seen through the lumbar "joint" (pelvis proximal, chest distal, joint-centre constraint as
an approximation). Samples are used only where that heading is established, so a motion that moves
the joint centre too little to observe it (hip flexion with a still pelvis) gives no direction, and the
caller refuses the segment with a message saying so.
"""

from __future__ import annotations

import numpy as np

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.joints.relative_heading import estimate_relative_heading, heading_rotation
from gait_biofeedback.core.segments import ImuSeries
from gait_biofeedback.core.stamps import seconds_to_ns

MIN_ESTABLISHED_S = 2.0  # s of motion with an established heading needed for a direction


def _common(a: ImuSeries, b: ImuSeries) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the samples of ``a`` and ``b`` with the same stamp (the IMUs are sampled together)."""
    _, ia, ib = np.intersect1d(seconds_to_ns(a.t), seconds_to_ns(b.t), return_indices=True)
    return ia, ib


def forward_in_proximal(proximal: ImuSeries, q_proximal: np.ndarray, distal: ImuSeries,
                        q_distal: np.ndarray, x_distal: np.ndarray, motion: tuple[float, float],
                        toward_distal: bool = False) -> np.ndarray | None:
    """Mean over the ``motion`` window (s) of a direction, with the joint's kinematic heading δ:

    * ``toward_distal`` False: the distal's sensor vector ``x_distal`` seen in the proximal sensor
      (pelvis forward from a thigh's anatomical x);
    * True: the proximal's sensor vector ``x_distal`` seen in the distal sensor (chest forward from the
      pelvis' x).

    Not normalised (its length tells how consistent it was); None when the heading was established on
    fewer than ``MIN_ESTABLISHED_S`` s of the window."""
    ip, idist = _common(proximal, distal)
    if len(ip) < 20:
        return None
    t = proximal.t[ip]
    qp, qd = np.asarray(q_proximal)[ip], np.asarray(q_distal)[idist]
    delta, ok = estimate_relative_heading(seconds_to_ns(t), qp, proximal.gyr[ip],
                                          proximal.acc[ip], qd, distal.gyr[idist], distal.acc[idist])
    use = ok & (t >= motion[0]) & (t <= motion[1])
    if use.sum() * float(np.median(np.diff(t))) < MIN_ESTABLISHED_S:
        return None
    turn = heading_rotation(delta[use])
    if toward_distal:
        world = quat.rotate(quat.conjugate(turn), quat.rotate(qp[use], x_distal))
        return quat.rotate_inverse(qd[use], world).mean(axis=0)
    world = quat.rotate(turn, quat.rotate(qd[use], x_distal))
    return quat.rotate_inverse(qp[use], world).mean(axis=0)
