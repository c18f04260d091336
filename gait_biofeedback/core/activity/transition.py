"""Stand-to-sit / sit-to-stand window analysis (thesis §7.2.5, Eq 55–57; spec gait.md §3.4).

Runs once per trunk-inclination excursion, on the buffered body-frame accelerations around it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gait_biofeedback.core.activity.signal import STANDARD_GRAVITY, zero_phase_gravity

# Tolerance for "θ has reached its minimum" when bounding [t1, t2]: within 1 rad-degree or 10 % of
# the excursion, whichever is larger (choice; the thesis's "nearest local minima" with a margin so a
# flat plateau does not stretch the window).
WINDOW_TOLERANCE_FRACTION = 0.10
WINDOW_TOLERANCE_RAD = np.radians(1.0)


@dataclass(frozen=True)
class SitStandWindow:
    """Result of one candidate: [t1, t2], instant, chest height change ΔY and the SVM score."""

    t1: float
    t2: float
    instant: float
    delta_height_m: float
    svm_score: float  # 2·C(t_mid) − C(t2), C = cumulative ∫SVM from t1 (m/s); < 0 → stand-to-sit


def analyse_sit_stand(
    times: np.ndarray, acc_body: np.ndarray, rate_hz: float, t_peak: float
) -> SitStandWindow | None:
    """Bound, measure and score one θ excursion (thesis §7.2.5; READINGs gait.md §3.4, §6 27/29).

    - θ and GA are recomputed zero-phase over the buffer, so t1/t2 are not lagged by the causal GA.
    - t1/t2: the nearest θ minima before/after the peak (READING 29); the instant is their mid-point.
    - ΔY (Eq 55–56, READING 27): raw acceleration projected on the GA direction (the 3-D form of
      Eq 55, exact for any lean direction), minus g, its mean removed over [t1, t2], integrated twice.
    - SVM (Eq 57) from GA; the thesis classifies by the sign of its cumulative integral at the
      instant. READING: we use C(t_mid) − (C(t2) − C(t_mid)), the first half minus the second half,
      which has the same sign for the thesis's patterns and cancels a constant SVM offset (gain
      error of an uncalibrated sensor).
    """
    if len(times) < int(2 * rate_hz):
        return None
    ga = zero_phase_gravity(acc_body, rate_hz)
    ga_norm = np.linalg.norm(ga, axis=1)
    theta = np.arccos(np.clip(ga[:, 1] / STANDARD_GRAVITY, -1.0, 1.0))
    near = np.flatnonzero(np.abs(times - t_peak) <= 1.5)
    if near.size == 0:
        return None
    k_peak = near[np.argmax(theta[near])]
    before, after = theta[: k_peak + 1], theta[k_peak:]
    v1, v2 = before.min(), after.min()
    tol1 = max(WINDOW_TOLERANCE_RAD, WINDOW_TOLERANCE_FRACTION * (theta[k_peak] - v1))
    tol2 = max(WINDOW_TOLERANCE_RAD, WINDOW_TOLERANCE_FRACTION * (theta[k_peak] - v2))
    k1 = int(np.flatnonzero(before <= v1 + tol1)[-1])
    k2 = k_peak + int(np.flatnonzero(after <= v2 + tol2)[0])
    if k2 - k1 < 3:
        return None
    dt = 1.0 / rate_hz
    seg = slice(k1, k2 + 1)
    vertical = np.einsum("ij,ij->i", acc_body[seg], ga[seg] / ga_norm[seg, None]) - STANDARD_GRAVITY
    vertical -= vertical.mean()
    velocity = np.cumsum(vertical) * dt
    delta_height = float(np.sum(velocity) * dt)
    svm_cumulative = np.cumsum(ga_norm[seg] - STANDARD_GRAVITY) * dt
    k_mid = (k2 - k1) // 2
    score = float(2.0 * svm_cumulative[k_mid] - svm_cumulative[-1])
    t1, t2 = float(times[k1]), float(times[k2])
    return SitStandWindow(t1, t2, 0.5 * (t1 + t2), delta_height, score)
