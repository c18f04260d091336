"""Spatial parameters of one stride from a smoothed foot trajectory (gait.md §4.8, EXT).

Suh 2014 reports no stride parameter; these definitions are the project's (``docs/benchmarks/spatial.md``,
*Spatial parameters*):

- A stride runs from one zero-velocity interval (stance) to the next. Each stance's position is the
  mean position over its samples, and its orientation is that of the sample next to the swing.
- ``stride_length``: horizontal distance between the two stance positions, m.
- ``stride_time``: from the first stance's start to the next stance's start (foot flat to foot flat).
  NaN when the first stance is longer than ``MAX_STANCE_S``: the walk started from standing, and
  that stride has no cycle time. ``gait_speed`` = length / time, m/s.
- ``max_sensor_height``: the highest sensor position in the swing, above the first stance's, m.
- ``min_toe_clearance``: with a sensor-to-toe lever arm (sensor frame, m), the toe's lowest height
  between the first and last local maxima of its swing height higher than ``MIN_TOE_PEAK_M``, above
  its stance height. NaN without a lever arm, or when the swing has fewer than two such maxima.
- ``foot_angle_ic`` / ``foot_angle_tc``: the foot's pitch about the stride's lateral axis,
  relative to its stance orientation, in rad, positive toes up.
  - Strike (IC): the largest pitch in the swing's second half, relative to the next stance.
  - Push-off (TC): the smallest pitch in its first half, relative to the first stance; negative
    means toes down.
  The zero-velocity intervals start after IC and end before TC, so the extremes of the swing
  next to them are taken instead of the samples at the events.
- ``turning_angle``: the heading change of the foot from stance to stance, rad, positive left
  (about world z).
- ``lateral_excursion``: the swing's largest horizontal distance from the line joining the stances,
  m, positive left.
- Angles need a direction of travel: for strides shorter than ``MIN_LENGTH_M`` they are NaN.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from gait_biofeedback.core import quaternion as quat

MAX_STANCE_S = 1.5  # s: a longer stance is standing, and the stride after it has no cycle time
MIN_LENGTH_M = 0.1  # m: shorter strides (stepping on the spot) have no direction for the angles
LOST_FLAG = "lost samples interpolated"  # informational: within max_swing_lost_s, max_stance_gap_s
MIN_TOE_PEAK_M = 0.01  # m: a toe-height maximum lower than this is the toe still rolling on the floor


@dataclass(frozen=True)
class SpatialStride:
    """One stride's spatial parameters (SI units, NaN when unknown); indices are sample numbers of
    the recording (``stance_start``: first sample of the first stance, ``foot_off``: its last,
    ``foot_flat``: first sample of the next stance, ``end``: the last sample used); live strides
    also carry the stamps (int ns) of ``foot_off`` and ``foot_flat``."""

    stance_start: int
    foot_off: int
    foot_flat: int
    end: int
    stride_length: float
    stride_time: float
    gait_speed: float
    max_sensor_height: float
    min_toe_clearance: float
    foot_angle_ic: float
    foot_angle_tc: float
    turning_angle: float
    lateral_excursion: float
    flags: tuple[str, ...] = field(default=())
    foot_off_ns: int | None = None
    foot_flat_ns: int | None = None


UNKNOWN_VALUES = ("stride_length", "gait_speed", "max_sensor_height", "min_toe_clearance", "foot_angle_ic",
                  "foot_angle_tc", "turning_angle", "lateral_excursion")


def unknown(stride: SpatialStride, why: str) -> SpatialStride:
    """``stride`` with NaN spatial values and the flag ``why`` added (its samples and timing kept)."""
    return replace(stride, flags=(*stride.flags, why), **dict.fromkeys(UNKNOWN_VALUES, math.nan))


def heading_change(q_from: np.ndarray, q_to: np.ndarray) -> float:
    """The turn about the world vertical (rad, positive left) from orientation ``q_from`` to ``q_to``."""
    m = quat.as_matrix(quat.multiply(q_to, quat.conjugate(q_from)))
    return math.atan2(m[1, 0] - m[0, 1], m[0, 0] + m[1, 1])


def _pitch(q: np.ndarray, q_ref: np.ndarray, lateral: np.ndarray) -> np.ndarray:
    """Toes-up angle of ``q`` relative to ``q_ref`` about the world horizontal ``lateral`` (left)."""
    rotvec = quat.as_rotvec(quat.multiply(q, quat.conjugate(q_ref)))
    return -(rotvec[..., :2] @ lateral)


def _min_between_maxima(height: np.ndarray) -> float:
    """Lowest ``height`` between its first and last local maxima above ``MIN_TOE_PEAK_M``."""
    inner = height[1:-1]
    peaks = np.flatnonzero((inner > height[:-2]) & (inner >= height[2:]) & (inner > MIN_TOE_PEAK_M)) + 1
    if len(peaks) < 2:
        return math.nan
    return float(height[peaks[0]:peaks[-1] + 1].min())


def _foot_angles(swing: np.ndarray, q_strike_ref: np.ndarray, lateral: np.ndarray) -> tuple[float, float]:
    """(``foot_angle_ic``, ``foot_angle_tc``) of the swing's orientations, foot-off first (module
    docstring): the largest pitch of its second half relative to ``q_strike_ref``, the smallest of its
    first half relative to its first sample."""
    mid = (len(swing) - 1) // 2
    return (float(_pitch(swing[mid:], q_strike_ref, lateral).max()),
            float(_pitch(swing[:mid + 1], swing[0], lateral).min()))


SWING_VALUES = ("max_sensor_height", "min_toe_clearance", "foot_angle_ic", "foot_angle_tc", "turning_angle",
                "lateral_excursion")
"""The values :func:`swing_so_far` estimates before the stride closes."""


def _toe_clearance(orientation: np.ndarray, position: np.ndarray, stance: slice, swing: slice,
                   toe_lever_arm_m: np.ndarray | None) -> float:
    """``min_toe_clearance`` (module docstring) of the ``swing`` samples above the ``stance``'s mean toe
    height; NaN without a lever arm."""
    if toe_lever_arm_m is None or len(toe_lever_arm_m) != 3:
        return math.nan
    toe = position[:, 2] + (quat.as_matrix(orientation) @ np.asarray(toe_lever_arm_m, float))[:, 2]
    return _min_between_maxima(toe[swing] - float(toe[stance].mean()))


def _lateral_excursion(position: np.ndarray, start: np.ndarray, lateral: np.ndarray) -> float:
    side = (position[:, :2] - start[:2]) @ lateral
    return float(side[np.argmax(np.abs(side))])


def swing_so_far(orientation: np.ndarray, position: np.ndarray, first: tuple[int, int],
                 toe_lever_arm_m: np.ndarray | None = None) -> dict[str, float]:
    """``SWING_VALUES`` of a swing still in progress, as :func:`stride_parameters` defines them, from
    the samples ``first`` (the stance before it, indices as there) to the last one. EXT, what is not
    known yet is taken from what is: the direction of travel (for the angles and the lateral excursion)
    is the one so far; the strike's pitch is relative to the first stance (the next one has not begun;
    on level ground the two stances' pitches agree); the turning angle is the heading change from the
    foot-off to the last sample (the foot hardly turns about the vertical from the IC to foot flat).
    Angles and lateral excursion NaN under ``MIN_LENGTH_M`` of travel."""
    a0, a1 = first
    p_first = position[a0:a1 + 1].mean(axis=0)
    out = dict.fromkeys(SWING_VALUES, math.nan)
    out["max_sensor_height"] = float(position[a1:, 2].max() - p_first[2])
    out["min_toe_clearance"] = _toe_clearance(orientation, position, slice(a0, a1 + 1), slice(a1, None),
                                              toe_lever_arm_m)
    out["turning_angle"] = heading_change(orientation[a1], orientation[-1])
    travel = (position[-1] - p_first)[:2]
    length = float(np.linalg.norm(travel))
    if length >= MIN_LENGTH_M:
        forward = travel / length
        lateral = np.array([-forward[1], forward[0]])
        out["foot_angle_ic"], out["foot_angle_tc"] = _foot_angles(orientation[a1:], orientation[a1], lateral)
        out["lateral_excursion"] = _lateral_excursion(position[a1:], p_first, lateral)
    return out


def stride_parameters(t: np.ndarray, orientation: np.ndarray, position: np.ndarray,
                      first: tuple[int, int], second: tuple[int, int], numbers: list[int],
                      toe_lever_arm_m: np.ndarray | None = None,
                      max_swing_s: float = math.inf) -> SpatialStride:
    """The stride between the stances ``first`` and ``second`` (``(first, last)`` sample, indices into
    ``t``/``orientation``/``position``; ``second`` may be the part of the stance seen so far).
    ``numbers[i]`` is the recording's sample number of index ``i``, as reported. A swing longer than
    ``max_swing_s`` gives NaN values and a flag."""
    a0, a1 = first
    b0, b1 = second
    p_first = position[a0:a1 + 1].mean(axis=0)
    p_second = position[b0:b1 + 1].mean(axis=0)
    travel = (p_second - p_first)[:2]
    length = float(np.linalg.norm(travel))
    standing_before = t[a1] - t[a0] > MAX_STANCE_S
    stride_time = math.nan if standing_before else float(t[b0] - t[a0])
    swing = slice(a1, b0 + 1)
    height = float(position[swing, 2].max() - p_first[2])
    clearance = _toe_clearance(orientation, position, slice(a0, a1 + 1), swing, toe_lever_arm_m)
    flags = ["started from standing"] if standing_before else []
    angle_ic = angle_tc = lateral_excursion = math.nan
    if length >= MIN_LENGTH_M:
        forward = travel / length
        lateral = np.array([-forward[1], forward[0]])
        angle_ic, angle_tc = _foot_angles(orientation[a1:b0 + 1], orientation[b0], lateral)
        lateral_excursion = _lateral_excursion(position[swing], p_first, lateral)
    else:
        flags.append("no direction of travel")
    turning = heading_change(orientation[a1], orientation[b0])
    stride = SpatialStride(
        stance_start=numbers[a0], foot_off=numbers[a1], foot_flat=numbers[b0], end=numbers[b1],
        stride_length=length, stride_time=stride_time, gait_speed=length / stride_time,
        max_sensor_height=height, min_toe_clearance=clearance, foot_angle_ic=angle_ic,
        foot_angle_tc=angle_tc, turning_angle=turning,
        lateral_excursion=lateral_excursion, flags=tuple(flags))
    swing_s = float(t[b0] - t[a1])
    if swing_s > max_swing_s:
        return unknown(stride, f"no stance for {swing_s:.1f} s: spatial values unknown")
    return stride
