"""True per-stride values of the stroke quantities of a simulated session (docs/guide/stroke.md).

Computed from the simulator's exact geometry (segment positions and orientations, true joint angles,
true IC/TC), never from the estimators, with the same definitions as the biofeedback evaluator
(:mod:`gait_biofeedback.core.biofeedback.stroke`), for the stride of side S from its IC (``t0``) to its
next IC (``t1``), with the other foot's IC ``t_o`` and S's TC ``t_c`` inside it:

* ``trailing_limb_angle`` (rad): angle between the vertical and the line from S's hip joint centre to its
  metatarsal heads (``toe_length`` ahead of the ankle, ``ankle_height`` below it, in the foot frame),
  projected on the pelvis's sagittal plane (vertical and the pelvis's horizontal forward direction), at
  ``t_o``; positive when the foot is behind the hip.
* ``propulsion`` (rad): ankle plantarflexion from ``t_o`` to the least dorsiflexion in
  [``t_o``, ``t_c`` + 10 % of the stride time].
* ``knee_hyperextension_stance`` (rad): the least knee flexion from 1/6 to 5/6 of the stance time.
* ``foot_strike_angle`` (rad): the foot's pitch (its x axis above the horizontal) at ``t1`` (the strike
  that ends the stride's swing, as the foot trajectory's ``foot_angle_ic``).
* ``swing_foot_clearance`` (m): the foot sensor's highest position from ``t_c`` to ``t1`` above its
  position at foot flat (``t0`` + 20 % of the stride time).
* ``step_length`` (m): forward distance (along the pelvis heading) from the other ankle at its foot flat
  to S's ankle at S's next foot flat (``t1`` + 20 %), the step that ends at ``t1``.
* ``stance_time`` (s): ``t_c - t0``.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.segments import SIDES
from gait_biofeedback.sim.simulator import SimulatedSession

FLAT_AT = 0.2  # fraction of the stride after an IC where the simulated foot is flat (kinematics: 0.10-0.30)


def _at(t: np.ndarray, values: np.ndarray, when: float) -> np.ndarray:
    """``values`` (N, ...) linearly interpolated at ``when``."""
    k = int(np.clip(np.searchsorted(t, when) - 1, 0, len(t) - 2))
    f = (when - t[k]) / (t[k + 1] - t[k])
    return values[k] + f * (values[k + 1] - values[k])


def stride_truth(session: SimulatedSession) -> list[dict[str, float | str]]:
    """One dict per stride of each side whose IC, TC, other IC and next IC are all true events
    (``side``, ``t_start``, ``t_end`` s, and the quantities of the module docstring)."""
    truth = session.truth
    cfg = session.config
    t = truth.t
    out: list[dict[str, float | str]] = []
    pelvis_x = quat.as_matrix(truth.segment_orientation["pelvis"])[:, :, 0]
    forward = pelvis_x * np.array([1.0, 1.0, 0.0])
    forward /= np.linalg.norm(forward, axis=1, keepdims=True)
    for side in SIDES:
        other = SIDES[1 - SIDES.index(side)]
        ics, tcs, other_ics = (np.asarray(x, dtype=float) for x in (
            truth.initial_contacts[side], truth.terminal_contacts[side], truth.initial_contacts[other]))
        hip, ankle = truth.segment_position[f"{side}_thigh"], truth.segment_position[f"{side}_foot"]
        foot_r = quat.as_matrix(truth.segment_orientation[f"{side}_foot"])
        toe = ankle + foot_r[:, :, 0] * cfg.toe_length - foot_r[:, :, 1] * cfg.ankle_height
        knee = truth.joint_angles[f"{side}_knee_flexion"]
        dorsi = truth.joint_angles[f"{side}_ankle_dorsiflexion"]
        sensor_z = truth.sensor_position[f"{side}_foot"][:, 2]
        for t0, t1 in itertools.pairwise(ics):
            tc = tcs[(tcs > t0) & (tcs < t1)]
            to = other_ics[(other_ics > t0) & (other_ics < t1)]
            before = other_ics[other_ics < t1]
            if len(tc) != 1 or len(to) != 1 or t1 + FLAT_AT * (t1 - t0) > t[-1] - 0.01:
                continue
            tc, to, stride = float(tc[0]), float(to[0]), t1 - t0
            fwd = _at(t, forward, to)
            d = _at(t, hip, to) - _at(t, toe, to)
            tla = math.atan2(float(d @ fwd), float(d[2]))
            push = (t >= to) & (t <= tc + 0.1 * stride)
            mid = (t >= t0 + (tc - t0) / 6) & (t <= t0 + 5 * (tc - t0) / 6)
            swing = (t >= tc) & (t <= t1)
            x_axis = _at(t, foot_r[:, :, 0], t1)
            flat_t1, flat_other = t1 + FLAT_AT * stride, float(before[-1]) + FLAT_AT * stride
            other_ankle = truth.segment_position[f"{other}_foot"]
            step = float((_at(t, ankle, flat_t1) - _at(t, other_ankle, flat_other)) @ _at(t, forward, t1))
            out.append({
                "side": side, "t_start": float(t0), "t_end": float(t1),
                "trailing_limb_angle": tla,
                "propulsion": float(np.interp(to, t, dorsi) - dorsi[push].min()),
                "knee_hyperextension_stance": float(knee[mid].min()),
                "foot_strike_angle": math.atan2(float(x_axis[2]), float(np.hypot(x_axis[0], x_axis[1]))),
                "swing_foot_clearance": float(sensor_z[swing].max() - np.interp(t0 + FLAT_AT * stride, t,
                                                                                sensor_z)),
                "step_length": step,
                "stance_time": tc - float(t0),
            })
    return sorted(out, key=lambda r: float(r["t_end"]))
