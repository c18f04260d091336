"""Madgwick(2011) gradient-descent complementary filter with adaptive gain regulation.

Update (orientation.md §13.1, EXT; objective and Jacobians are the thesis' Eq 31/34 with a = d = 0):
f = [R(q)ᵀ g − â ; R(q)ᵀ b − m̂], ∇f = Jᵀ f, ŝ = ∇f/‖∇f‖;
gyro drift (ζ): ω_ε = 2 q* ⊗ ŝ, b_ω += ζ ω_ε dt, ω_c = ω − b_ω;
q ← q ⊗ exp(½ ω_c dt) − β ŝ dt, normalised (closed-form strap-down instead of the Euler step).
The Earth field b = (0, √(h_x²+h_y²), h_z) with h = R(q) m (ENU: horizontal field along +y, north).
β is regulated by :class:`~gait_biofeedback.core.orientation.gain_regulation.GainRegulator`
(thesis Eq 23, VST2):
parameters ``scheme`` ∈ {fixed, two_level, three_level, fuzzy}, ``beta1..3`` (rad/s), ``s_acc1/2``,
``s_mag1/2`` (dimensionless deviations), ``zeta`` (rad/s²); VST3 (``fuzzy``): ``fuzzy_acc``,
``fuzzy_mag`` (8 numbers each, on the deviations) and ``fuzzy_beta`` (8 numbers, rad/s).
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from gait_biofeedback.core.orientation.filters import _scalar as sq
from gait_biofeedback.core.orientation.filters._regulated import FUZZY_DEVIATION, regulator_from
from gait_biofeedback.core.orientation.filters.base import OrientationFilter


class MadgwickFilter(OrientationFilter):
    """Madgwick MARG/IMU filter with fixed / two-level / three-level / fuzzy β (thesis ch. 4)."""

    name = "madgwick"
    DEFAULTS: ClassVar[dict[str, Any]] = {
        "scheme": "three_level", "beta1": 0.1, "beta2": 0.02, "beta3": 0.002,
        "s_acc1": 0.03, "s_acc2": 0.15, "s_mag1": 0.03, "s_mag2": 0.15, "zeta": 0.0,
        "fuzzy_acc": FUZZY_DEVIATION, "fuzzy_mag": FUZZY_DEVIATION,
        "fuzzy_beta": (0.002, 0.02, 0.005, 0.03, 0.05, 0.08, 0.05, 0.12),
    }

    def _configure(self, params: dict[str, Any]) -> None:
        self.regulator = regulator_from(params, "beta")
        self.zeta = float(params["zeta"])

    def _reset_state(self) -> None:
        self._bias = [0.0, 0.0, 0.0]
        self._gain = self.regulator.gains[0]

    def _online_bias(self) -> np.ndarray:
        return np.array(self._bias)

    def _extra_state(self) -> dict[str, Any]:
        return {"gain": self._gain, "gain_level": self.regulator.level}

    def _step(self, gx, gy, gz, ax, ay, az, m, dt, dev_acc, dev_mag):
        w, x, y, z = self._q
        beta = self._gain = self.regulator.gain(dev_acc, dev_mag)
        na = math.sqrt(ax * ax + ay * ay + az * az)
        if na == 0.0:
            return sq.normalized(sq.gyro_step(self._q, gx, gy, gz, dt))
        ax, ay, az = ax / na, ay / na, az / na
        # accelerometer part: H_Aᵀ f_A (thesis Eq 31 rows 1-3, Eq 34)
        fa0 = 2.0 * (x * z - w * y) - ax
        fa1 = 2.0 * (w * x + y * z) - ay
        fa2 = 1.0 - 2.0 * (x * x + y * y) - az
        s0 = -2.0 * y * fa0 + 2.0 * x * fa1
        s1 = 2.0 * z * fa0 + 2.0 * w * fa1 - 4.0 * x * fa2
        s2 = -2.0 * w * fa0 + 2.0 * z * fa1 - 4.0 * y * fa2
        s3 = 2.0 * x * fa0 + 2.0 * y * fa1
        if m is not None:
            nm = math.sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2])
            mx, my, mz = m[0] / nm, m[1] / nm, m[2] / nm
            hx, hy, hz = sq.to_world(self._q, mx, my, mz)
            bn = math.sqrt(hx * hx + hy * hy)
            bu = hz
            # thesis Eq 31 rows 4-6 with reference (0, bn, bu)
            fm0 = 2.0 * bn * (w * z + x * y) + 2.0 * bu * (x * z - w * y) - mx
            fm1 = 2.0 * bn * (0.5 - x * x - z * z) + 2.0 * bu * (w * x + y * z) - my
            fm2 = 2.0 * bn * (y * z - w * x) + 2.0 * bu * (0.5 - x * x - y * y) - mz
            # H_Mᵀ f_M (thesis Eq 34 with m_x = 0, m_y = bn, m_z = bu)
            s0 += 2.0 * ((bn * z - bu * y) * fm0 + bu * x * fm1 - bn * x * fm2)
            s1 += 2.0 * ((bn * y + bu * z) * fm0 + (-2.0 * bn * x + bu * w) * fm1
                         + (-bn * w - 2.0 * bu * x) * fm2)
            s2 += 2.0 * ((bn * x - bu * w) * fm0 + bu * z * fm1 + (bn * z - 2.0 * bu * y) * fm2)
            s3 += 2.0 * ((bn * w + bu * x) * fm0 + (-2.0 * bn * z + bu * y) * fm1 + bn * y * fm2)
        ns = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2 + s3 * s3)
        if ns > 0.0:
            s0, s1, s2, s3 = s0 / ns, s1 / ns, s2 / ns, s3 / ns
            if self.zeta > 0.0:
                # ω_ε = 2 q* ⊗ ŝ (vector part), integrated into the drift estimate
                k = 2.0 * self.zeta * dt
                b = self._bias
                b[0] += k * (w * s1 - x * s0 - y * s3 + z * s2)
                b[1] += k * (w * s2 + x * s3 - y * s0 - z * s1)
                b[2] += k * (w * s3 - x * s2 + y * s1 - z * s0)
        b = self._bias
        qw, qx, qy, qz = sq.gyro_step(self._q, gx - b[0], gy - b[1], gz - b[2], dt)
        k = beta * dt
        return sq.normalized((qw - k * s0, qx - k * s1, qy - k * s2, qz - k * s3))
