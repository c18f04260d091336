"""Periodic joint-angle patterns of level walking for the simulator (core/simulator.py).

The sagittal hip and knee curves are Fourier series (7 harmonics) fitted here to key points of textbook
normal gait (EXT: typical adult curves, e.g. Perry, Winter): hip +30° at initial contact (IC), -10° near
50 %, +34° in late swing; knee 5° at IC, ~18° loading peak, ~38° at terminal contact (TC), ~60° peak in
swing. Frontal/transverse components are a few degrees. The foot's world pitch (toe up positive) is a
C² piecewise quintic with an exactly flat (0°) foot from 10 % to 35 % so a rolling heel → flat → toe contact
model keeps the stance foot still: toe-up ~16° at IC (maximum 17° just before IC), toe-down ~-61° at TC and a
minimum (-68°) just after TC. The ankle angle is whatever joins the shank to that foot.

All curves are defined on a normalised cycle ``u`` with TC at 0.6; an actual stance fraction is mapped by the
smooth monotone warp ``u = p + c sin(2πp)/(2π)`` (valid for stance fractions 0.56-0.75).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

DEG = np.pi / 180.0
NOMINAL_STANCE = 0.6
MIN_STANCE, MAX_STANCE = 0.56, 0.75
_HARMONICS = 7


def smootherstep(x: np.ndarray | float) -> np.ndarray:
    """C² ramp 0→1 on [0, 1] (6x⁵ - 15x⁴ + 10x³), clipped outside."""
    x = np.clip(np.asarray(x, dtype=float), 0.0, 1.0)
    return x * x * x * (x * (6.0 * x - 15.0) + 10.0)


def window(t: np.ndarray, duration: float, ramp: float) -> np.ndarray:
    """C² envelope on [0, duration]: rises over ``ramp`` s, falls over the last ``ramp`` s."""
    return smootherstep(t / ramp) * smootherstep((duration - t) / ramp)


class PeriodicCurve:
    """Truncated Fourier series through periodic key points ``[(u, value)]`` (u in [0, 1))."""

    def __init__(self, keypoints: list[tuple[float, float]], harmonics: int = _HARMONICS) -> None:
        u = np.array([k[0] for k in keypoints] + [1.0])
        v = np.array([k[1] for k in keypoints] + [keypoints[0][1]])
        dense_u = np.arange(256) / 256.0
        spectrum = np.fft.rfft(CubicSpline(u, v, bc_type="periodic")(dense_u)) / 256.0
        self.mean = float(spectrum[0].real)
        self._coef = 2.0 * spectrum[1 : harmonics + 1]
        self._k = np.arange(1, harmonics + 1)

    def __call__(self, u: np.ndarray) -> np.ndarray:
        arg = 2.0 * np.pi * np.asarray(u, dtype=float)[..., None] * self._k
        return self.mean + np.sum(self._coef.real * np.cos(arg) - self._coef.imag * np.sin(arg), axis=-1)


class QuinticKnots:
    """Periodic C² piecewise quintic through knots ``[(u, value, slope)]`` with zero curvature at knots."""

    def __init__(self, knots: list[tuple[float, float, float]]) -> None:
        self.u = np.array([k[0] for k in knots] + [knots[0][0] + 1.0])
        self.v = np.array([k[1] for k in knots] + [knots[0][1]])
        self.d = np.array([k[2] for k in knots] + [knots[0][2]])

    def __call__(self, u: np.ndarray) -> np.ndarray:
        u = np.asarray(u, dtype=float)
        u = self.u[0] + np.mod(u - self.u[0], 1.0)
        i = np.clip(np.searchsorted(self.u, u, side="right") - 1, 0, len(self.u) - 2)
        h = self.u[i + 1] - self.u[i]
        s = (u - self.u[i]) / h
        s2, s3 = s * s, s * s * s
        h00 = 1 - 10 * s3 + 15 * s3 * s - 6 * s3 * s2
        h01 = 1 - h00
        h10 = s - 6 * s3 + 8 * s3 * s - 3 * s3 * s2
        h11 = -4 * s3 + 7 * s3 * s - 3 * s3 * s2
        return h00 * self.v[i] + h01 * self.v[i + 1] + h * (h10 * self.d[i] + h11 * self.d[i + 1])


# Key points (normalised cycle u, degrees).
_HIP_FLEXION = [(0.0, 30), (0.1, 26), (0.3, 6), (0.5, -10), (0.6, -3), (0.72, 16), (0.87, 34), (0.95, 32)]
_KNEE_FLEXION = [(0.0, 5), (0.06, 13), (0.15, 18), (0.3, 9), (0.42, 6), (0.5, 14), (0.6, 38), (0.7, 58),
                 (0.74, 60), (0.82, 48), (0.9, 22), (0.97, 4)]
_HIP_ADDUCTION = [(0.0, 1), (0.15, 6), (0.45, 3), (0.6, -3), (0.72, -6), (0.9, -2)]
_HIP_INTERNAL = [(0.0, 3), (0.3, 1), (0.55, -4), (0.8, 2)]
_KNEE_ADDUCTION = [(0.0, 0), (0.2, 2), (0.5, 1), (0.72, -2)]
_KNEE_INTERNAL = [(0.0, -2), (0.25, 4), (0.6, 0), (0.8, -5)]
# Foot world pitch (u, deg, deg per cycle): max before IC, flat 0.10-0.35, toe-down through TC.
_FOOT_PITCH = [(0.10, 0, 0), (0.28, 0, 0), (0.45, -16, -190), (0.60, -61, -230), (0.66, -68, 0),
               (0.80, -30, 330), (0.97, 17, 0)]
_PELVIS_TILT = -8.0  # deg, mean anterior tilt while walking (the standing posture defines 0)
_TRUNK_LEAN = 2.0  # deg, chest forward of vertical while walking


@dataclass(frozen=True)
class GaitPattern:
    """Scales of the normal pattern: ``hip_range``/``knee_range``/``foot_range`` scale the excursion about
    the curve mean, ``frontal_range`` the frontal/transverse components (a slow "pathological" gait uses
    values < 1)."""

    stance_fraction: float = NOMINAL_STANCE
    hip_range: float = 1.0
    knee_range: float = 1.0
    foot_range: float = 1.0
    frontal_range: float = 1.0


PATHOLOGIES: dict[str, dict[str, float]] = {
    # slow hemiparetic-like pattern: small sagittal ranges (both legs, for simplicity)
    "slow": {"hip_range": 0.6, "knee_range": 0.55, "foot_range": 0.6, "frontal_range": 0.7},
}

_CURVES = {
    "hip_flexion": PeriodicCurve(_HIP_FLEXION),
    "knee_flexion": PeriodicCurve(_KNEE_FLEXION),
    "hip_adduction": PeriodicCurve(_HIP_ADDUCTION),
    "hip_internal_rotation": PeriodicCurve(_HIP_INTERNAL),
    "knee_adduction": PeriodicCurve(_KNEE_ADDUCTION),
    "knee_internal_rotation": PeriodicCurve(_KNEE_INTERNAL),
}
_FOOT = QuinticKnots([(u, v, d) for u, v, d in _FOOT_PITCH])


def warp(phase: np.ndarray, stance_fraction: float) -> np.ndarray:
    """Normalised cycle ``u`` (TC at 0.6) of the gait phase ``phase`` (IC at integers, TC at stance)."""
    if not MIN_STANCE <= stance_fraction <= MAX_STANCE:
        raise ValueError(f"stance_fraction {stance_fraction} outside [{MIN_STANCE}, {MAX_STANCE}]")
    p = np.mod(phase, 1.0)
    s = np.sin(2.0 * np.pi * stance_fraction)
    c = 0.0 if abs(stance_fraction - NOMINAL_STANCE) < 1e-12 else (
        (NOMINAL_STANCE - stance_fraction) * 2.0 * np.pi / s)
    return p + c * np.sin(2.0 * np.pi * p) / (2.0 * np.pi)


def leg_angles(phase: np.ndarray, pattern: GaitPattern) -> dict[str, np.ndarray]:
    """Clinical joint angles (rad) of one leg and its foot world pitch ``foot_pitch`` (rad)."""
    u = warp(phase, pattern.stance_fraction)
    out: dict[str, np.ndarray] = {}
    for name, curve in _CURVES.items():
        scale = pattern.frontal_range
        if name == "hip_flexion":
            scale = pattern.hip_range
        elif name == "knee_flexion":
            scale = pattern.knee_range
        out[name] = DEG * (curve.mean + scale * (curve(u) - curve.mean))
    out["foot_pitch"] = DEG * pattern.foot_range * _FOOT(u)
    return out


def pelvis_angles(phase_left: np.ndarray, pattern: GaitPattern) -> dict[str, np.ndarray]:
    """Pelvis (tilt about z [+ = posterior], obliquity about x, rotation about y) in rad over the cycle,
    and the chest flexion relative to the pelvis that keeps the trunk nearly upright.

    The pelvis tilts 8° forward while walking (so the thigh swings about ±20° from vertical for the hip's
    +30°..-10°), the swing side drops (obliquity) and the leading side is forward (rotation) at each IC.
    """
    p = np.asarray(phase_left, dtype=float)
    k = pattern.frontal_range * DEG
    return {
        "pelvis_tilt": _PELVIS_TILT * DEG + k * 1.5 * np.cos(4.0 * np.pi * (p - 0.1)),
        "chest_flexion": np.full_like(p, (_PELVIS_TILT + _TRUNK_LEAN) * DEG),
        "pelvis_obliquity": -k * 4.0 * np.sin(2.0 * np.pi * (p - 0.35)),
        "pelvis_rotation": -k * 5.0 * np.cos(2.0 * np.pi * p),
    }


def contact_weight(phase: np.ndarray, stance_fraction: float) -> np.ndarray:
    """Share (0..1) of the body weight on this foot: 1 in single support, 0 in swing, C² in double support."""
    p = np.mod(phase, 1.0)
    ds = stance_fraction - 0.5
    rise = smootherstep(p / ds)
    fall = 1.0 - smootherstep((p - 0.5) / ds)
    return np.where(p < stance_fraction, np.minimum(rise, fall), 0.0)
