"""Mahony(2008) explicit complementary filter with adaptive gain regulation.

Update (orientation.md §13.2, EXT): v = R(q)ᵀ e_z, e = â × v (+ magnetometer term), e_I += e dt,
ω_c = ω + k_p e + k_i e_I, q ← q ⊗ exp(½ ω_c dt). The online bias estimate is −k_i e_I.
Project choice (thesis §2.7 block 6, decouple attitude from y_M): with ``mag_heading_only`` (default)
the magnetometer error m̂ × w (w = R(q)ᵀ b, b = (0, √(h_x²+h_y²), h_z)) is projected on the estimated
up axis v, so a magnetic disturbance can only move the heading, never the inclination.
k_p is regulated by :class:`~gait_biofeedback.core.orientation.gain_regulation.GainRegulator` (thesis Eq 23,
VST2, VST3): ``scheme``, ``kp1..3`` (rad/s), ``s_acc1/2``, ``s_mag1/2``; ``fuzzy_acc``, ``fuzzy_mag``,
``fuzzy_kp`` (8 numbers each) for ``scheme: fuzzy``; ``ki`` (rad/s²) fixed, as in Table 5;
``mag_weight`` scales the magnetometer error relative to the accelerometer one.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from gait_biofeedback.core.orientation.filters import _scalar as sq
from gait_biofeedback.core.orientation.filters._regulated import FUZZY_DEVIATION, regulator_from
from gait_biofeedback.core.orientation.filters.base import OrientationFilter


class MahonyFilter(OrientationFilter):
    """Mahony explicit complementary filter, fixed / two-level / three-level / fuzzy k_p (thesis ch. 4)."""

    name = "mahony"
    DEFAULTS: ClassVar[dict[str, Any]] = {
        "scheme": "three_level", "kp1": 1.0, "kp2": 0.2, "kp3": 0.02,
        "s_acc1": 0.03, "s_acc2": 0.15, "s_mag1": 0.03, "s_mag2": 0.15, "ki": 0.0,
        "mag_weight": 1.0, "mag_heading_only": True,
        "fuzzy_acc": FUZZY_DEVIATION, "fuzzy_mag": FUZZY_DEVIATION,
        "fuzzy_kp": (0.02, 0.2, 0.1, 0.3, 0.5, 0.8, 0.5, 1.2),
    }

    def _configure(self, params: dict[str, Any]) -> None:
        self.regulator = regulator_from(params, "kp")
        self.ki = float(params["ki"])
        self.mag_weight = float(params["mag_weight"])
        self.heading_only = bool(params["mag_heading_only"])

    def _reset_state(self) -> None:
        self._integral = [0.0, 0.0, 0.0]
        self._gain = self.regulator.gains[0]

    def _online_bias(self) -> np.ndarray:
        return -self.ki * np.array(self._integral)

    def _extra_state(self) -> dict[str, Any]:
        return {"gain": self._gain, "gain_level": self.regulator.level}

    def _step(self, gx, gy, gz, ax, ay, az, m, dt, dev_acc, dev_mag):
        kp = self._gain = self.regulator.gain(dev_acc, dev_mag)
        na = math.sqrt(ax * ax + ay * ay + az * az)
        if na == 0.0:
            return sq.normalized(sq.gyro_step(self._q, gx, gy, gz, dt))
        ax, ay, az = ax / na, ay / na, az / na
        vx, vy, vz = sq.up_in_sensor(self._q)
        ex = ay * vz - az * vy
        ey = az * vx - ax * vz
        ez = ax * vy - ay * vx
        if m is not None:
            nm = math.sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2])
            mx, my, mz = m[0] / nm, m[1] / nm, m[2] / nm
            hx, hy, hz = sq.to_world(self._q, mx, my, mz)
            wx, wy, wz = sq.to_sensor(self._q, 0.0, math.sqrt(hx * hx + hy * hy), hz)
            cx = my * wz - mz * wy
            cy = mz * wx - mx * wz
            cz = mx * wy - my * wx
            if self.heading_only:
                p = cx * vx + cy * vy + cz * vz
                cx, cy, cz = p * vx, p * vy, p * vz
            k = self.mag_weight
            ex += k * cx
            ey += k * cy
            ez += k * cz
        if self.ki > 0.0:
            i = self._integral
            i[0] += ex * dt
            i[1] += ey * dt
            i[2] += ez * dt
            gx += self.ki * i[0]
            gy += self.ki * i[1]
            gz += self.ki * i[2]
        return sq.normalized(sq.gyro_step(self._q, gx + kp * ex, gy + kp * ey, gz + kp * ez, dt))
