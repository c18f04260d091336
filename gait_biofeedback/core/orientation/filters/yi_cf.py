"""Yi et al. 2018 [P1]: FQA + gyro complementary filter with an adaptive fusion coefficient.

orientation.md §8. Per sample:
1. FQA (Yun 2008, [P1 (6)–(14)]) from the accelerometer (+ magnetometer): elevation, roll and azimuth
   quaternions by half-angle formulas, q_FQA = q_z ⊗ q_y ⊗ q_x.
   READING (frame): derived here for the project's ENU world (static accelerometer reads +up):
   sin θ = −ā_x, sin φ = ā_y/cos θ, cos φ = ā_z/cos θ; the tilt-compensated field M = R_y R_x m has
   (M_x, M_y) ∝ (sin ψ, cos ψ) because north is +y (the corrected form of the garbled [P1 (12)],
   §12 item 30). Near cos θ = 0 (``fqa_eps``) roll is set to 0 (the paper's offset is not given).
2. Deviations [P1 (16)–(18)] in normalised units: Δ_acc = ‖G − R_FQA ā‖ = |‖ā‖ − 1|,
   Δ_mag = ‖N − R_FQA m̄‖ (magnitude + dip mismatch), Δ_bias = Δ_mag + α Δ_acc.
3. Fusion coefficient k = A(Δ_bias − C) + B [P1 (16)], clipped to [0, 1] (READING §12 item 34).
4. q_gyro = q_base ⊗ exp(½ ω dt) (READING: Hamilton right product, closed form, not [P1 (1)]'s
   left Euler step). ``propagate_from``: ``"fqa"`` = the paper's stability rule (q_base = previous
   q_FQA: one sample of gyro memory); ``"fused"`` (default, project decision of §12 item 34) =
   previous fused estimate, which makes it a true complementary filter that bridges disturbances.
5. q_fus = normalise(k q_FQA + (1 − k) q_gyro) [P1 (15)] after aligning hemispheres.
Without magnetometer (6D, or gated as disturbed) the FQA heading is replaced by the heading of q_gyro.
The paper fits (A, B, C) on ≥ 20 samples by gradient descent [P1 (19)–(28)]; here they are
parameters tuned once offline (benchmarks/tune_orientation.py). No gyro-bias estimation: relies on
the start-up static bias.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

from gait_biofeedback.core.orientation.filters import _scalar as sq
from gait_biofeedback.core.orientation.filters.base import OrientationFilter


def _half(c: float, s: float) -> tuple[float, float]:
    """(cos x/2, sin x/2) from (cos x, sin x) by the half-angle formulas [P1 (7)–(8)]."""
    ch = math.sqrt(max(0.0, 0.5 * (1.0 + c)))
    sh = math.sqrt(max(0.0, 0.5 * (1.0 - c)))
    return ch, (sh if s >= 0.0 else -sh)


def fqa_tilt(ax: float, ay: float, az: float, eps: float = 1e-3) -> sq.Quat:
    """Tilt quaternion q_y ⊗ q_x (yaw 0) of a specific-force vector, ENU (derived from [P1 (6)–(11)])."""
    n = math.sqrt(ax * ax + ay * ay + az * az)
    st = max(-1.0, min(1.0, -ax / n))
    ct = math.sqrt(1.0 - st * st)
    if ct < eps:
        sp, cp = 0.0, 1.0
    else:
        sp, cp = ay / (n * ct), az / (n * ct)
    cth, sth = _half(ct, st)
    cph, sph = _half(cp, sp)
    return (cth * cph, cth * sph, sth * cph, -sth * sph)


class YiCF(OrientationFilter):
    """Improved complementary filter of [P1]: FQA + gyro with adaptive fusion coefficient."""

    name = "yi_cf"
    DEFAULTS: ClassVar[dict[str, Any]] = {
        "A": -0.05, "B": 0.01, "C": 0.0, "alpha": 1.5, "propagate_from": "fused", "fqa_eps": 1e-3,
    }

    def _configure(self, p: dict[str, Any]) -> None:
        if p["propagate_from"] not in ("fused", "fqa"):
            raise ValueError("propagate_from must be 'fused' or 'fqa'")
        self.A, self.B, self.C = float(p["A"]), float(p["B"]), float(p["C"])
        self.alpha = float(p["alpha"])
        self.from_fqa = p["propagate_from"] == "fqa"
        self.eps = float(p["fqa_eps"])

    def _reset_state(self) -> None:
        self._q_fqa = self._q
        self._k = 0.0

    def _on_initialize(self) -> None:
        self._q_fqa = self._q

    def _extra_state(self) -> dict[str, Any]:
        return {"fusion_coefficient": self._k, "q_fqa": self._q_fqa}

    def _step(self, gx, gy, gz, ax, ay, az, m, dt, dev_acc, dev_mag):
        base = self._q_fqa if self.from_fqa else self._q
        qg = sq.gyro_step(base, gx, gy, gz, dt)
        qt = fqa_tilt(ax, ay, az, self.eps)
        dmag = 0.0
        if m is not None and self._mag_ref is not None:
            mx, my, mz = sq.to_world(qt, m[0], m[1], m[2])
            hn = math.sqrt(mx * mx + my * my)
            if hn > 0.0:
                ch, sh = _half(my / hn, mx / hn)
                qf = sq.multiply((ch, 0.0, 0.0, sh), qt)
            else:
                qf = sq.with_yaw(qt, sq.yaw(qg))
            dmag = math.hypot(hn - self._mag_ref[0], mz - self._mag_ref[1])
        else:
            qf = sq.with_yaw(qt, sq.yaw(qg))
        k = self.A * (dmag + self.alpha * dev_acc - self.C) + self.B
        k = self._k = min(1.0, max(0.0, k))
        if qf[0] * qg[0] + qf[1] * qg[1] + qf[2] * qg[2] + qf[3] * qg[3] < 0.0:
            qf = (-qf[0], -qf[1], -qf[2], -qf[3])
        self._q_fqa = qf
        j = 1.0 - k
        return sq.normalized((k * qf[0] + j * qg[0], k * qf[1] + j * qg[1], k * qf[2] + j * qg[2],
                              k * qf[3] + j * qg[3]))
