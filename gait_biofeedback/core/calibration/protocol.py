"""Which calibration protocol a recorded motion looks like: hip flexion or walking (issue 14).

A calibration computed with the wrong protocol's sign rules is 180° off and looks fine, so the motion
is checked against the protocol before any segment is calibrated. READING (the thesis describes the
protocols, gait.md §1.3, not how to tell them apart): hip flexion is done one leg at a time, standing on
the other, with the trunk still; walking moves both legs at once, bounces the trunk at each step and
plants each foot still in every stance. Three observations, each from the sensors that are present,
each on the *active* part of the motion window (where some sensor's 1 s mean angular rate exceeds
``ACTIVE_RATE``, so the standing after the motion does not dilute them):

* ``both_legs``: the share of the active time in which both legs are active (a leg is active where the
  1 s mean of its sensors' largest angular rate exceeds ``ACTIVE_RATE``): walking ≥ 0.6, hip flexion
  ≤ 0.3;
* ``trunk_bounce``: median over the active time of the 1 s standard deviation of the pelvis (else chest)
  accelerometer norm (m/s²): walking ≥ 0.6, hip flexion ≤ 0.3;
* ``foot_stances``: per foot, the still runs (angular rate below ``STILL_RATE`` for 0.15–2.5 s) with
  motion on both sides; the fewest over the feet: walking ≥ 3, hip flexion ≤ 1 (a foot swinging at the
  hip passes through zero rate only for an instant at each turn). A foot is still below
  ``STILL_FRACTION`` of its own 95th-percentile rate (at least ``STILL_RATE``): real sensors' noise and
  bias keep a planted foot above a fixed 0.3 rad/s (with it, 13 of 52 ipol_gait walks showed ≤ 1
  stance; with the fraction, none). Few stances vote for hip flexion only when the feet are slow
  (95th percentile ≤ ``MAX_HIP_FLEXION_FOOT_RATE``): running (pyshoe_vicon) has stances too short to
  count and fast feet.

Each observation votes when it is clearly on one side; the motion looks like a protocol when at least
one votes for it and none against. Between the bands, or with votes both ways, it looks like neither
(``None``): the requested protocol is then used and the message says it was not confirmed.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from gait_biofeedback.core.calibration.cycles import count_cycles, lowpass_motion
from gait_biofeedback.core.calibration.windows import moving_mean, moving_std, runs
from gait_biofeedback.core.segments import SIDES, ImuSeries

ACTIVE_RATE = 0.5  # rad/s, 1 s mean angular rate of an active sensor
STILL_RATE = 0.3  # rad/s, a planted foot
STILL_FRACTION = 0.15  # of the foot's 95th percentile rate: still (real sensors' noise and bias)
STANCE_S = (0.15, 2.5)  # s, how long a foot's still run between two motions lasts in walking
MAX_UPRIGHT_TILT = np.radians(35.0)  # a segment's mean attitude in the motion vs its standing
MAX_HIP_FLEXION_FOOT_RATE = 4.5  # rad/s, 95th percentile: a foot swung at the hip is slower
BANDS = {  # observation: (at most this: hip flexion, at least this: walking)
    "both_legs": (0.3, 0.6),
    "trunk_bounce": (0.3, 0.6),
    "foot_stances": (1, 3),
}
WORDS = {"hip_flexion": "hip flexion", "walking": "walking"}


@dataclass(frozen=True)
class ProtocolCheck:
    """``looks_like``: "hip_flexion", "walking" or None (cannot tell); ``observations``: name → value;
    ``votes``: name → the protocol it voted for; ``segments``: the sensors with data in the window."""

    looks_like: str | None
    observations: dict[str, float] = field(default_factory=dict)
    votes: dict[str, str] = field(default_factory=dict)
    segments: tuple[str, ...] = ()

    def evidence(self) -> str:
        """The observations in words, e.g. 'both legs moving 92 % of the time, trunk bounce 1.4 m/s²'."""
        parts = []
        for name, value in self.observations.items():
            if name == "both_legs":
                parts.append(f"both legs moving {100 * value:.0f} % of the time")
            elif name == "trunk_bounce":
                parts.append(f"trunk bounce {value:.2f} m/s²")
            else:
                parts.append(f"{value:.0f} foot stances")
        if parts:
            return ", ".join(parts)
        return ("nothing tells the protocol: that needs sensors on both legs, the pelvis or chest, or a foot"
                + (f" (the recording has {', '.join(self.segments)})" if self.segments else ""))


def _one_second_mean(series: ImuSeries, values: np.ndarray) -> np.ndarray:
    return moving_mean(values, max(3, round(series.rate_hz)))


def _resample(series: ImuSeries, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    return np.interp(t, series.t, values, left=0.0, right=0.0)


def _still_runs_between_motion(rate: np.ndarray, rate_hz: float) -> int:
    still = rate < max(STILL_RATE, STILL_FRACTION * float(np.percentile(rate, 95)))
    lo, hi = STANCE_S[0] * rate_hz, STANCE_S[1] * rate_hz
    return sum(1 for a, b in runs(still) if a > 0 and b < len(rate) and lo <= b - a <= hi)


def check_protocol(data: dict[str, ImuSeries], motion: tuple[float, float]) -> ProtocolCheck:
    """What the motion in the window ``motion`` (s) of ``data`` looks like (module docstring). The
    gyro's mean over the whole window is not removed (a bias of a few °/s is far below the bands)."""
    cut = {}
    for seg, d in data.items():
        sel = (d.t >= motion[0]) & (d.t <= motion[1])
        if sel.sum() >= 3:
            cut[seg] = ImuSeries(seg, d.t[sel], d.acc[sel], d.gyr[sel])
    if not cut:
        return ProtocolCheck(None)
    ref = max(cut.values(), key=len)
    t = ref.t
    rates = {seg: _resample(d, _one_second_mean(d, np.linalg.norm(d.gyr, axis=1)), t)
             for seg, d in cut.items()}
    active = np.max(np.vstack(list(rates.values())), axis=0) > ACTIVE_RATE
    observations: dict[str, float] = {}
    if active.sum() < 3:
        return ProtocolCheck(None, observations, segments=tuple(cut))
    legs = {side: [rates[s] for s in cut if s.startswith(side)] for side in SIDES}
    if all(legs.values()):
        leg_active = {side: np.max(np.vstack(r), axis=0) > ACTIVE_RATE for side, r in legs.items()}
        either = leg_active["left"] | leg_active["right"]
        if either.any():
            observations["both_legs"] = float(np.mean((leg_active["left"] & leg_active["right"])[either]))
    trunk = next((cut[s] for s in ("pelvis", "chest") if s in cut), None)
    if trunk is not None:
        std = moving_std(np.linalg.norm(trunk.acc, axis=1), max(3, round(trunk.rate_hz)))
        observations["trunk_bounce"] = float(np.median(_resample(trunk, std, t)[active]))
    feet = [cut[f"{side}_foot"] for side in SIDES if f"{side}_foot" in cut]
    fastest_foot = 0.0
    if feet:
        foot_rates = [moving_mean(np.linalg.norm(f.gyr, axis=1), max(1, round(0.05 * f.rate_hz)))
                      for f in feet]
        observations["foot_stances"] = float(min(_still_runs_between_motion(r, f.rate_hz)
                                                 for r, f in zip(foot_rates, feet, strict=True)))
        fastest_foot = max(float(np.percentile(r, 95)) for r in foot_rates)
    votes = {}
    for name, value in observations.items():
        low, high = BANDS[name]
        if value <= low and not (name == "foot_stances" and fastest_foot > MAX_HIP_FLEXION_FOOT_RATE):
            votes[name] = "hip_flexion"
        elif value >= high:
            votes[name] = "walking"
    said = set(votes.values())
    return ProtocolCheck(said.pop() if len(said) == 1 else None, observations, votes, tuple(cut))


def upright_tilt(data: dict[str, ImuSeries], standing: tuple[float, float], motion: tuple[float, float]
                 ) -> dict[str, float]:
    """Segment → angle (rad) between its mean accelerometer direction in ``standing`` and over the
    ``motion``. Walking and hip flexion swing the segments about their standing attitude (qmt walk:
    ≤ 12°; simulated: ≤ 9°), so a large angle means the "standing" was not upright (sitting: the
    thighs 80° off), and the verticals taken from it would be wrong."""
    out = {}
    for seg, d in data.items():
        st = (d.t >= standing[0]) & (d.t <= standing[1])
        mo = (d.t >= motion[0]) & (d.t <= motion[1])
        if st.sum() < 3 or mo.sum() < 3:
            continue
        a, b = d.acc[st].mean(axis=0), d.acc[mo].mean(axis=0)
        cos = float(a @ b / max(np.linalg.norm(a) * np.linalg.norm(b), 1e-12))
        out[seg] = float(np.arccos(np.clip(cos, -1.0, 1.0)))
    return out


def leg_cycles(data: dict[str, ImuSeries], standing: tuple[float, float], motion: tuple[float, float]) -> int:
    """The most movement cycles any leg sensor shows in ``motion``: the cycle counter of the
    calibration (:func:`~.cycles.count_cycles`) on the principal axis of its low-passed
    gyro, the ``standing``'s mean removed. The calibration refuses a leg segment with fewer than its
    protocol's ``MIN_CYCLES``, so ``auto`` does not offer such a motion as a calibration (ipol_gait:
    5 s of shuffling after a walk looked like hip flexion, with no cycle)."""
    best = 0
    for seg, s in data.items():
        if not seg.endswith(("thigh", "shank", "foot")):
            continue
        st = (s.t >= standing[0]) & (s.t <= standing[1])
        mo = (s.t >= motion[0]) & (s.t <= motion[1]) & np.all(np.isfinite(s.gyr), axis=1)
        if mo.sum() < 15 or not st.any():
            continue
        gyr = lowpass_motion(s.gyr[mo] - np.nanmean(s.gyr[st], axis=0), s.rate_hz)
        axis = np.linalg.svd(gyr, full_matrices=False)[2][0]
        best = max(best, count_cycles(gyr @ axis))
    return best
