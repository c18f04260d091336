"""Per-stride quantities of stroke gait training from the sagittal joint angles and the stride's events
(issue 49 item 2; definitions and sources in docs/guide/stroke.md).

A stride of side S runs from its IC (``t_start``) to its next IC (``t_end``); the other foot's IC inside
it is ``t_other = t_end - step_time`` and S's TC is ``t_tc``. Angles are the calibrated sagittal joint
angles of S (hip flexion ``h``, knee flexion ``k``, ankle dorsiflexion ``d``; 0 in the standing posture
of the calibration), so in the leg's sagittal plane the thigh is ``h``, the shank ``h - k`` and the foot
``h - k + d`` from their standing directions, relative to the pelvis.

* ``trailing_limb_angle`` (rad): the angle between the vertical and the line from the hip joint centre
  to the metatarsal heads, at ``t_other`` (terminal stance: the other foot's IC), positive with the foot
  behind the hip. Hsiao et al. 2015 ("Mechanisms to increase propulsive force for individuals
  poststroke", J NeuroEng Rehabil 12:40: greater trochanter to 5th metatarsal head) and Awad et al. 2015
  ("Paretic propulsion and trailing limb angle are key determinants of long-distance walking function
  after stroke", Neurorehabil Neural Repair 29:499) use it as the main kinematic determinant of paretic
  propulsion. Joint angles are relative to the pelvis; the vertical
  comes from the stance foot being flat in mid-stance (Perry & Burnfield 2010, foot flat from loading
  response to heel rise): over 20-45 % of S's stance the foot's world pitch is 0, so the pelvis's
  sagittal pitch is ``-(h - k + d)`` there (median) and is taken as constant until ``t_other``
  (READING: pelvic tilt varies by 2-4° over the cycle; :func:`pelvis_pitch_from_foot_flat`). The
  chain uses the body dimensions (thigh, shank, ankle height, ankle to toes).
* ``propulsion`` (rad): the ankle's push-off, the plantarflexion from ``t_other`` to the least
  dorsiflexion in [``t_other``, ``t_tc`` + 10 % of the stride time]. Choice: anterior ground reaction
  (propulsion) comes from the trailing limb's orientation and the ankle plantarflexor moment (Hsiao et
  al. 2015, "The relative contribution of ankle moment and trailing limb angle to propulsive force
  during gait", Hum Mov Sci 39:212); IMUs give no moment, and the
  plantarflexors' work shows as the ankle plantarflexing through pre-swing (Perry: ~30° from 50 % to
  62 % of the cycle; reduced after a stroke). The TLA is its own quantity, so this one carries the
  ankle's part; a weak push-off is low.
* ``knee_hyperextension_stance`` (rad): the least knee flexion from 1/6 to 5/6 of the stance time
  (single-limb support of a 60 % stance: 10-50 % of the cycle), negative = hyperextended (genu
  recurvatum; Perry & Burnfield 2010 ch. on the knee's stance deviations).
* ``foot_strike_angle`` (rad) and ``swing_foot_clearance`` (m): the foot trajectory's pitch at the
  closing IC (toes up positive; ``foot_angle_ic``) and highest rise of the foot sensor in the swing above
  its stance (``max_foot_height``), gait.md §4.8; Mariani et al. 2010 ("3D gait assessment in young and
  elderly subjects using foot-worn inertial sensors", J Biomech 43:2999): foot-IMU strike angle and
  swing height; the JNER 2023 stroke study of issue 49 fed back the strike angle.
* ``step_length_asymmetry_paretic``, ``stance_time_asymmetry_paretic`` (1): paretic / non-paretic means
  over the evaluator's moving window (the ratio of Patterson et al. 2010, "Evaluation of gait symmetry
  after stroke", Gait Posture 31:241, with the paretic side on top instead of the larger value: < 1
  when the paretic side's is shorter).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from gait_biofeedback.core.body import BodyDimensions

FOOT_FLAT = (0.20, 0.45)  # part of the stance (IC → TC) where the stance foot is flat
PUSH_OFF_AFTER_TC = 0.10  # of the stride time: the push-off's plantarflexion peaks just after toe off
SINGLE_SUPPORT = (1.0 / 6.0, 5.0 / 6.0)  # part of the stance searched for the knee's least flexion


def pelvis_pitch_from_foot_flat(t: np.ndarray, angles: np.ndarray, t_start: float, t_tc: float) -> float:
    """The pelvis's sagittal pitch (rad, forward rotation of the leg chain's frame) over ``FOOT_FLAT`` of
    the stance: ``-median(h - k + d)``; NaN without samples there."""
    a, b = (t_start + f * (t_tc - t_start) for f in FOOT_FLAT)
    sel = (t >= a) & (t <= b)
    if not sel.any():
        return math.nan
    return -float(np.median(angles[sel, 0] - angles[sel, 1] + angles[sel, 2]))


def trailing_limb_angle(hip: float, knee: float, ankle: float, pelvis_pitch: float,
                        lengths: BodyDimensions) -> float:
    """Angle (rad) between the vertical and the hip → metatarsal heads line of a leg with sagittal
    angles ``hip``, ``knee``, ``ankle`` (rad) under a pelvis pitched by ``pelvis_pitch``; positive when
    the foot is behind the hip."""
    thigh, shank = hip + pelvis_pitch, hip - knee + pelvis_pitch
    foot = shank + ankle
    x = lengths.thigh_length_m * math.sin(thigh) + lengths.shank_length_m * math.sin(shank)
    y = -lengths.thigh_length_m * math.cos(thigh) - lengths.shank_length_m * math.cos(shank)
    x += lengths.foot_length_m * math.cos(foot) + lengths.ankle_height_m * math.sin(foot)
    y += lengths.foot_length_m * math.sin(foot) - lengths.ankle_height_m * math.cos(foot)
    return math.atan2(-x, -y)


def stroke_kinematics(t: np.ndarray, angles: np.ndarray, t_start: float, t_tc: float, t_other: float,
                      t_end: float, lengths: BodyDimensions) -> dict[str, float]:
    """``trailing_limb_angle``, ``propulsion``, ``knee_hyperextension_stance`` (rad) of one stride from
    its side's sagittal ``angles`` (N, 3: hip, knee, ankle) at ``t`` (module docstring); a quantity
    whose events are unknown (NaN) or out of order is left out."""
    out: dict[str, float] = {}
    if not t_start < t_tc < t_end:
        return out
    stance = t_tc - t_start
    sel = (t >= t_start + SINGLE_SUPPORT[0] * stance) & (t <= t_start + SINGLE_SUPPORT[1] * stance)
    if sel.any():
        out["knee_hyperextension_stance"] = float(angles[sel, 1].min())
    if not t_start < t_other < t_tc:
        return out
    at_other = [float(np.interp(t_other, t, angles[:, j])) for j in range(3)]
    push = (t >= t_other) & (t <= t_tc + PUSH_OFF_AFTER_TC * (t_end - t_start))
    if push.any():
        out["propulsion"] = at_other[2] - float(angles[push, 2].min())
    pitch = pelvis_pitch_from_foot_flat(t, angles, t_start, t_tc)
    if math.isfinite(pitch):
        out["trailing_limb_angle"] = trailing_limb_angle(*at_other, pitch, lengths)
    return out


def paretic_ratio(paretic: Sequence[float], other: Sequence[float]) -> float:
    """mean(``paretic``) / mean(``other``); NaN until both have a value (or the other's mean is 0)."""
    if not paretic or not other:
        return math.nan
    den = sum(other) / len(other)
    return (sum(paretic) / len(paretic)) / den if den else math.nan
