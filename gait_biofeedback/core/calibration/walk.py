"""The feet calibrated from a walk alone, when a recording has no quiet standing (issue 15, item 1).

READING (issue 15: "a fallback when the recording starts walking: the vertical from the stance phases
and the heading from the walk. A walk with stance phases is never refused"): a foot is flat and still
for a moment in every stance, so those moments (:func:`stance_phases`) stand in for the
standing of thesis Eq 14 (vertical and gyro bias), and the walk's swings give the heading (Eq 15–16,
the walking protocol; the foot's own pitch-shape sign rule, :func:`~.sensor_to_segment.foot_pitch_sign`,
needs no other segment). Only the feet: a thigh, shank or trunk has no still moment in a walk that
shows its standing attitude (a thigh's mean over a stride is flexed), so their joint angles would be
offset; they are refused, saying that a standing is needed. The motion must look like walking
(:func:`~.protocol.check_protocol`): a foot swung at the hip has no stance phases to trust.

Offline only (``analyze`` / ``replay --calibrate-at auto`` on another lab's recording that starts
walking): live, the clinician has the patient stand still, which gives every segment.
"""

from __future__ import annotations

import numpy as np

from gait_biofeedback.core.calibration.protocol import WORDS, check_protocol
from gait_biofeedback.core.calibration.sensor_to_segment import (
    MIN_STANDING_SAMPLES,
    SegmentCalibrationResult,
    SessionCalibration,
    calibrate_segment,
    label,
    mean_orientation,
)
from gait_biofeedback.core.calibration.windows import moving_mean, moving_std, runs
from gait_biofeedback.core.quaternion import IDENTITY
from gait_biofeedback.core.segments import ImuSeries

STANCE_WINDOW_S = 0.06  # s: the window of a still stance phase's spreads
STANCE_GYRO_STD = 0.05  # rad/s
STANCE_GYRO_NORM = 0.3  # rad/s: a few °/s of bias pass, the heel and forefoot rockers' rolling does not
STANCE_ACC_STD = 0.3  # m/s²
MIN_STANCE_S = 0.1  # s of stance phases needed in place of a standing (and MIN_STANDING_SAMPLES)
STILL_PERIOD_GAP_S = 0.2  # s: still runs this close are one still period (a swing lasts 0.3 s or more)
STANCE_LIMITS = (0.2, 1.5)  # rad/s, m/s²: the standing check's RMS limits for stance phases


def stance_phases(gyr: np.ndarray, acc: np.ndarray, rate_hz: float) -> np.ndarray:
    """(N,) bool: the foot is flat and still, over the ``STANCE_WINDOW_S`` around each sample: gyro
    spread (norm of its per-axis standard deviations) below ``STANCE_GYRO_STD``, mean ``‖ω‖`` below
    ``STANCE_GYRO_NORM``, spread of ``‖a‖`` below ``STANCE_ACC_STD``. The window was chosen on ipol_gait
    subjects 1–5 with each trial's standing cut off (``benchmarks/gait_events.py --walk-only``): 0.1 s
    refused 6 of 56 feet (fast walkers' feet are not still that long), 0.08 s 3, 0.06 s 1."""
    w = max(2, round(STANCE_WINDOW_S * rate_hz))
    gyr_spread = np.linalg.norm(moving_std(gyr, w), axis=1)
    turning = moving_mean(np.linalg.norm(gyr, axis=1), w) >= STANCE_GYRO_NORM  # a rocker, not a flat foot
    shaken = moving_std(np.linalg.norm(acc, axis=1), w) >= STANCE_ACC_STD
    return (gyr_spread < STANCE_GYRO_STD) & ~turning & ~shaken


def still_periods(flat: np.ndarray, rate_hz: float) -> list[tuple[int, int]]:
    """[start, stop) of the runs of ``flat`` joined across gaps shorter than ``STILL_PERIOD_GAP_S``:
    one per stance of a walk, one per standing (which a foot's small shifts break into short runs)."""
    joined = flat.copy()
    for a, b in runs(~flat):
        if a > 0 and b < len(flat) and b - a < round(STILL_PERIOD_GAP_S * rate_hz):
            joined[a:b] = True
    return runs(joined)


def agreeing_stances(acc: np.ndarray, flat: np.ndarray, rate_hz: float) -> np.ndarray:
    """``flat`` without the still periods (:func:`still_periods`) whose mean acceleration is more than
    half the standing check's accelerometer limit (``STANCE_LIMITS``) from the median of the periods'
    means: the first and last steps of a walk (gait initiation and termination), a stance on a slope or
    a standing with the foot not flat disagree with the walk's other steps (the simulator's walk from
    rest: left foot 2.9° → 0.7°, right foot refused → 0.1°). Each period is one vote, however long: ipol
    7-5's final standing, its vertical 24° from its first standing's, broke into eight still runs 0.02–0.05
    s apart in its first 20 s of walking; counted run by run they outnumbered the walk's stance phases
    and the foot was refused; a standing agreeing with the stances is kept (ipol 1-2 left, 4-3 left, 4-4
    right: under 0.1 s of flat stance without theirs). The gyro's means too, at twice its limit,
    refused 1 more of the 104 ipol_gait feet in their first 20 s of walking."""
    periods = still_periods(flat, rate_hz)
    if not periods:
        return flat
    means = np.array([acc[a:b][flat[a:b]].mean(axis=0) for a, b in periods])
    off = np.linalg.norm(means - np.median(means, axis=0), axis=1) > STANCE_LIMITS[1] / 2
    kept = flat.copy()
    for (a, b), out in zip(periods, off, strict=True):
        if out:
            kept[a:b] = False
    return kept


def _refused(segment: str, message: str) -> SegmentCalibrationResult:
    return SegmentCalibrationResult(segment, IDENTITY.copy(), False, 0.0, "explained_variance", float("nan"),
                                    message)


def stance_calibration(segment: str, gyr: np.ndarray, acc: np.ndarray, rate_hz: float,
                       orientations: np.ndarray | None = None) -> SegmentCalibrationResult:
    """One foot from its walk: the still stance phases as the standing, every finite sample as the
    walking motion (module docstring). ``orientations``: (N, 4) sensor→world of the same samples (their
    mean over the stance phases is kept as the standing orientation). The standing check allows the
    stance phases ``STANCE_LIMITS`` (a stance rolls, and the feet are set down at slightly different
    pitches: ipol_gait's stance samples have 2–5 °/s RMS about their mean, the simulator's up to 1.13
    m/s²). Never raises: refused with a message when the walk has under ``MIN_STANCE_S`` of agreeing
    stance phases (``docs/benchmarks/gait_events.md``, *A walk without standing*: the figures on
    ipol_gait)."""
    gyr, acc = np.asarray(gyr, dtype=float), np.asarray(acc, dtype=float)
    finite = np.all(np.isfinite(gyr), axis=1) & np.all(np.isfinite(acc), axis=1)
    flat = agreeing_stances(acc, stance_phases(gyr, acc, rate_hz) & finite, rate_hz)
    need = max(round(MIN_STANCE_S * rate_hz), MIN_STANDING_SAMPLES)  # 100.000000000002 Hz: 10 samples
    if flat.sum() < need:
        return _refused(
            segment,
            f"{label(segment)}: no quiet standing, and only {flat.sum() / rate_hz:.2f} s of still stance "
            f"phases in the walk (need {need / rate_hz:.2g} s): start the recording with the patient "
            "standing still")
    q_stand = mean_orientation(orientations[flat]) if orientations is not None else None
    result = calibrate_segment(segment, acc[flat], gyr[flat], gyr[finite], rate_hz, "walking", q_stand,
                               standing_limits=STANCE_LIMITS)
    if not result.valid:
        result.message = f"{result.message} (from the walk's stance phases: no quiet standing)"
    return result


def calibrate_feet_from_walk(data: dict[str, ImuSeries], orientations: dict[str, np.ndarray] | None = None,
                             protocol: str = "walking") -> SessionCalibration:
    """The session calibration of a walk without standing (module docstring): the feet from their
    stance phases, every other segment refused. Refused as a whole when the motion does not look like
    walking, or when ``protocol`` is hip flexion."""
    feet = [s for s in data if s.endswith("foot")]
    t0 = min(float(s.t[0]) for s in data.values())
    t1 = max(float(s.t[-1]) for s in data.values())
    check = check_protocol(data, (t0, t1))
    refuse = "calibration refused, previous calibration stays in force: no quiet standing"
    if protocol == "hip_flexion" or check.looks_like != "walking" or not feet:
        why = (f"the {WORDS['hip_flexion']} protocol needs one" if protocol == "hip_flexion"
               else "no foot sensor to calibrate from a walk" if not feet
               else f"and the movement does not look like walking ({check.evidence()})")
        return SessionCalibration("walking", {}, False, f"{refuse}, {why}: have the patient stand still 3 s "
                                  "before the movements", None, (t0, t1), check.looks_like)
    orientations = orientations or {}
    results = {seg: stance_calibration(seg, data[seg].gyr, data[seg].acc, data[seg].rate_hz,
                                       orientations.get(seg)) for seg in feet}
    for seg in data:
        if seg not in results:
            results[seg] = _refused(seg, f"{label(seg)}: needs a quiet standing (only the feet calibrate "
                                    "from a walk)")
    valid = [label(s) for s, r in results.items() if r.valid]
    problems = [r.message for r in results.values() if not r.valid]
    if not valid:
        message = f"{refuse}: " + "; ".join(problems)
    else:
        message = ("calibrated " + ", ".join(valid) + " from the walk's stance phases (no quiet standing: "
                   "gait events and foot trajectories, no joint angles)")
        if problems:
            message += "; NOT calibrated: " + "; ".join(problems)
    return SessionCalibration("walking", results, bool(valid), message, None, (t0, t1), check.looks_like)
