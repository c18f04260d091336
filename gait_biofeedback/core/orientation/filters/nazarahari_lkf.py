"""Nazarahari(2020): the thesis' full-state linear KF (thesis §5.2.1.1, Eq 26–37; orientation.md §5).

Prediction x⁻ = ℱx⁺ (Eq 26, Φ by the 2nd-order Taylor of Eq 38), P⁻ = ℱPℱᵀ + 𝒬 (Eq 28).
Measurement: one gradient-descent step on the objective of Eq 31 with Jacobian Eq 33–34,
z = x − μ J_fᵀ f(x) (Eq 32), covariance ℛ = 𝓛 Σ_{A,M} 𝓛ᵀ with 𝓛 = μ J_fᵀ (Eq 35–37); K, x⁺, P⁺
of the standard LKF, q⁺ normalised. VST switches σ_G, σ_A, σ_M as in the EKF (Eq 48–50).

The literal text has two flaws (orientation.md §12 items 16, 16b); this is the working reading:
1. Eq 32 is applied to the *prior* x⁻_{k+1}, not to the previous posterior x⁺_k (which would undo
   the gyro increment of the current step).
2. The gyro bias would be inert (zero innovation, zero-noise pseudo-measurement, no q–b_G coupling).
   Fix: the covariance transition includes the EKF's ∂q/∂b_G block (Eq 40) and the measurement
   covers only q, a and d (ℋ selects those 10 entries), so b_G is updated through its
   cross-covariance with q. Without a magnetometer (6D / gated) the d entries are dropped too.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from gait_biofeedback.core.orientation.filters import _full_state as fs
from gait_biofeedback.core.orientation.filters.nazarahari_rekf import NazarahariREKF

_SEL_9D = np.r_[0:7, 10:13]
_SEL_6D = np.r_[0:7]


class NazarahariLKF(NazarahariREKF):
    """Full-state LKF with a gradient-descent pseudo-measurement (working reading, see module doc)."""

    name = "nazarahari_lkf"
    DEFAULTS: ClassVar[dict[str, Any]] = {
        **{k: v for k, v in NazarahariREKF.DEFAULTS.items() if k != "gamma"}, "mu": 0.5,
    }

    def _step(self, gx, gy, gz, ax, ay, az, m, dt, dev_acc, dev_mag):
        p = self.p
        x, P = self._x, self._P
        w = np.array([gx, gy, gz]) - x[fs.B]
        sigma_g = p["sigma_g1"] if float(w @ w) < p["s_g"] ** 2 else p["sigma_g2"]
        xp, Pp = fs.predict(x, P, w, dt, sigma_g, p)
        xp[fs.Q] /= np.linalg.norm(xp[fs.Q])
        qp = xp[fs.Q]
        mu = p["mu"]
        sigma_a = p["sigma_a1"] if dev_acc < p["s_a"] else p["sigma_a2"]
        HA = fs.jacobian_acc(qp)
        grad = np.zeros(13)
        fa = fs.predicted_acc(qp) + xp[fs.A] - np.array([ax, ay, az])
        grad[fs.Q] = HA.T @ fa
        grad[fs.A] = fa
        use_mag = m is not None and self._mag_ref is not None
        sel = _SEL_9D if use_mag else _SEL_6D
        L = np.zeros((13, 6 if use_mag else 3))
        L[fs.Q, 0:3] = mu * HA.T
        L[fs.A, 0:3] = mu * np.eye(3)
        sig = [sigma_a * sigma_a] * 3
        if use_mag:
            mref = np.array([0.0, self._mag_ref[0], self._mag_ref[1]])
            HM = fs.jacobian_mag(qp, mref)
            fm = fs.predicted_mag(qp, mref) + xp[fs.D] - np.asarray(m)
            grad[fs.Q] += HM.T @ fm
            grad[fs.D] = fm
            L[fs.Q, 3:6] = mu * HM.T
            L[fs.D, 3:6] = mu * np.eye(3)
            sigma_m = p["sigma_m1"] if dev_mag < p["s_m"] else p["sigma_m2"]
            sig += [sigma_m * sigma_m] * 3
        Ls = L[sel]
        R = (Ls * np.array(sig)) @ Ls.T
        Psel = Pp[:, sel]
        S = Psel[sel] + R
        K = np.linalg.solve(S, Psel.T).T
        xn = xp + K @ (-mu * grad[sel])
        self._P = Pp - K @ Psel.T
        self._P = 0.5 * (self._P + self._P.T)
        xn[fs.Q] /= np.linalg.norm(xn[fs.Q])
        self._x = xn
        return tuple(xn[fs.Q].tolist())
