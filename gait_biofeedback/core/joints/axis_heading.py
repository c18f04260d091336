"""Relative heading of the hip's two sensors from their calibrated medio-lateral axes (issue 14).

The joint-centre constraint of :mod:`~gait_biofeedback.core.joints.relative_heading` needs the joint
centre's acceleration to be seen alike from both sensors. At the knee and ankle it is (large swing
accelerations, sensors 10–25 cm from the joint). At the hip it is not on real sensors: the pelvis barely
rotates, so the hip centre's horizontal acceleration is the pelvis' own 1–2 m/s², while the thigh sensor
sees it through ``Γ r`` terms of 5–10 m/s² over 20 cm of soft tissue. On the qmt walk (real, 6D) the
kinematic hip offset wandered by 80° within 30 s while the knees held theirs within a few degrees
(docs/benchmarks/joint_angles.md), and with it the hip angles (internal rotation −57…+17°).

Method (READING, chosen here; Lehmann, Laidig, Deimel & Seel 2020 bound a 3-DoF joint's heading by its
range of motion; here the bound is made a mean): the hip rotates about its medio-lateral axis far more
than about the others (flexion 40–45° in gait, adduction ±6°, internal rotation ±5° about the standing
value), so the calibrated medio-lateral axes of the pelvis and thigh (anatomical z, thesis Eq 17,
``docs/conventions.md``) point, on average, to one world heading. With ``z₁ = R(q₁) R(r₁) ẑ`` and
``z₂ = R(q₂) R(r₂) ẑ`` in the two sensors' worlds, their horizontal parts ``h₁, h₂`` (x + iy) give
``δ = arg Σ w·h₁·conj(h₂)``, exponentially weighted over ``time_constant`` (5 s, several strides) as
the joint-centre estimate is, each product weighing by its size (an axis near vertical, as when lying on
one side, tells little). It needs no motion (standing and sitting inform it too) and holds on any ground.

What it cannot see: the slow part of the hip's internal rotation (its mean over ``time_constant``) is
held at the standing value, which the standing offset already defines as zero; the course within a
stride (±5° in healthy gait) is measured. A patient walking with the hip turned out against standing
reads as neutral: docs/benchmarks/joint_angles.md says so. Adduction tilts the axis without turning its
heading.
The calibration gives the axes: before one is in force the estimate waits, and a new one restarts it.
The filters' own heading corrections (9D, step 3 of the joint-centre module) are read the same way.
"""

from __future__ import annotations

from gait_biofeedback.core.joints import _heading_kernel as hk
from gait_biofeedback.core.joints.relative_heading import (
    TIME_CONSTANT_S,
    HeadingEstimate,
    RelativeHeadingEstimator,
)

MIN_SECONDS = 1.0  # s of horizontal axes (weight 1 each) before the estimate is used: about one stride
MIN_COHERENCE = 0.7  # |Σ| / Σ|·|: the two axes' headings agree within about ±45°


class AxisHeadingEstimator(RelativeHeadingEstimator):
    """Streaming heading offset of the hip's two sensors from their calibrated medio-lateral axes
    (module docstring). :meth:`set_axes` gives the axes (sensor coordinates, from the calibration);
    :meth:`update` takes the same synchronised samples as the joint-centre estimator; its arithmetic is
    :func:`._heading_kernel.axis_step`."""

    _kind = hk.AXIS

    def __init__(self, time_constant: float = TIME_CONSTANT_S, min_seconds: float = MIN_SECONDS,
                 min_coherence: float = MIN_COHERENCE) -> None:
        self.axes: tuple[tuple[float, ...], tuple[float, ...]] | None = None
        super().__init__(time_constant, min_information=min_seconds, min_coherence=min_coherence)

    def _restarted(self) -> None:
        super()._restarted()
        self.state = "waiting for a calibration" if self.axes is None else "converging"

    def set_axes(self, axis1: tuple | None, axis2: tuple | None) -> None:
        """The proximal's and distal's medio-lateral axes in their sensor coordinates (None: a segment
        is not calibrated). The average restarts; the filters' world turns are kept."""
        self.axes = None if axis1 is None or axis2 is None else (tuple(map(float, axis1)),
                                                                 tuple(map(float, axis2)))
        f, i = self._f, self._i
        for k in (hk.SUM, hk.SUM + 1, hk.MAGNITUDE, hk.INFORMATION, hk.KDELTA):
            f[k] = 0.0
        i[hk.ESTABLISHED], i[hk.HAS_AXES] = 0, int(self.axes is not None)
        for k, v in enumerate((*self.axes[0], *self.axes[1]) if self.axes is not None else (0.0,) * 6):
            f[hk.AXES + k] = v
        self.state = "waiting for a calibration" if self.axes is None else "converging"

    def update(self, ns: int, q1: tuple, gyr1: tuple, acc1: tuple, q2: tuple, gyr2: tuple,
               acc2: tuple, magnetic: tuple[bool, bool] = (False, False)) -> HeadingEstimate:
        """Add one sample (``acc`` is not used: same call as the joint-centre estimator); the estimate in
        force for it, which includes it. Non-finite samples are skipped; a stamp more than 1 s back
        restarts the average and the world turns (the filters restarted)."""
        self._took(self._k.axis_step(self._f, self._i, self._p, int(ns), *q1, *gyr1, *q2, *gyr2,
                                      bool(magnetic[0]), bool(magnetic[1])))
        return self._estimate()
