"""Mamdani fuzzy gain regulation (VST3, thesis §4.2.2.2; orientation.md §3.4) and its SISO form.

Each variable has three membership functions defined by 8 numbers ``(L1, L2, M1, M2, M3, M4, H1, H2)``:
L = ``zmf(L1, L2)`` (falling), M = ``pimf(M1, M2, M3, M4)``, H = ``smf(H1, H2)`` (rising), MATLAB's
spline-based shapes. READING (orientation.md §3.4, §12 item 27): the thesis text calls L "S-shaped"
and H "Z-shaped", but its seven ordering constraints (L before M before H) only make sense with the
falling function for L, so that is what is used. :func:`ordered` enforces the constraints in the
thesis' order (§4.2.3): L2 ≥ L1, L2 ≥ M1, M2 ≥ M1, M3 ≥ M2, M4 ≥ M3, M4 ≥ H1, H2 ≥ H1.

Operators (thesis): AND = min, OR = max, implication = min (truncation), aggregation = max,
defuzzification = centroid, here over ``GRID`` points spanning the output's parameters (the output
universe is [min, max] of its 8 numbers). When no rule fires, the previous output is kept (READING:
MATLAB returns the middle of the universe; keeping the last value is the safer choice in a filter).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

import numpy as np

from gait_biofeedback.core.jit import fast

GRID = 101


def ordered(params: Sequence[float]) -> tuple[float, ...]:
    """The 8 MF parameters with the thesis' seven ordering constraints applied (§4.2.3, in order)."""
    if len(params) != 8:
        raise ValueError(
            f"a fuzzy variable needs 8 numbers (L1, L2, M1, M2, M3, M4, H1, H2), got {len(params)}"
        )
    l1, l2, m1, m2, m3, m4, h1, h2 = (float(v) for v in params)
    if not all(np.isfinite([l1, l2, m1, m2, m3, m4, h1, h2])):
        raise ValueError(f"fuzzy membership parameters must be finite, got {list(params)}")
    l2 = max(l2, l1)
    l2 = max(l2, m1)
    m2 = max(m2, m1)
    m3 = max(m3, m2)
    m4 = max(m4, m3)
    m4 = max(m4, h1)
    h2 = max(h2, h1)
    return (l1, l2, m1, m2, m3, m4, h1, h2)


def zmf(x: float, a: float, b: float) -> float:
    """MATLAB ``zmf``: 1 up to a, spline down to 0 at b (a step at a when a == b)."""
    if x <= a:
        return 1.0
    if x >= b:
        return 0.0
    mid = 0.5 * (a + b)
    u = (x - a) / (b - a)
    if x <= mid:
        return 1.0 - 2.0 * u * u
    v = (x - b) / (b - a)
    return 2.0 * v * v


def smf(x: float, a: float, b: float) -> float:
    """MATLAB ``smf`` = 1 − ``zmf``."""
    return 1.0 - zmf(x, a, b)


def memberships(x: float, p: Sequence[float]) -> tuple[float, float, float]:
    """(μ_L, μ_M, μ_H) of ``x`` for ordered parameters ``p``; M = ``smf(M1, M2)·zmf(M3, M4)``."""
    return (zmf(x, p[0], p[1]), smf(x, p[2], p[3]) * zmf(x, p[4], p[5]), smf(x, p[6], p[7]))


def _curves(p: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = min(p), max(p)
    y = np.linspace(lo, hi, GRID) if hi > lo else np.full(GRID, lo)
    return y, np.array([memberships(v, p) for v in y]).T.copy()


def centroid(
    y: np.ndarray, curves: np.ndarray, w_low: float, w_mid: float, w_high: float, last: float
) -> float:
    """Centroid of max(min(w_L, L), min(w_M, M), min(w_H, H)) sampled at ``y`` (``curves``: 3 × len(y));
    ``last`` when no rule fires. A numba kernel (:mod:`gait_biofeedback.core.jit`)."""
    num = 0.0
    den = 0.0
    for k in range(y.shape[0]):
        a = min(w_low, curves[0, k])
        b = min(w_mid, curves[1, k])
        c = min(w_high, curves[2, k])
        if b > a:
            a = b
        if c > a:
            a = c
        num += a * y[k]
        den += a
    return num / den if den > 0.0 else last


def siso(
    values: np.ndarray, inputs: np.ndarray, y: np.ndarray, curves: np.ndarray, reverse: bool, last: np.ndarray
) -> None:
    """Independent single-input systems (rows): memberships of ``values[i]`` in ``inputs[i]`` fire the
    output sets L, M, H (H, M, L with ``reverse``); centroids into ``last`` (kept where nothing fires)."""
    for i in range(values.shape[0]):
        lo, mid, hi = memberships(values[i], inputs[i])
        if reverse:
            lo, hi = hi, lo
        last[i] = centroid(y[i], curves[i], lo, mid, hi, last[i])


class FuzzyOutput:
    """One output variable: its sets sampled on ``GRID`` points, defuzzified by centroid."""

    def __init__(self, params: Sequence[float]) -> None:
        self.y, self.curves = _curves(ordered(params))
        self.last = float(self.y.mean())
        self._centroid = fast(sys.modules[__name__], "centroid", (self.y, self.curves, 0.0, 1.0, 0.0, 0.0))

    def defuzzify(self, w_low: float, w_mid: float, w_high: float) -> float:
        """Output value for the strengths of the rules whose consequents are L, M and H."""
        self.last = self._centroid(self.y, self.curves, w_low, w_mid, w_high, self.last)
        return self.last


class SharedGainFIS:
    """Two inputs (Δ_A, Δ_M) → one gain (Madgwick β, Mahony k_p), the thesis' three rules (§4.2.2.2):
    acc L AND mag L → gain H; acc M AND mag M → gain M; acc H OR mag H → gain L.
    Without a magnetometer the mag antecedents drop out (each rule on the accelerometer alone)."""

    def __init__(self, acc: Sequence[float], mag: Sequence[float], gain: Sequence[float]) -> None:
        self.acc = ordered(acc)
        self.mag = ordered(mag)
        self.out = FuzzyOutput(gain)
        self.firing = (0.0, 0.0, 0.0)

    def __call__(self, dev_acc: float, dev_mag: float | None) -> float:
        la, ma, ha = memberships(dev_acc, self.acc)
        if dev_mag is None:
            w_high, w_mid, w_low = la, ma, ha
        else:
            lm, mm, hm = memberships(dev_mag, self.mag)
            w_high, w_mid, w_low = min(la, lm), min(ma, mm), max(ha, hm)
        self.firing = (w_low, w_mid, w_high)
        return self.out.defuzzify(w_low, w_mid, w_high)


class SisoFIS:
    """Independent single-input systems, one rule set each (L → c_L, M → c_M, H → c_H).

    ``consequents``: ``"LMH"`` (larger deviation → larger noise σ, the READING for the Kalman filters'
    σ_G, σ_A, σ_M, orientation.md §3.4) or ``"HML"`` (IAE: a negative discrepancy → increase Q,
    ≅ 0 → no change, positive → decrease, §3.5)."""

    def __init__(
        self, inputs: Sequence[Sequence[float]], outputs: Sequence[Sequence[float]], consequents: str = "LMH"
    ) -> None:
        if len(inputs) != len(outputs):
            raise ValueError("one output variable per input variable")
        if consequents not in ("LMH", "HML"):
            raise ValueError(f"consequents must be 'LMH' or 'HML', got {consequents!r}")
        self.inputs = np.array([ordered(p) for p in inputs])
        outs = [FuzzyOutput(p) for p in outputs]
        self.y = np.stack([o.y for o in outs])
        self.curves = np.stack([o.curves for o in outs])
        self.last = np.array([o.last for o in outs])
        self._reverse = consequents == "HML"
        self._kernel = fast(
            sys.modules[__name__],
            "siso",
            (np.zeros(len(outs)), self.inputs, self.y, self.curves, False, self.last.copy()),
            ("zmf", "smf", "memberships", "centroid"),
        )

    def __call__(self, values: Sequence[float]) -> list[float]:
        """Output values (one per system) for the input ``values``."""
        self._kernel(
            np.array(values, dtype=float), self.inputs, self.y, self.curves, self._reverse, self.last
        )
        return self.last.tolist()
