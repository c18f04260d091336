"""Zihajehzadeh et al. 2014 [P2]: cascaded two-step Kalman filter (tilt KF → yaw KF).

orientation.md §9, ENU world. Step 1 (tilt, [P2 (5)–(17)]): state x₁ = third row of R (world up in
the sensor frame); A₁ = I − Δt [ω×] (7), 𝒬₁ = −Δt² [x₁×] Σ_G [x₁×] (15); measurement
z₁ = ā − c_a a⁺(k−1) (13) with C₁ = g I (9), ℛ₁ = (σ_A² + c_a²‖a⁺‖²/3) I (16, READING: × I₃);
a⁺ = ā − g x₁⁺ (14). Step 2 (yaw, [P2 (18)–(28)]): state x₂ = first row of R (world east in the
sensor frame), A₂, 𝒬₂ alike (20, 27), C₂ = I (22), ℛ₂ = σ_M² I (26).
READINGs: accelerometer in g (÷‖y_A,stat‖, so g = 1 and σ_A, c_a-model in g); the yaw measurement
z₂ of Eq 23–25 (tilt-compensated magnetometer → α_m → first row of R(α_m, β_m, γ_m)) is computed
in the equivalent singularity-free vector form z₂ = (m × x₁⁺)/‖m × x₁⁺‖ (east = north × up), using
the tilt of step 1 as Eq 23 does; x₁ is renormalised and x₂ Gram–Schmidt-orthogonalised to x₁
(§12 item 39). Disturbance switch Eq 26 (ℛ₂ = ∞ ⇒ skip the yaw update) by the shared gating with
the paper's ε_M = 0.01 (normalised norm band, §12 item 38) and ε_dip = 2° as defaults.
No gyro-bias state: relies on the start-up static bias (as the paper uses raw, static-compensated data).
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.orientation.filters import _scalar as sq
from gait_biofeedback.core.orientation.filters.base import OrientationFilter


class ZihajehzadehCKF(OrientationFilter):
    """Cascaded tilt/yaw Kalman filter of [P2] (σ_G² = σ_A² = 1e-4 and c_a = 0.3 as published)."""

    name = "zihajehzadeh_ckf"
    DEFAULTS: ClassVar[dict[str, Any]] = {
        "sigma_g": 0.01, "sigma_a": 0.01 / 9.81, "c_a": 0.3, "sigma_m": 0.05, "p0": 1e-3,
    }

    def __init__(self, rate_hz: float, *, mag_reject_norm: float | None = 0.01,
                 mag_reject_dip: float | None = math.radians(2.0), **kw: Any) -> None:
        super().__init__(rate_hz, mag_reject_norm=mag_reject_norm, mag_reject_dip=mag_reject_dip, **kw)

    def _configure(self, p: dict[str, Any]) -> None:
        self.sg2 = float(p["sigma_g"]) ** 2
        self.sa2 = float(p["sigma_a"]) ** 2
        self.ca = float(p["c_a"])
        self.sm2 = float(p["sigma_m"]) ** 2
        self.p0 = float(p["p0"])

    def _reset_state(self) -> None:
        self._on_initialize()

    def _on_initialize(self) -> None:
        self._x1 = np.array(sq.up_in_sensor(self._q))
        self._x2 = np.array(sq.to_sensor(self._q, 1.0, 0.0, 0.0))
        self._P1 = np.eye(3) * self.p0
        self._P2 = np.eye(3) * self.p0
        self._acc = np.zeros(3)

    def _extra_state(self) -> dict[str, Any]:
        return {"external_acc": self._acc.copy()}

    def _step(self, gx, gy, gz, ax, ay, az, m, dt, dev_acc, dev_mag):
        A = np.eye(3) - dt * quat.skew(np.array([gx, gy, gz]))
        eye = np.eye(3)
        # step 1: tilt
        x1 = A @ self._x1
        s1 = quat.skew(self._x1)
        P1 = A @ self._P1 @ A.T + (dt * dt * self.sg2) * (s1 @ s1.T)
        acc = np.array([ax, ay, az])
        z1 = acc - self.ca * self._acc
        r1 = self.sa2 + self.ca * self.ca * float(self._acc @ self._acc) / 3.0
        K1 = P1 @ np.linalg.inv(P1 + r1 * eye)
        x1 = x1 + K1 @ (z1 - x1)
        self._P1 = (eye - K1) @ P1
        x1 /= np.linalg.norm(x1)
        self._acc = acc - x1
        # step 2: yaw
        x2 = A @ self._x2
        s2 = quat.skew(self._x2)
        P2 = A @ self._P2 @ A.T + (dt * dt * self.sg2) * (s2 @ s2.T)
        if m is not None:
            e = np.cross(np.asarray(m), x1)
            ne = np.linalg.norm(e)
            if ne > 1e-9:
                K2 = P2 @ np.linalg.inv(P2 + self.sm2 * eye)
                x2 = x2 + K2 @ (e / ne - x2)
                P2 = (eye - K2) @ P2
        self._P2 = P2
        x2 = x2 - (x2 @ x1) * x1
        x2 /= np.linalg.norm(x2)
        self._x1, self._x2 = x1, x2
        north = np.cross(x1, x2)
        return sq.from_rows(tuple(x2.tolist()), tuple(north.tolist()), tuple(x1.tolist()))
