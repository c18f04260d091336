"""Roetenberg(2005) indirect (error-state) complementary Kalman filter with magnetic disturbance states.

The thesis ran it as MATLAB's ``ahrsfilter`` (thesis §4.2.1, orientation.md §4.4); this follows that
documented model (MathWorks, "ahrsfilter: Algorithms"), which implements Roetenberg, Luinge, Baten,
Veltink, IEEE TNSRE 13(3), 2005, in this project's frames (ENU, q sensor → world, readings divided by
their reference norms: gravity = 1, field ≈ 1):
- 12-element error state x = [θ (orientation), δb (gyro bias), δa (linear acceleration, sensor frame),
  δd (magnetic disturbance, sensor frame)]; its a-priori estimate is zero and it is reset after every
  correction (the state transition is zero: P⁻ is built from the blocks of P⁺).
- prediction: q⁻ = q ⊗ exp(½(ω − b)T); linear acceleration a⁻ = ν a⁺ (``lin_acc_decay``, ν);
  gravity g = R(q⁻)ᵀ e_z and field h = R(q⁻)ᵀ m_w predicted in the sensor frame.
- measurement: z = [y_A − a⁻ − g; y_M − h], H = [[g]×, −κ[g]×, I, 0; [h]×, −κ[h]×, 0, I], κ = T;
  ℛ = diag(σ_A² + κ²(ζ + σ_G²) I₃, σ_M² + κ²(ζ + σ_G²) I₃). Magnetic jamming (‖y_M‖² > 4 m_exp²):
  only the gravity rows are used (as in 6D).
- correction: x̂ = K z; q⁺ = q⁻ ⊗ [1, θ̂/2] (normalised), b⁺ = b + δb̂, a⁺ = a⁻ + δâ,
  m_w ← m_w + R(q⁺) δd̂, then re-expressed with its inclination and strength m_exp, horizontal part
  along north (+y).
- next P⁻: θθ = P⁺θθ + κ²(P⁺bb + ζ) + κ²σ_G², θb = −κ(P⁺bb + ζ), bb = P⁺bb + ζ,
  aa = ν² P⁺aa + ξ, dd = σ² P⁺dd + γ (σ = ``mag_disturbance_decay``); other blocks zero.
READINGs: the thesis' Table 5 variables (P₀, σ_G, σ_A, σ_M, ζ, ξ, γ, σ, m_exp) map to ``p0`` (P₀ =
p0·I; default 1e-6: after the start-up step the static bias is removed and the attitude set, and a
larger P₀ lets the bias states absorb the first motions: 33° instead of 2° on BROAD's fast rotation),
``sigma_g*``/``sigma_a*``/``sigma_m*`` (standard deviations: rad/s, g, field units),
``gyro_drift_noise`` ζ ((rad/s)², variance per sample), ``lin_acc_noise`` ξ (g²), ``mag_disturbance_noise``
γ (field units²), ``mag_disturbance_decay`` σ, ``expected_field`` m_exp (field units; 1 = the start-up
field); ν is not a thesis decision variable (MATLAB's default 0.5). MATLAB adds ξ and γ to ℛ as well;
here they drive the states' process noise only, which keeps δa and δd observable against the sensor
noise. Schemes (thesis: FOG and VST1 only): ``fixed`` (σ_G1, σ_A1, σ_M1) and ``two_level`` (each σ on its
own signal, Eq 48-50: ‖ω‖ vs s_g, Δ_A vs s_a, Δ_M vs s_m).
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from gait_biofeedback.core.jit import fast
from gait_biofeedback.core.orientation.filters import _roetenberg_kernel as rk
from gait_biofeedback.core.orientation.filters.base import OrientationFilter
from gait_biofeedback.core.orientation.gain_regulation import switch_level

SCHEMES = ("fixed", "two_level")


def _warmup() -> tuple:
    st = np.zeros(rk.N_STATE)
    st[rk.Q] = 1.0
    st[rk.FIELD : rk.FIELD + 3] = (0.0, 0.6, -0.8)
    st[rk.PM :] = np.eye(12).ravel() * 1e-3
    c = np.array([0.01, 0.02, 0.05, 1e-10, 1e-3, 1e-3, 0.5, 0.5, 1.0])
    return (st, c, 0.1, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.6, -0.8, True, 0.01)


class RoetenbergIKF(OrientationFilter):
    """Indirect Kalman filter (Roetenberg 2005 / MATLAB ahrsfilter) with FOG / VST1 noise levels."""

    name = "roetenberg_ikf"
    DEFAULTS: ClassVar[dict[str, Any]] = {
        "scheme": "two_level",
        "p0": 1e-6,
        "sigma_g1": 0.01,
        "sigma_g2": 0.03,
        "s_g": 1.0,
        "sigma_a1": 0.02,
        "sigma_a2": 0.2,
        "s_a": 0.05,
        "sigma_m1": 0.05,
        "sigma_m2": 0.5,
        "s_m": 0.05,
        "gyro_drift_noise": 1e-10,
        "lin_acc_noise": 1e-3,
        "mag_disturbance_noise": 1e-4,
        "mag_disturbance_decay": 0.5,
        "lin_acc_decay": 0.5,
        "expected_field": 1.0,
    }

    def _configure(self, p: dict[str, Any]) -> None:
        if p["scheme"] not in SCHEMES:
            raise ValueError(
                f"{self.name}: scheme {p['scheme']!r} is not available (the thesis ran FOG and "
                f"VST1 only); expected one of {SCHEMES}"
            )
        self.scheme = p["scheme"]
        for key in (
            "p0",
            "sigma_g1",
            "sigma_a1",
            "sigma_m1",
            "sigma_g2",
            "sigma_a2",
            "sigma_m2",
            "expected_field",
        ):
            if not float(p[key]) > 0.0:
                raise ValueError(f"{self.name}: {key} must be positive, got {p[key]}")
        for key in ("lin_acc_decay", "mag_disturbance_decay"):
            if not 0.0 <= float(p[key]) <= 1.0:
                raise ValueError(f"{self.name}: {key} must be within [0, 1], got {p[key]}")
        self.p0 = float(p["p0"])
        two = self.scheme == "two_level"
        self._levels = {s: tuple(float(p[f"sigma_{s}{i}"]) for i in ((1, 2) if two else (1,))) for s in "gam"}
        self._thresholds = {s: (float(p[f"s_{s}"]),) if two else () for s in "gam"}
        self._c = np.array(
            [
                self._levels["g"][0],
                self._levels["a"][0],
                self._levels["m"][0],
                p["gyro_drift_noise"],
                p["lin_acc_noise"],
                p["mag_disturbance_noise"],
                p["lin_acc_decay"],
                p["mag_disturbance_decay"],
                p["expected_field"],
            ],
            dtype=float,
        )
        self._kernel = fast(rk, "step", _warmup())

    def _reset_state(self) -> None:
        self._st = np.zeros(rk.N_STATE)
        self._st[rk.PM :] = np.eye(12).ravel() * self.p0
        self._field_of: tuple[float, float] | None = None
        self._mag_used = False

    def _online_bias(self) -> np.ndarray:
        return self._st[rk.BIAS : rk.BIAS + 3].copy()

    def _extra_state(self) -> dict[str, Any]:
        st = self._st
        return {
            "linear_acceleration_g": st[rk.LIN : rk.LIN + 3].copy(),
            "field": st[rk.FIELD : rk.FIELD + 3].copy(),
            "sigma_g": self._c[rk.SG],
            "sigma_a": self._c[rk.SA],
            "sigma_m": self._c[rk.SM],
            "magnetometer_used": self._mag_used,
        }

    def _step(self, gx, gy, gz, ax, ay, az, m, dt, dev_acc, dev_mag):
        st, c, lv, th = self._st, self._c, self._levels, self._thresholds
        use_mag = m is not None and self._mag_ref is not None
        c[rk.SG] = switch_level(math.sqrt(gx * gx + gy * gy + gz * gz), th["g"], lv["g"])
        c[rk.SA] = switch_level(dev_acc, th["a"], lv["a"])
        if use_mag:
            c[rk.SM] = switch_level(dev_mag, th["m"], lv["m"])
            mx, my, mz = m
            if self._mag_ref is not self._field_of:  # a new reference (initialise / calibrate)
                n, u = self._field_of = self._mag_ref
                k = c[rk.M_EXP] / math.hypot(n, u)
                st[rk.FIELD : rk.FIELD + 3] = (0.0, n * k, u * k)
        else:
            mx = my = mz = 0.0
        st[rk.Q : rk.Q + 4] = self._q
        try:
            self._mag_used = self._kernel(st, c, gx, gy, gz, ax, ay, az, mx, my, mz, use_mag, dt)
        except np.linalg.LinAlgError:  # a singular innovation covariance: handled as a numerical failure
            st[0] = math.nan
        q = st[rk.Q : rk.Q + 4].tolist()
        if q[0] - q[0] != 0.0:  # numerical failure: the base keeps the last q; restart the filter state
            self._reset_state()
            return (math.nan, 0.0, 0.0, 0.0)
        return tuple(q)
