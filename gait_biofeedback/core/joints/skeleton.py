"""Stick-figure geometry of the lower body from segment orientations (for the ``skeleton`` markers).

EXT: a rigid-link model with the pelvis origin (mid-hip point) at the world origin. Hip centres at
±``hip_width_m``/2 along the pelvis z (right), knee = hip + R_thigh (0, −thigh, 0), ankle = knee +
R_shank (0, −shank, 0), toe = ankle + R_foot (toe, −ankle_height_m, 0); segment→world orientations.
"""

from __future__ import annotations

import numpy as np

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.body import BodyDimensions
from gait_biofeedback.core.segments import SIDES


def stick_figure(orientations: dict[str, np.ndarray], lengths: BodyDimensions | None = None
                 ) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """[(segment, start point, end point)] in world coordinates (m) of the segments available.

    Without a pelvis orientation the pelvis is taken upright facing +x (world), so the legs still draw.
    """
    lengths = lengths or BodyDimensions()
    pelvis = np.asarray(orientations.get("pelvis", quat.IDENTITY), dtype=float)
    lines: list[tuple[str, np.ndarray, np.ndarray]] = []
    origin = np.zeros(3)
    if "chest" in orientations:
        trunk = np.array([0.0, lengths.trunk_length_m, 0.0])
        lines.append(("chest", origin, quat.rotate(np.asarray(orientations["chest"], dtype=float), trunk)))
    for side in SIDES:
        sign = 1.0 if side == "right" else -1.0
        hip = quat.rotate(pelvis, np.array([0.0, 0.0, sign * lengths.hip_width_m / 2]))
        lines.append(("pelvis", origin, hip))
        chain = (("thigh", np.array([0.0, -lengths.thigh_length_m, 0.0])),
                 ("shank", np.array([0.0, -lengths.shank_length_m, 0.0])),
                 ("foot", np.array([lengths.foot_length_m, -lengths.ankle_height_m, 0.0])))
        start = hip
        for part, vector in chain:
            seg = f"{side}_{part}"
            if seg not in orientations:
                break
            end = start + quat.rotate(np.asarray(orientations[seg], dtype=float), vector)
            lines.append((seg, start, end))
            start = end
    return lines
