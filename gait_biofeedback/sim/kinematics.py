"""Periodic joint-angle patterns of level walking for the simulator (sim/simulator.py).

The sagittal hip and knee curves are Fourier series (7 harmonics) fitted here to key points of textbook
normal gait (EXT: typical adult curves, e.g. Perry, Winter): hip +30° at initial contact (IC), -10° near
50 %, +34° in late swing; knee 5° at IC, ~18° loading peak, ~38° at terminal contact (TC), ~60° peak in
swing. Frontal/transverse components are a few degrees. The foot's world pitch (toe up positive) is a
C² piecewise quintic with an exactly flat (0°) foot from 10 % to 35 % so a rolling heel → flat → toe contact
model keeps the stance foot still: toe-up ~16° at IC (maximum 17° just before IC), toe-down ~-61° at TC and a
minimum (-68°) just after TC. The ankle angle is whatever joins the shank to that foot.

Stair ascent/descent (``stairs_angles``) replace the sagittal hip, knee and foot pitch curves by
stair-gait shapes (EXT: typical adult stair kinematics, e.g. McFadyen & Winter 1988, Riener et al. 2002):
ascent lands with hip ~62° and knee ~58° flexed on a nearly flat foot and extends the stance leg to lift
the body one step; descent lands toe first with a nearly straight knee that flexes to ~85° by TC to lower
the body one step. The trunk leans forward going up.

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
    """Periodic C² piecewise quintic Hermite through knots ``[(u, value, slope[, curvature])]`` (curvature
    = second derivative per cycle², 0 when omitted). A knot with slope 0 and a curvature of the right sign is
    a sharp local extremum, placed exactly at that knot."""

    def __init__(self, knots: list[tuple[float, ...]]) -> None:
        full = [(*k, 0.0)[:4] for k in knots]
        self.u = np.array([k[0] for k in full] + [full[0][0] + 1.0])
        self.v = np.array([k[1] for k in full] + [full[0][1]])
        self.d = np.array([k[2] for k in full] + [full[0][2]])
        self.a = np.array([k[3] for k in full] + [full[0][3]])

    def __call__(self, u: np.ndarray) -> np.ndarray:
        u = np.asarray(u, dtype=float)
        u = self.u[0] + np.mod(u - self.u[0], 1.0)
        i = np.clip(np.searchsorted(self.u, u, side="right") - 1, 0, len(self.u) - 2)
        h = self.u[i + 1] - self.u[i]
        s = (u - self.u[i]) / h
        s2, s3 = s * s, s * s * s
        s4, s5 = s3 * s, s3 * s2
        h00 = 1 - 10 * s3 + 15 * s4 - 6 * s5
        h10 = s - 6 * s3 + 8 * s4 - 3 * s5
        h20 = 0.5 * (s2 - 3 * s3 + 3 * s4 - s5)
        h11 = -4 * s3 + 7 * s4 - 3 * s5
        h21 = 0.5 * (s3 - 2 * s4 + s5)
        return (h00 * self.v[i] + (1 - h00) * self.v[i + 1] + h * (h10 * self.d[i] + h11 * self.d[i + 1])
                + h * h * (h20 * self.a[i] + h21 * self.a[i + 1]))


# Key points (normalised cycle u, degrees).
_HIP_FLEXION = [(0.0, 30), (0.1, 26), (0.3, 6), (0.5, -10), (0.6, -3), (0.72, 16), (0.87, 34), (0.95, 32)]
_KNEE_FLEXION = [(0.0, 5), (0.06, 13), (0.15, 18), (0.3, 9), (0.42, 6), (0.5, 14), (0.6, 38), (0.7, 58),
                 (0.74, 60), (0.82, 48), (0.9, 22), (0.97, 4)]
_HIP_ADDUCTION = [(0.0, 1), (0.15, 6), (0.45, 3), (0.6, -3), (0.72, -6), (0.9, -2)]
_HIP_INTERNAL = [(0.0, 3), (0.3, 1), (0.55, -4), (0.8, 2)]
_KNEE_ADDUCTION = [(0.0, 0), (0.2, 2), (0.5, 1), (0.72, -2)]
_KNEE_INTERNAL = [(0.0, -2), (0.25, 4), (0.6, 0), (0.8, -5)]
# Foot world pitch (u, deg, deg/cycle[, deg/cycle²]): sharp toe-up maximum at IC (u = 0; real foot IMUs with
# motion capture put it at heel strike), heel rocker to flat by 0.10, flat 0.10-0.30, heel rise, toe-down
# -61° at TC and a sharp minimum 0.008 cycle after TC (real: within ~15 ms after toe-off), then a steady rise
# through swing (ankle near neutral, toe clearance >= 2 cm).
_FOOT_PITCH = [(0.0, 22, 0, -5000), (0.10, 0, 0), (0.30, 0, 0), (0.45, -12, -160, -1500), (0.57, -45, -520),
               (0.608, -62, 0, 15000), (0.70, -48, 240), (0.82, -13, 280), (0.91, 10, 190)]
# Stair gait (u, deg); frontal/transverse components stay those of level walking.
_STAIRS_HIP = {
    "up": [(0.0, 62), (0.1, 58), (0.3, 32), (0.5, 12), (0.6, 14), (0.72, 40), (0.85, 66), (0.95, 64)],
    "down": [(0.0, 18), (0.15, 12), (0.35, 10), (0.5, 22), (0.6, 30), (0.75, 36), (0.88, 28), (0.95, 20)]}
_STAIRS_KNEE = {
    "up": [(0.0, 58), (0.08, 55), (0.3, 18), (0.45, 10), (0.6, 20), (0.68, 60), (0.78, 92), (0.88, 78),
           (0.96, 60)],
    "down": [(0.0, 18), (0.1, 24), (0.25, 38), (0.45, 62), (0.6, 80), (0.72, 95), (0.82, 70), (0.92, 30),
             (0.97, 19)]}
# ascent: nearly flat landing, small heel rise; descent: toe-first landing (minimum at IC), heel lowers by
# 0.15. Little knee and foot motion in double support keeps the two legs' geometries together.
_STAIRS_FOOT = {
    "up": [(0.0, 6, 0, -3000), (0.08, 0, 0), (0.35, 0, 0), (0.5, -6, -90), (0.608, -22, 0, 6000),
           (0.8, -4, 80)],
    "down": [(0.0, -16, 0, 3000), (0.15, 0, 0), (0.4, 0, 0), (0.55, -18, -250), (0.62, -32, 0, 8000),
             (0.8, -10, 0, -2000)]}
STAIRS_PELVIS_TILT = {"up": -6.0, "down": 0.0}  # deg, added to the walking pelvis tilt (- = anterior)
STAIRS_TRUNK_LEAN = {"up": 12.0, "down": 4.0}  # deg, chest forward of vertical
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
_FOOT = QuinticKnots(_FOOT_PITCH)
_STAIRS_CURVES = {d: {"hip_flexion": PeriodicCurve(_STAIRS_HIP[d]),
                      "knee_flexion": PeriodicCurve(_STAIRS_KNEE[d]),
                      "foot_pitch": QuinticKnots(_STAIRS_FOOT[d])} for d in ("up", "down")}


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


def pelvis_angles(phase_left: np.ndarray, pattern: GaitPattern, up: np.ndarray | float = 0.0,
                  down: np.ndarray | float = 0.0) -> dict[str, np.ndarray]:
    """Pelvis (tilt about z [+ = posterior], obliquity about x, rotation about y) in rad over the cycle,
    and the chest flexion relative to the pelvis that keeps the trunk nearly upright.

    The pelvis tilts 8° forward while walking (so the thigh swings about ±20° from vertical for the hip's
    +30°..-10°), the swing side drops (obliquity) and the leading side is forward (rotation) at each IC.
    ``up``/``down`` (0..1) blend in stair ascent/descent: more anterior pelvis tilt and trunk lean
    (``STAIRS_PELVIS_TILT``, ``STAIRS_TRUNK_LEAN``).
    """
    p = np.asarray(phase_left, dtype=float)
    k = pattern.frontal_range * DEG
    up = np.asarray(up, dtype=float)
    down = np.asarray(down, dtype=float)
    extra_tilt = up * STAIRS_PELVIS_TILT["up"] + down * STAIRS_PELVIS_TILT["down"]
    lean = _TRUNK_LEAN + up * (STAIRS_TRUNK_LEAN["up"] - _TRUNK_LEAN) + down * (
        STAIRS_TRUNK_LEAN["down"] - _TRUNK_LEAN)
    return {
        "pelvis_tilt": (_PELVIS_TILT + extra_tilt) * DEG + k * 1.5 * np.cos(4.0 * np.pi * (p - 0.1)),
        "chest_flexion": np.broadcast_to((_PELVIS_TILT + extra_tilt + lean) * DEG, p.shape).copy(),
        "pelvis_obliquity": -k * 4.0 * np.sin(2.0 * np.pi * (p - 0.35)),
        "pelvis_rotation": -k * 5.0 * np.cos(2.0 * np.pi * p),
    }


def stairs_angles(phase: np.ndarray, pattern: GaitPattern, direction: str) -> dict[str, np.ndarray]:
    """Sagittal hip/knee flexion and foot world pitch (rad) of stair gait, ``direction`` "up" or "down"
    (the pattern's stance fraction warps the cycle; its range scales are for level walking and unused)."""
    u = warp(phase, pattern.stance_fraction)
    return {name: DEG * curve(u) for name, curve in _STAIRS_CURVES[direction].items()}


def contact_weight(phase: np.ndarray, stance_fraction: float) -> np.ndarray:
    """Share (0..1) of the body weight on this foot: 1 in single support, 0 in swing, C² in double support."""
    p = np.mod(phase, 1.0)
    ds = stance_fraction - 0.5
    rise = smootherstep(p / ds)
    fall = 1.0 - smootherstep((p - 0.5) / ds)
    return np.where(p < stance_fraction, np.minimum(rise, fall), 0.0)
