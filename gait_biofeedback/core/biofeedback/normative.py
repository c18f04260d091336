"""Reference sagittal joint-angle curves of adult level walking for the dashboard (thesis §9.2.5).

The thesis asks for a display of the error between the measured and a "targeted normal" pattern
(ch. 8, §9.2.5, gait.md §5.3) but gives no target curves. This module ships a *coarse reference*:

* Key values (degrees, at % of the stride from initial contact) typed in from the textbook descriptions
  of normal gait by phase: knee and ankle from Perry J., Burnfield J.M., *Gait Analysis: Normal and
  Pathological Function*, 2nd ed., SLACK, 2010 (knee ~5° at IC, ~15-20° loading-response peak, ~5° in
  mid/terminal stance, ~40° at the end of pre-swing, ~60° peak in initial swing, back to ~5° at the end
  of swing; ankle neutral at IC, ~5° plantar flexion in loading response, ~10° dorsiflexion in terminal
  stance, ~20° plantar flexion just after toe off, neutral in mid/terminal swing); hip relative to the
  pelvis as in the laboratory normal data of Kadaba M.P. et al., *J Orthop Res* 8:383-392, 1990 (~30°
  flexion at IC, ~10° extension near 50 % of the stride, ~35° peak flexion in late swing).
* Between the key values: a periodic cubic spline, sampled every 5 % (0, 5, ..., 100 %).

What this is NOT: a digitised mean ± SD table. The shaded band on the dashboard is ``mean ±
tolerance`` with a tolerance the therapist sets in ``config/targets.yaml`` (EXT), not a published
standard deviation. The key values are the commonly quoted round numbers of those sources and must be
checked by the clinician before a patient is trained towards them.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline

DEG = np.pi / 180.0
PERCENT_STEP = 5.0
"""Resolution of the shipped reference curves, % of the stride."""

REFERENCE_SOURCES: tuple[str, ...] = (
    "Perry J, Burnfield JM. Gait Analysis: Normal and Pathological Function. 2nd ed. SLACK; 2010.",
    "Kadaba MP, Ramakrishnan HK, Wootten ME, et al. Repeatability of kinematic, kinetic, and "
    "electromyographic data in normal adult gait. J Orthop Res. 1990;8(3):383-392.",
)

# (percent of stride from IC, degrees); the value at 100 % equals the value at 0 % (periodic).
KEY_VALUES_DEG: dict[str, tuple[tuple[float, float], ...]] = {
    "hip_flexion": ((0, 30), (12, 28), (30, 10), (50, -10), (62, 0), (75, 22), (87, 35), (100, 30)),
    "knee_flexion": ((0, 5), (12, 18), (40, 5), (50, 7), (62, 40), (73, 60), (87, 25), (100, 5)),
    "ankle_dorsiflexion": ((0, 0), (8, -5), (30, 5), (48, 10), (62, -20), (75, -5), (87, 0), (100, 0)),
}
"""Sagittal key values; names match the JointState suffixes (``<side>_<name>``)."""

DEFAULT_TOLERANCE_DEG: dict[str, float] = {"hip_flexion": 7.0, "knee_flexion": 7.0, "ankle_dorsiflexion": 5.0}
"""Half-width of the reference band when config/targets.yaml does not set one (EXT)."""


def percent_grid(step: float = PERCENT_STEP) -> np.ndarray:
    """0, step, ..., 100 (% of the stride)."""
    return np.linspace(0.0, 100.0, round(100.0 / step) + 1)


def reference_curve(name: str, percent: np.ndarray | None = None) -> np.ndarray:
    """Reference curve ``name`` (rad) at ``percent`` (% of the stride; default every 5 %)."""
    if name not in KEY_VALUES_DEG:
        raise ValueError(f"no reference curve {name!r}; known: {sorted(KEY_VALUES_DEG)}")
    x, y = np.array(KEY_VALUES_DEG[name], dtype=float).T
    spline = CubicSpline(x, y, bc_type="periodic")
    p = percent_grid() if percent is None else np.asarray(percent, dtype=float)
    return DEG * spline(np.mod(p, 100.0) if percent is not None else p)


def reference_band(name: str, tolerance: float, percent: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(mean, low, high) in rad of the reference curve ``name`` ± ``tolerance`` (rad)."""
    mean = reference_curve(name, percent)
    return mean, mean - tolerance, mean + tolerance
