"""Adaptive gain regulation by variable switching thresholds (thesis ch. 4, orientation.md §3).

Signals (thesis Eq 23): Δ_A = |‖y_A‖ − ‖y_A,stat‖| and Δ_M = |‖y_M‖ − ‖y_M,stat‖|.
READING (units of S_A, S_M are not stated, orientation.md §12 item 6): here both deviations are
dimensionless, taken on readings already divided by their reference norms, i.e.
Δ_A = |‖y_A‖/‖y_A,stat‖ − 1| (a fraction of g) and likewise Δ_M; thresholds are in the same units.

Schemes for one shared gain (Madgwick β, Mahony k_p):
- ``fixed`` (FOG): always ``gains[0]``.
- ``two_level`` (VST1, thesis Eq 23): ``gains[0]`` if Δ_A < S_A1 and Δ_M < S_M1, else ``gains[1]``.
- ``three_level`` (VST2, READING of orientation.md §3.3, equation not written in the thesis):
  ``gains[0]`` if Δ_A < S_A1 and Δ_M < S_M1; else ``gains[1]`` if Δ_A < S_A2 and Δ_M < S_M2;
  else ``gains[2]``.
- ``fuzzy`` (VST3, thesis §4.2.2.2): the Mamdani system of
  :class:`~gait_biofeedback.core.orientation.fuzzy.SharedGainFIS` (:class:`FuzzyGainRegulator`).
Without a magnetometer (Δ_M is None) only the accelerometer condition applies (Madgwick(IMU), Table 10).
For Kalman filters each noise level switches on its own signal (thesis Eq 48–50): :func:`switch_level`.
"""

from __future__ import annotations

from collections.abc import Sequence

SCHEMES = ("fixed", "two_level", "three_level", "fuzzy")
"""Gain schemes of the complementary filters (thesis Table 5: FOG, VST1, VST2, VST3)."""


def switch_level(signal: float, thresholds: Sequence[float], levels: Sequence[float]) -> float:
    """Per-sensor hard switch (thesis Eq 48–50, VST2 for KFs): ``levels[i]``, i = thresholds passed.

    ``levels`` must have one more entry than ``thresholds``; thresholds ascending.
    """
    i = 0
    for t in thresholds:
        if signal < t:
            break
        i += 1
    return levels[i]


class GainRegulator:
    """Selects a shared correction gain from Δ_A and Δ_M (thesis Eq 23 and VST2)."""

    def __init__(self, scheme: str, gains: Sequence[float], acc_thresholds: Sequence[float] = (),
                 mag_thresholds: Sequence[float] = ()) -> None:
        if scheme == "iae":
            raise ValueError("gain scheme 'iae' (innovation adaptive estimation of 𝒬) exists for the Kalman "
                             "filter guo_fkf only (thesis §4.2.2.3); expected one of " + ", ".join(SCHEMES))
        if scheme not in SCHEMES[:3]:
            raise ValueError(f"unknown gain scheme {scheme!r}; expected one of {SCHEMES}")
        levels = {"fixed": 1, "two_level": 2, "three_level": 3}[scheme]
        if len(gains) < levels:
            raise ValueError(f"scheme {scheme!r} needs {levels} gains, got {len(gains)}")
        if len(acc_thresholds) < levels - 1 or len(mag_thresholds) < levels - 1:
            raise ValueError(f"scheme {scheme!r} needs {levels - 1} acc and mag thresholds")
        self.scheme = scheme
        self.gains = tuple(float(g) for g in gains[:levels])
        self.acc_thresholds = tuple(float(s) for s in acc_thresholds[: levels - 1])
        self.mag_thresholds = tuple(float(s) for s in mag_thresholds[: levels - 1])
        self.level = 0  # index of the gain selected last (0 = most trust in acc/mag)

    def gain(self, dev_acc: float, dev_mag: float | None = None) -> float:
        """Gain for the current deviations (dimensionless, see module docstring)."""
        level = 0
        for sa, sm in zip(self.acc_thresholds, self.mag_thresholds, strict=True):
            if dev_acc < sa and (dev_mag is None or dev_mag < sm):
                break
            level += 1
        self.level = level
        return self.gains[level]


class FuzzyGainRegulator:
    """VST3: the shared gain from the Mamdani system on (Δ_A, Δ_M); same interface as
    :class:`GainRegulator` (``level``: the strongest rule, 0 = most trust in acc/mag)."""

    scheme = "fuzzy"

    def __init__(self, acc: Sequence[float], mag: Sequence[float], gain: Sequence[float]) -> None:
        from gait_biofeedback.core.orientation.fuzzy import SharedGainFIS

        self.fis = SharedGainFIS(acc, mag, gain)
        self.gains = (self.fis(0.0, 0.0),)
        self.level = 0

    def gain(self, dev_acc: float, dev_mag: float | None = None) -> float:
        """Gain for the current deviations (dimensionless, see module docstring)."""
        g = self.fis(dev_acc, dev_mag)
        low, mid, high = self.fis.firing
        self.level = 0 if high >= max(mid, low) else 1 if mid >= low else 2
        return g
