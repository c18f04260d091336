"""Guo(2017) fast Kalman filter: a linear KF on the quaternion with a Wahba measurement quaternion.

Thesis §4.2.1 / Fig 11(b), orientation.md §4.3 (the thesis does not restate Guo's equations; this
follows the structure it gives, and the reference paper: Guo, Wu, Wang, Qian, Sensors 2017):
- prediction: q⁻ = q ⊗ exp(½ ω T) (closed form of Eq 7-8) = M q, P⁻ = M P Mᵀ + 𝒬,
  𝒬 = T²/4 · Ξ(q⁻) diag(σ_G²) Ξ(q⁻)ᵀ with q̇ = ½ Ξ(q) ω;
- measurement: the quaternion that solves Wahba's problem for the pairs (world up, accelerometer) and
  (world field, magnetometer) with weights 1/σ_A², 1/σ_M² (Markley 2008's closed form for two
  vectors, instead of Guo's own eigen-solution of the same problem), on the prior's hemisphere;
  its covariance ℛ = J diag(σ_A² I₃, σ_M² I₃) Jᵀ with J the Jacobian of that quaternion with respect to
  the (normalised) readings, by central differences, plus a unit variance along the measured
  quaternion itself (its norm carries no information; without it ℛ is singular there and the 4-D
  update, whose P has no variance along q⁻, amplifies the second-order radial part of z − q⁻ into
  degrees of error on real data). READING: σ_G, σ_A, σ_M are standard deviations
  (they are squared in 𝒬 and ℛ, orientation.md §12 item 17). Units: σ_G rad/s; σ_A in g, σ_M in
  units of ‖y_M,stat‖ (the readings are divided by their reference norms).
- update: H = I, K = P⁻(P⁻ + ℛ)⁻¹, q⁺ = q⁻ + K(z − q⁻) normalised, P⁺ = (I − K)P⁻ projected on the
  tangent space at q⁺ (T P⁺ T, T = I − q⁺q⁺ᵀ: the norm is set by normalising, not estimated).
- 6D (no or a gated magnetometer): the measurement is q⁻ tilted the shortest way that puts the
  accelerometer on world up, so its heading is the prior's; a 1 rad² pseudo-variance about world z
  is added to ℛ (the heading is not measured).
- P₀ = p0·I (one decision variable, orientation.md §4.5).

Gain schemes (thesis Table 5): ``fixed`` (FOG: σ_G1, σ_A1, σ_M1), ``two_level`` (VST1, Eq 48-50:
each σ switches on its own signal: ‖ω‖ vs s_g1, Δ_A vs s_a1, Δ_M vs s_m1), ``three_level`` (VST2:
second thresholds s_*2 and levels σ_*3), ``fuzzy`` (VST3: three SISO Mamdani systems,
:class:`~gait_biofeedback.core.orientation.fuzzy.SisoFIS`, input sets ``fuzzy_gyr``/``fuzzy_acc``/
``fuzzy_mag``, output sets ``fuzzy_sigma_g``/``fuzzy_sigma_a``/``fuzzy_sigma_m``, larger deviation →
larger σ) and ``iae`` (innovation adaptive estimation, §4.2.2.3): σ_A, σ_M fixed at level 1 and the
three diagonal entries of Σ_G adapted by SISO fuzzy rules on the discrepancy D = Ŝ − Ĉ between the
predicted innovation covariance Ŝ = P⁻ + ℛ and the actual one Ĉ (mean of r rᵀ over ``iae_window``
innovations; Escamilla-Ambrosio & Mort, the sign for which the rules make sense, orientation.md §3.5).
READINGs for IAE: D is 4×4 and Σ_G 3×3; the vector-part entries (x, y, z) of D are used (the scalar
entry is second order in small errors), each normalised as d = D_ii / Ŝ_ii; the fuzzy output is a
change of ln Σ_G,ii per sample (``iae_input``/``iae_output``: 24 numbers, three sets of 8 for x, y, z),
rules d < 0 → increase, d ≅ 0 → keep, d > 0 → decrease; Σ_G,ii stays within 10⁻³…10³ × σ_G1².
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any, ClassVar

import numpy as np

from gait_biofeedback.core.jit import fast
from gait_biofeedback.core.orientation.filters import _guo_kernel as gk
from gait_biofeedback.core.orientation.filters.base import OrientationFilter
from gait_biofeedback.core.orientation.fuzzy import SisoFIS
from gait_biofeedback.core.orientation.gain_regulation import switch_level

KF_SCHEMES = ("fixed", "two_level", "three_level", "fuzzy", "iae")
_IAE_LIMIT = math.log(1e3)


def _warmup() -> tuple:
    st = np.zeros(gk.N_STATE)
    st[gk.Q] = 1.0
    st[gk.P0 : gk.P0 + 16] = np.eye(4).ravel() * 1e-3
    st[gk.MREF : gk.MREF + 3] = (0.0, 0.6, -0.8)
    st[gk.SG : gk.SG + 3] = 0.01
    return (st, 0.1, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.6, -0.8, True, 0.01, 0.02, 0.05)


class GuoFKF(OrientationFilter):
    """Guo(2017) fast Kalman filter with FOG / VST1 / VST2 / VST3 / IAE noise regulation (thesis ch. 4)."""

    name = "guo_fkf"
    DEFAULTS: ClassVar[dict[str, Any]] = {
        "scheme": "three_level",
        "p0": 1e-3,
        "sigma_g1": 0.01,
        "sigma_g2": 0.03,
        "sigma_g3": 0.1,
        "s_g1": 0.5,
        "s_g2": 3.0,
        "sigma_a1": 0.02,
        "sigma_a2": 0.2,
        "sigma_a3": 2.0,
        "s_a1": 0.03,
        "s_a2": 0.15,
        "sigma_m1": 0.05,
        "sigma_m2": 0.5,
        "sigma_m3": 5.0,
        "s_m1": 0.03,
        "s_m2": 0.15,
        "fuzzy_gyr": (0.3, 1.0, 0.3, 1.0, 2.0, 4.0, 2.0, 4.0),
        "fuzzy_acc": (0.02, 0.06, 0.02, 0.06, 0.1, 0.2, 0.1, 0.2),
        "fuzzy_mag": (0.02, 0.06, 0.02, 0.06, 0.1, 0.2, 0.1, 0.2),
        "fuzzy_sigma_g": (0.01, 0.02, 0.01, 0.03, 0.05, 0.1, 0.05, 0.15),
        "fuzzy_sigma_a": (0.02, 0.1, 0.05, 0.2, 0.4, 1.0, 0.5, 2.0),
        "fuzzy_sigma_m": (0.05, 0.3, 0.1, 0.5, 1.0, 3.0, 1.0, 5.0),
        "iae_window": 25,
        "iae_input": (-0.5, 0.0, -0.5, -0.1, 0.1, 0.5, 0.0, 0.5) * 3,
        "iae_output": (-0.02, 0.0, -0.01, -0.002, 0.002, 0.01, 0.0, 0.02) * 3,
    }

    def _configure(self, p: dict[str, Any]) -> None:
        if p["scheme"] not in KF_SCHEMES:
            raise ValueError(f"{self.name}: unknown scheme {p['scheme']!r}; expected one of {KF_SCHEMES}")
        self.scheme = p["scheme"]
        levels = {"fixed": 1, "two_level": 2, "three_level": 3, "fuzzy": 1, "iae": 1}[self.scheme]
        self._levels = {s: tuple(float(p[f"sigma_{s}{i}"]) for i in range(1, levels + 1)) for s in "gam"}
        self._thresholds = {s: tuple(float(p[f"s_{s}{i}"]) for i in range(1, levels)) for s in "gam"}
        for key in ("p0", *(f"sigma_{s}{i}" for s in "gam" for i in range(1, levels + 1))):
            if not float(p[key]) > 0.0:
                raise ValueError(f"{self.name}: {key} must be positive, got {p[key]}")
        self.p0 = float(p["p0"])
        self._fis = None
        if self.scheme == "fuzzy":
            for key in ("fuzzy_sigma_g", "fuzzy_sigma_a", "fuzzy_sigma_m"):
                if not min(p[key]) > 0.0:  # the output universe is [min, max] of the 8 numbers
                    raise ValueError(f"{self.name}: {key} must be positive numbers, got {list(p[key])}")
            self._fis = SisoFIS(
                [p["fuzzy_gyr"], p["fuzzy_acc"], p["fuzzy_mag"]],
                [p["fuzzy_sigma_g"], p["fuzzy_sigma_a"], p["fuzzy_sigma_m"]],
            )
        elif self.scheme == "iae":
            sets_in, sets_out = tuple(p["iae_input"]), tuple(p["iae_output"])
            if len(sets_in) != 24 or len(sets_out) != 24:
                raise ValueError(f"{self.name}: iae_input and iae_output need 24 numbers each (3 × 8)")
            self._fis = SisoFIS(
                [sets_in[i : i + 8] for i in (0, 8, 16)],
                [sets_out[i : i + 8] for i in (0, 8, 16)],
                consequents="HML",
            )
            self.iae_window = int(p["iae_window"])
            if self.iae_window < 2:
                raise ValueError(f"{self.name}: iae_window must be at least 2, got {p['iae_window']}")
        self._kernel = fast(gk, "step", _warmup(), gk.HELPERS)

    def _reset_state(self) -> None:
        self._st = np.zeros(gk.N_STATE)
        self._st[gk.P0 : gk.P0 + 16] = np.eye(4).ravel() * self.p0  # projected at the first update
        self._sigma_g = [self._levels["g"][0]] * 3
        self._st[gk.SG : gk.SG + 3] = self._sigma_g
        self._sigmas = (self._levels["g"][0], self._levels["a"][0], self._levels["m"][0])
        self._mref_of: tuple[float, float] | None = None
        self._window: deque[tuple[float, float, float]] = deque(maxlen=getattr(self, "iae_window", 2))
        self._sums = [0.0, 0.0, 0.0]

    @property
    def covariance(self) -> np.ndarray:
        """P (4×4) of the quaternion."""
        return self._st[gk.P0 : gk.P0 + 16].reshape(4, 4).copy()

    def _extra_state(self) -> dict[str, Any]:
        return {
            "sigma_g": np.array(self._sigma_g),
            "sigma_a": self._sigmas[1],
            "sigma_m": self._sigmas[2],
            "covariance_trace": float(np.trace(self.covariance)),
        }

    def _noise(self, gyr_norm: float, dev_acc: float, dev_mag: float | None) -> tuple[float, float]:
        """σ_A, σ_M for this sample (and σ_G into ``self._sigma_g``) by the scheme."""
        lv, th = self._levels, self._thresholds
        if self.scheme == "fuzzy":
            sg, sa, sm = self._fis((gyr_norm, dev_acc, 0.0 if dev_mag is None else dev_mag))
            self._set_sigma_g(sg, sg, sg)
            return sa, sm
        if self.scheme == "iae":
            return lv["a"][0], lv["m"][0]
        sg = switch_level(gyr_norm, th["g"], lv["g"])
        self._set_sigma_g(sg, sg, sg)
        sm = lv["m"][0] if dev_mag is None else switch_level(dev_mag, th["m"], lv["m"])
        return switch_level(dev_acc, th["a"], lv["a"]), sm

    def _set_sigma_g(self, x: float, y: float, z: float) -> None:
        if self._sigma_g != [x, y, z]:
            self._sigma_g = [x, y, z]
            self._st[gk.SG : gk.SG + 3] = self._sigma_g

    def _adapt_process_noise(self) -> None:
        """IAE: D = Ŝ − Ĉ over the window → ln Σ_G,ii changed by the fuzzy rules (module docstring)."""
        st = self._st
        r = st[gk.INNOV : gk.INNOV + 4].tolist()
        sq = (r[1] * r[1], r[2] * r[2], r[3] * r[3])
        window, sums = self._window, self._sums
        if len(window) == window.maxlen:
            old = window[0]
            for i in range(3):
                sums[i] -= old[i]
        window.append(sq)
        for i in range(3):
            sums[i] += sq[i]
        if len(window) < window.maxlen:
            return
        s = st[gk.SDIAG : gk.SDIAG + 4].tolist()
        k = 1.0 / len(window)
        change = self._fis([(s[i + 1] - sums[i] * k) / s[i + 1] for i in range(3)])
        base = self._levels["g"][0]
        sg = self._sigma_g
        self._set_sigma_g(
            *(
                base
                * math.exp(0.5 * min(_IAE_LIMIT, max(-_IAE_LIMIT, 2.0 * math.log(sg[i] / base) + change[i])))
                for i in range(3)
            )
        )

    def _step(self, gx, gy, gz, ax, ay, az, m, dt, dev_acc, dev_mag):
        if ax == 0.0 and ay == 0.0 and az == 0.0:
            return self._q
        has_mag = m is not None and self._mag_ref is not None
        if not has_mag:
            dev_mag = None
        sa, sm = self._noise(math.sqrt(gx * gx + gy * gy + gz * gz), dev_acc, dev_mag)
        self._sigmas = (self._sigma_g[0], sa, sm)
        st = self._st
        if has_mag:
            mx, my, mz = m
            if self._mag_ref is not self._mref_of:
                n, u = self._mref_of = self._mag_ref
                k = 1.0 / math.hypot(n, u)
                st[gk.MREF : gk.MREF + 3] = (0.0, n * k, u * k)
        else:
            mx = my = mz = 0.0
        st[gk.Q : gk.Q + 4] = self._q
        try:
            self._kernel(st, gx, gy, gz, ax, ay, az, mx, my, mz, has_mag, dt, sa, sm)
        except np.linalg.LinAlgError:  # a singular innovation covariance: handled as a numerical failure
            st[0] = math.nan
        q = st[gk.Q : gk.Q + 4].tolist()
        if q[0] - q[0] != 0.0:  # numerical failure: the base keeps the last q; restart P
            st[gk.P0 : gk.P0 + 16] = np.eye(4).ravel() * self.p0
            return (math.nan, 0.0, 0.0, 0.0)
        if self.scheme == "iae":
            self._adapt_process_noise()
        return tuple(q)
