"""The trunk's body frame, gravity component and inclination (thesis §7.2.3, Eq 14, Eq 54; gait.md §3.2).

Raw acceleration → ×scale, rotated into the body frame (x forward, y up, z right) by the mounting that
an upright standing reference period defines (its mean acceleration is "up", Eq 14) → GA = 0.25 Hz
elliptic low-pass per axis → trunk inclination θ = arccos(GA_v/|GA|) (Eq 54, READING in
ActivityMonitor.update). The reference is given, found in the stream (``reference="auto"``, see
:mod:`~gait_biofeedback.core.activity.reference`) or the first ``reference_s`` seconds
(``reference="start"``, the thesis). The input is rescaled so that the reference's static norm is 1 g
(gait.md §3.7 "g: the sensor's static norm"); a norm far from 1 g in the declared unit raises
``UnitMismatchWarning``.
"""

from __future__ import annotations

import math

import numpy as np

from gait_biofeedback.core.activity.reference import CHEST_REREFERENCE_RAD, REREFERENCE_RAD, UprightFinder
from gait_biofeedback.core.activity.signal import (
    Biquad,
    clip_acos,
    gravity_lowpass_ba,
    group_delay_s,
    mounting_from_reference,
    scale_to_si,
)


def check_forward_axis(axis: np.ndarray) -> np.ndarray:
    """The axis as a float array; ValueError unless it is a finite non-zero 3-vector."""
    vector = np.asarray(axis, dtype=float)
    if vector.shape != (3,) or not np.all(np.isfinite(vector)) or not np.any(vector):
        raise ValueError(f"forward axis must be a finite non-zero 3-vector, got {axis!r}")
    return vector


class TrunkFrame:
    """The mounting (``rot``: sensor → body, times the scale to m/s²; None until a reference is known),
    the GA filters and the previous sample's θ (``theta_prev``). ``finder``: the stream's upright
    finder while it looks (``reference="auto"`` without a given one); ``reference_log``: (stamp s,
    source, rad from the reference it replaced or nan) of each reference taken."""

    def __init__(self, rate_hz: float, *, units: str, reference_s: float, auto: bool, align: bool,
                 forward_axis: np.ndarray | None, placement: str) -> None:
        self.rate_hz = rate_hz
        self.units = units
        self.align = align
        self.forward_axis = None if forward_axis is None else check_forward_axis(forward_axis)
        self._n_reference = max(1, round(reference_s * rate_hz))
        self._ref_sum = [0.0, 0.0, 0.0]
        self._ref_count = 0
        self.rot: list[float] | None = None
        gb, ga = gravity_lowpass_ba(rate_hz)
        self._gravity = [Biquad(gb, ga) for _ in range(3)]
        self.ga_delay = group_delay_s(gb, ga, 0.05, rate_hz)  # GA's group delay near DC (≈ 0.27 s)
        self.prime = False  # GA starts from the next sample, not from the reference
        rereference = CHEST_REREFERENCE_RAD if placement == "chest" else REREFERENCE_RAD
        self.finder = UprightFinder(rate_hz, reference_s, rereference_rad=rereference) if auto else None
        self.reference_log: list[tuple[float, str, float]] = []
        self.theta_prev = 0.0

    def calibrate(self, mean_acc: np.ndarray) -> None:
        """The mounting and scale from a reference period's mean acceleration (sensor axes); GA as if
        it had seen the reference forever; θ of the reference."""
        scale = scale_to_si(float(np.linalg.norm(mean_acc)), self.units)
        rot = mounting_from_reference(mean_acc, self.forward_axis) if self.align else np.eye(3)
        self.rot = [float(v) for v in (rot * scale).ravel()]
        body = (rot * scale) @ mean_acc
        for biquad, value in zip(self._gravity, body, strict=True):
            biquad.reset_steady(float(value))
        self.theta_prev = clip_acos(body[1] / float(np.linalg.norm(body)))

    def prime_filters(self, f: float, v: float, lat: float) -> float:
        """Start GA at this sample (no start-up transient from the reference posture to the current
        one, which looked like a θ excursion and produced false transitions at t ≈ 0); its θ."""
        self.prime = False
        for biquad, value in zip(self._gravity, (f, v, lat), strict=True):
            biquad.reset_steady(value)
        norm = math.sqrt(f * f + v * v + lat * lat)
        self.theta_prev = clip_acos(v / norm) if norm > 0.0 else 0.0
        return self.theta_prev

    def gravity(self, f: float, v: float, lat: float) -> tuple[float, float, float]:
        """Each sample (body frame, m/s²): GA."""
        return self._gravity[0].step(f), self._gravity[1].step(v), self._gravity[2].step(lat)

    def add_start(self, t: float, ax: float, ay: float, az: float) -> bool:
        """``reference="start"``: a sample of the first ``reference_s`` s; True when they calibrated."""
        self._ref_sum[0] += ax
        self._ref_sum[1] += ay
        self._ref_sum[2] += az
        self._ref_count += 1
        if self._ref_count < self._n_reference:
            return False
        self.calibrate(np.array(self._ref_sum) / self._ref_count)
        self.reference_log.append((t, "start", math.nan))
        return True

    def find_reference(self, t: float, ax: float, ay: float, az: float, gyro
                       ) -> tuple[str, list[float]] | None:
        """Feed the :class:`UprightFinder`; (what it found, "quiet" or "walking", and the walking bout's
        steps) when the mounting changed at this sample, else None.

        The first quiet period (or walking bout, if that comes first) calibrates; a walking bout then
        checks a quiet reference and replaces it beyond its ``rereference_rad``, after which the finder
        stops. GA restarts at this sample.
        """
        finder = self.finder
        found = finder.update(t, ax, ay, az, gyro)
        if found is None:
            return None
        if finder.done:
            self.finder = None
        if found == "confirmed":
            self.reference_log.append((t, "walking confirms quiet", finder.angle))
            return None
        self.calibrate(finder.reference)
        self.prime = True
        self.reference_log.append((t, found, finder.angle))
        return found, finder.walk_steps

    def forward_heading(self, forward_axis: np.ndarray) -> tuple[float, float] | None:
        """Take a new forward axis (sensor axes); (cos, sin) of its heading in the body frame's
        horizontal (x, z) plane, or None before the mounting is known (then only stored, as
        ``mounting_from_reference``'s forward hint). ValueError for a non-3-vector or an axis nearly
        vertical for the mounting."""
        forward = check_forward_axis(forward_axis)
        if self.rot is None:
            self.forward_axis = forward
            return None
        body = np.array(self.rot).reshape(3, 3) @ forward
        if math.hypot(body[0], body[2]) < 0.3 * float(np.linalg.norm(body)):
            raise ValueError(f"forward axis {forward.tolist()} is nearly vertical for this mounting")
        heading = math.atan2(body[2], body[0])
        self.forward_axis = forward
        return math.cos(heading), math.sin(heading)

    def keep_mounting(self, previous: TrunkFrame) -> bool:
        """Take the mounting and forward axis of the frame a restart replaced (GA then starts from the
        next sample); whether there was one."""
        if previous.rot is None:
            return False
        self.rot = list(previous.rot)
        finder = previous.finder
        if finder is not None:
            finder = UprightFinder(self.rate_hz, finder.quiet_s, reference=finder.reference,
                                   rereference_rad=finder.rereference_rad)
        self.finder = finder
        self.forward_axis = previous.forward_axis
        self.prime = True
        return True
