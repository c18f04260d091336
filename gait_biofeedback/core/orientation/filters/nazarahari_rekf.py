"""Nazarahari(2021): the thesis' full-state robust EKF (thesis §5.2.1.2, Eq 38–47; orientation.md §6).

Per sample (orientation.md §6.4): ω = y_G − b_G; x⁻ = [Φq, c_a a, b_G, c_d d] with Φ of Eq 38;
P⁻ = 𝒜P𝒜ᵀ + 𝒬 (Eq 39–40, 𝒬 of Eq 28); h = [R(q⁻)ᵀg + a; R(q⁻)ᵀm + d] (Eq 42), ℋ of Eq 43–44,
ℛ = diag(σ_A², σ_M²) (Eq 45); K = P⁻ℋᵀ(ℋP⁻ℋᵀ + ℛ)⁻¹, x⁺ = x⁻ + K(z − h); P⁺ by the H∞ form of
Eq 47 (``gamma``; ``gamma=None`` gives the plain EKF covariance); q⁺ normalised.
VST (Eq 48–50): σ_G ∈ {sigma_g1, sigma_g2} on ‖ω‖ vs s_g, σ_A on Δ_A vs s_a, σ_M on Δ_M vs s_m.
READINGs/choices: P₀ = p0·I (orientation.md §5.6) except the q block, p0_q·I, and the b_G block,
p0_bias·I (the static bias is removed by the start-up step, so its residual uncertainty is small);
q⁻ is normalised before h and ℋ are evaluated;
when the magnetometer is absent (6D) or gated as disturbed, only the accelerometer rows are used
and d is only propagated; if Eq 47 yields a non-positive diagonal (γ too small for the H∞ solution
to exist) the plain EKF covariance is used for that sample. Units: σ_G, sigma_bw in rad/s (·√s for
the random walk), σ_A, sigma_aw in g, σ_M, sigma_dw in units of ‖y_M,stat‖.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from gait_biofeedback.core.orientation.filters import _full_state as fs
from gait_biofeedback.core.orientation.filters.base import OrientationFilter


class NazarahariREKF(OrientationFilter):
    """Full-state robust EKF with gyro bias, external acceleration and magnetic disturbance states."""

    name = "nazarahari_rekf"
    DEFAULTS: ClassVar[dict[str, Any]] = {
        "p0": 1e-4,
        "p0_q": 1e-3,
        "p0_bias": 1e-6,
        "sigma_g1": 0.005,
        "sigma_g2": 0.02,
        "s_g": 0.5,
        "sigma_a1": 0.02,
        "sigma_a2": 0.2,
        "s_a": 0.05,
        "sigma_m1": 0.05,
        "sigma_m2": 0.5,
        "s_m": 0.05,
        "c_a": 0.9,
        "c_d": 0.999,
        "sigma_aw": 0.3,
        "sigma_bw": 1e-4,
        "sigma_dw": 0.02,
        "gamma": 30.0,
    }

    def _configure(self, p: dict[str, Any]) -> None:
        self.p = {k: (None if v is None else float(v)) for k, v in p.items()}

    def _reset_state(self) -> None:
        self._x = np.zeros(13)
        self._x[0] = 1.0
        self._P = np.eye(13) * self.p["p0"]
        self._P[fs.B, fs.B] = np.eye(3) * self.p["p0_bias"]
        self._P[fs.Q, fs.Q] = np.eye(4) * self.p["p0_q"]

    def _on_initialize(self) -> None:
        self._reset_state()
        self._x[fs.Q] = self._q

    def _online_bias(self) -> np.ndarray:
        return self._x[fs.B].copy()

    def _extra_state(self) -> dict[str, Any]:
        return {
            "external_acc": self._x[fs.A].copy(),
            "mag_disturbance": self._x[fs.D].copy(),
            "P_trace": float(np.trace(self._P)),
        }

    def _step(self, gx, gy, gz, ax, ay, az, m, dt, dev_acc, dev_mag):
        p = self.p
        x, P = self._x, self._P
        w = np.array([gx, gy, gz]) - x[fs.B]
        nw = math.sqrt(float(w @ w))
        sigma_g = p["sigma_g1"] if nw < p["s_g"] else p["sigma_g2"]
        xp, Pp = fs.predict(x, P, w, dt, sigma_g, p)
        qp = xp[fs.Q] / np.linalg.norm(xp[fs.Q])
        xp[fs.Q] = qp
        sigma_a = p["sigma_a1"] if dev_acc < p["s_a"] else p["sigma_a2"]
        use_mag = m is not None and self._mag_ref is not None
        n = 6 if use_mag else 3
        H = np.zeros((n, 13))
        H[0:3, fs.Q] = fs.jacobian_acc(qp)
        H[0:3, fs.A] = np.eye(3)
        z = np.empty(n)
        h = np.empty(n)
        z[0:3] = (ax, ay, az)
        h[0:3] = fs.predicted_acc(qp) + xp[fs.A]
        r = np.empty(n)
        r[0:3] = sigma_a * sigma_a
        if use_mag:
            mref = np.array([0.0, self._mag_ref[0], self._mag_ref[1]])
            sigma_m = p["sigma_m1"] if dev_mag < p["s_m"] else p["sigma_m2"]
            H[3:6, fs.Q] = fs.jacobian_mag(qp, mref)
            H[3:6, fs.D] = np.eye(3)
            z[3:6] = m
            h[3:6] = fs.predicted_mag(qp, mref) + xp[fs.D]
            r[3:6] = sigma_m * sigma_m
        PHt = Pp @ H.T
        S = H @ PHt + np.diag(r)
        K = np.linalg.solve(S, PHt.T).T
        xn = xp + K @ (z - h)
        Pn = Pp - K @ PHt.T
        if p["gamma"] is not None:
            Pr = self._robust_covariance(Pp, H, r, p["gamma"])
            if Pr is not None:
                Pn = Pr
        self._P = 0.5 * (Pn + Pn.T)
        xn[fs.Q] /= np.linalg.norm(xn[fs.Q])
        self._x = xn
        return tuple(xn[fs.Q].tolist())

    @staticmethod
    def _robust_covariance(Pp: np.ndarray, H: np.ndarray, r: np.ndarray, gamma: float) -> np.ndarray | None:
        """Thesis Eq 47: P⁺ = P⁻ − P⁻[ℋᵀ I] 𝓛⁻¹ [ℋ; I] P⁻, 𝓛 = diag(ℛ, −γ²I) + [ℋ; I] P⁻ [ℋᵀ I]."""
        n = H.shape[0]
        G = np.vstack([H, np.eye(13)])
        L = G @ Pp @ G.T
        L[:n, :n] += np.diag(r)
        L[n:, n:] -= gamma * gamma * np.eye(13)
        GP = G @ Pp
        Pn = Pp - GP.T @ np.linalg.solve(L, GP)
        return Pn if np.all(np.diag(Pn) > 0.0) else None
