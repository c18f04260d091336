"""Where a whole recording's first calibration is (``analyze --calibrate-at auto``): a quiet standing
then a motion that looks like a protocol (:func:`~.protocol.check_protocol`), else the first walk, whose
feet calibrate from their stance phases (:mod:`.walk`)."""

from __future__ import annotations

import numpy as np

from gait_biofeedback.core.calibration.cycles import MIN_CYCLES
from gait_biofeedback.core.calibration.protocol import (
    MAX_UPRIGHT_TILT,
    WORDS,
    ProtocolCheck,
    check_protocol,
    leg_cycles,
    upright_tilt,
)
from gait_biofeedback.core.calibration.walk import stance_calibration
from gait_biofeedback.core.calibration.windows import (
    MIN_STANDING_S,
    common_still,
    runs,
    standing_runs,
    standing_window,
)
from gait_biofeedback.core.segments import ImuSeries

TRIED_SHOWN = 6  # candidates a refusal names (in time order); the others are counted


def _feet_calibrate(data: dict[str, ImuSeries], until: float) -> bool:
    """Every foot of ``data`` calibrates from its stance phases up to ``until`` (s)."""
    feet = [s for seg, s in data.items() if seg.endswith("foot")]
    return all(stance_calibration(f.segment, f.gyr[f.t <= until], f.acc[f.t <= until], f.rate_hz).valid
               for f in feet)


def _first_walk(data: dict[str, ImuSeries], t: np.ndarray, still: np.ndarray, rate: float,
                still_runs: list[tuple[int, int]], min_motion: float, end_still: float, max_walk: float,
                max_motion: float) -> tuple[tuple[float, float], ProtocolCheck] | None:
    """(motion, check) of the first movement of at least ``min_motion`` s (from the first moving
    sample up to the next still run of ``end_still`` s) that looks like walking with a foot sensor
    present; None when there is none. The walk is cut to its first ``max_walk`` s if every foot
    calibrates from its stance phases in them, else to ``max_motion`` s: a fast walker's foot is flat
    for moments only (ipol_gait, the walk only, through the CLI: 1-6 and 8-3 right, 0.07 and 0.09 s of
    stance phases in 20 s; the calibration is in force from the start offline either way)."""
    if not any(seg.endswith("foot") for seg in data):
        return None
    moving = np.flatnonzero(~still)
    while moving.size:
        first = int(moving[0])
        later = [c for c, e in still_runs if c > first and (e - c) / rate >= end_still]
        stop = later[0] if later else len(t) - 1
        whole = (float(t[first]), min(float(t[stop]), float(t[first]) + max_motion))
        motion = (whole[0], min(whole[1], whole[0] + max_walk))
        if motion[1] - motion[0] >= min_motion:
            check = check_protocol(data, motion)
            if check.looks_like == "walking":
                if motion[1] < whole[1] and not _feet_calibrate(data, motion[1]):
                    motion = whole
                    check = check_protocol(data, motion)
                return motion, check
        moving = moving[moving > stop]
    return None


def find_calibration(data: dict[str, ImuSeries], standing_duration: float = 3.0, min_motion: float = 4.0,
                     max_motion: float = 60.0, end_still: float = 3.0, max_walk: float = 20.0
                     ) -> tuple[tuple[float, float] | None, tuple[float, float], ProtocolCheck]:
    """(standing, motion, what the motion looks like) of the first calibration in a whole recording
    (``analyze --calibrate-at auto``): a quiet standing of ``standing_duration`` s (the last seconds of a
    still run that long, ending where the sensors are quietest, :func:`~.windows.standing_window`; else
    the longest shorter one of at least 0.5 s, as :func:`~.windows.find_standing_then_motion` does with
    ``shorter_standing``), then at least ``min_motion`` s of movement up to the next still run of
    ``end_still`` s (at most ``max_motion`` s), that :func:`check_protocol` recognises and during which
    every segment stays within ``MAX_UPRIGHT_TILT`` of its standing attitude (:func:`upright_tilt`:
    sitting is not standing). A walk is cut to its first ``max_walk`` s (ample for the protocol's 8 steps,
    and the calibration is then in force for the rest of it). Without any such standing, the first walk
    (:func:`_first_walk`) with ``standing`` None: the feet calibrate from its stance phases
    (:mod:`.walk`). ValueError saying what was looked for when nothing qualifies."""
    t, still, ref = common_still(data)
    rate = ref.rate_hz
    still_runs = runs(still)
    quiet = standing_runs(t, still)
    tried = []
    long_enough = [(a, b) for a, b in quiet if b - a >= standing_duration - 1e-9]
    shorter = sorted((r for r in quiet if MIN_STANDING_S <= r[1] - r[0] < standing_duration - 1e-9),
                     key=lambda r: r[0] - r[1])  # the longest first (windows.py: the fallback)
    for a, run_end in long_enough + shorter:
        if run_end >= t[-1] - 1e-9:
            continue
        standing = standing_window(data, a, run_end, standing_duration)
        start = standing[1]
        later = [c for c, e in still_runs if t[c] > run_end and (e - c) / rate >= end_still]
        end = min(float(t[later[0]]) if later else float(t[-1]), start + max_motion)
        if end - start < min_motion:
            continue
        motion = (start, end)
        check = check_protocol(data, motion)
        tilt = upright_tilt(data, standing, motion)
        worst = max(tilt, key=tilt.get) if tilt else None
        cycles = leg_cycles(data, standing, motion)
        if check.looks_like is None:
            tried.append(f"{start - t[0]:.0f} s: {check.evidence()}")
        elif worst is not None and tilt[worst] > MAX_UPRIGHT_TILT:
            tried.append(f"{start - t[0]:.0f} s: {worst.replace('_', ' ')} {np.degrees(tilt[worst]):.0f}° "
                         "from its standing attitude (not standing?)")
        elif cycles < MIN_CYCLES[check.looks_like]:
            tried.append(f"{start - t[0]:.0f} s: {WORDS[check.looks_like]} with {cycles} movement cycles "
                         f"of a leg (the protocol needs {MIN_CYCLES[check.looks_like]})")
        else:
            if check.looks_like == "walking" and end - start > max_walk:
                motion = (start, start + max_walk)
                check = check_protocol(data, motion)
            return standing, motion, check
    walk = _first_walk(data, t, still, rate, still_runs, min_motion, end_still, max_walk, max_motion)
    if walk is not None:
        return None, *walk
    tried.sort(key=lambda text: float(text.split(" s: ", 1)[0]))
    shown = tried[:TRIED_SHOWN] + ([f"{len(tried) - TRIED_SHOWN} more"] if len(tried) > TRIED_SHOWN else [])
    raise ValueError("no calibration found (quiet standing of "
                     f"{standing_duration:g} s, then hip flexion or walking for {min_motion:g} s or more)"
                     + (": " + "; ".join(shown) if shown else "")
                     + "; give the instant with --calibrate-at SECONDS:PROTOCOL, or lower the calibration "
                       "parameter default_standing_duration_s for a recording with a shorter standing")
