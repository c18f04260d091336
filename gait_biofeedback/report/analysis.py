"""The figures of one session's report, from :class:`~gait_biofeedback.report.extract.SessionData`.

* **Strides used**: plausible strides (``gait/cycles``) inside a walking bout of the activity monitor
  (its locomotion state, widened by ``BOUT_LEAD_S`` before, for its detection delay, and
  ``BOUT_TAIL_S`` after). Strides outside every bout (e.g. events from calibration moves) are left out
  and counted; a recording without ``activity/state`` uses every plausible stride, and says so. Turns
  are left out too, as gait analysis does (steady straight walking): a stride whose foot's heading
  changed by more than ``TURN_LIMIT`` (``turning_angle``; a stride without one is kept), or inside a
  turn of several strides (:func:`~gait_biofeedback.core.gait.cycles.turning_strides`). gaitmap_example
  through ``analyze``: its left stride length read 1.29 ± 0.22 m with its turning strides (0.56–0.82 m,
  68–114°) and a false left/right difference; 1.36 ± 0.07 m without, as its motion capture's straight
  strides (1.30–1.45 m). So are a walk's first and last stride of each foot (gait initiation and the
  stop: :func:`~gait_biofeedback.core.gait.cycles.steady_strides`).
* **Per stride**: the biofeedback node's own evaluator
  (:class:`~gait_biofeedback.core.biofeedback.evaluator.BiofeedbackEvaluator`) fed with the recording's
  joint angles: time-normalised sagittal curves (every 2 %, 51 points, IC to next IC), the kinematic
  cue quantities, the step length and the cues; so the report's numbers are the live ones. Samples
  marked recovering are left out, and a stride with a hole longer than 0.1 s has no curves.
* **Discrete joint values** (joints.csv) of every joint angle in ``joint_states``: at IC, at TC, min,
  max, range of motion over the stride, peak in swing (TC to the closing IC).
* **Spatiotemporal table**: mean, SD and count per side; symmetry indices ``(L - R) / (0.5 (L + R))``
  of the side means (Robinson et al. 1987).
* **Gait Profile Score** (Baker et al. 2009): Gait Variable Score = RMS over the 51 points of the
  session's mean curve minus the reference mean; GPS = RMS of the GVSs, per side and over both.
  READING: Baker computes the GVS of "the patient's data" without saying mean curve or per cycle; the
  mean curve is used (per-cycle GVSs would add the stride-to-stride variability to the score). The
  reference is the coarse textbook curve of :mod:`~gait_biofeedback.core.biofeedback.normative`, so
  the score is not comparable with a laboratory's GPS; only the sagittal variables have a reference
  here, so the pelvis angles, hip abduction and rotation and the foot progression are missing and named.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from gait_biofeedback.core.biofeedback import normative
from gait_biofeedback.core.biofeedback.evaluator import (
    SAGITTAL,
    SEVERITY_IN_BAND,
    BiofeedbackEvaluator,
    Stride,
    Targets,
)
from gait_biofeedback.core.gait.cycles import (
    TURN_LIMIT,
    TURN_WINDOW_S,
    WHOLE_TURN_LIMIT,
    left_out_reasons,
    symmetry_index,
)
from gait_biofeedback.core.segments import SIDES
from gait_biofeedback.report.extract import SessionData

BOUT_LEAD_S, BOUT_TAIL_S = 2.0, 0.5
MAX_GAP_S = 0.1
GPS_MISSING = (
    "pelvic tilt",
    "pelvic obliquity",
    "pelvic rotation",
    "hip abduction",
    "hip rotation",
    "foot progression",
)
"""The nine GPS variables of Baker et al. 2009 without a reference here (hip ab/adduction and rotation
are measured, but no reference curve is shipped for them)."""
TABLE = (
    "gait_speed",
    "stride_length",
    "step_length",
    "cadence",
    "stride_time",
    "step_time",
    "stance_fraction",
    "swing_fraction",
    "double_support_fraction",
)
SYMMETRY = ("step_time", "step_length", "stance_time", "swing_time")


@dataclass
class SessionAnalysis:
    """Everything the report shows of one session (SI units; module docstring)."""

    strides: list[dict]
    used: list[dict]
    left_out_outside_walking: int
    left_out_turning: int
    left_out_ends: int  # a walk's first and last stride of each foot (gait initiation, the stop)
    walking_bouts: list[tuple[float, float]] | None
    curves: dict[str, dict[str, np.ndarray]]
    percent: np.ndarray
    discrete: list[dict]
    table: dict[str, dict[str, tuple[float, float, int]]]
    symmetry: dict[str, float]
    gvs: dict[str, dict[str, float]]
    gps: dict[str, float]
    cues: dict[str, dict]
    cue_source: str
    strides_without_curves: dict[str, int]
    """Why strides used have no curves: :data:`NO_CURVES` reason → how many."""
    notes: list[str] = field(default_factory=list)


NO_CURVES = {
    "no_sensors": "there are no hip, knee and ankle angles of that side in the recording (a thigh, shank "
                  "or foot sensor missing, or not calibrated)",
    "not_published": "no joint angles were published during them (a joint still waiting for its two "
                     "sensors' common heading, which needs walking, or no calibration in force yet)",
    "holes": "their joint angles had a hole over 0.1 s or were marked recovering",
}


def walking_bouts(data: SessionData) -> list[tuple[float, float]] | None:
    """(start, end) s of the activity monitor's locomotion bouts; None without ``activity/state``."""
    return locomotion_bouts([(t, locomotion) for t, _posture, locomotion, *_ in data.activity])


def locomotion_bouts(states: list[tuple[float, int]]) -> list[tuple[float, float]] | None:
    """(start, end) s of the locomotion bouts among ``activity/state`` (s, locomotion code) in order;
    None without any state."""
    if not states:
        return None
    bouts, start = [], None
    for t, locomotion in states:
        if locomotion and start is None:
            start = t
        elif not locomotion and start is not None:
            bouts.append((start, t))
            start = None
    if start is not None:
        bouts.append((start, states[-1][0]))
    return bouts


def _inside(row: dict, bouts: list[tuple[float, float]]) -> bool:
    return any(row["start_s"] >= a - BOUT_LEAD_S and row["end_s"] <= b + BOUT_TAIL_S for a, b in bouts)


LEFT_OUT = {
    "implausible": "the stride is not plausible (its flag says why)",
    "outside_walking": f"outside every walking bout of the activity monitor ({BOUT_LEAD_S:g} s before, "
                       f"{BOUT_TAIL_S:g} s after)",
    "turning": f"a turn: the foot's heading changed by more than {math.degrees(TURN_LIMIT):.0f}° in the "
               f"stride, or a foot's by more than {math.degrees(WHOLE_TURN_LIMIT):.0f}° over it and "
               f"{TURN_WINDOW_S:g} s around it (turning_angle)",
    "walk_start_or_end": "the foot's first or last stride of a walk (gait initiation, the stop)",
}
"""Why a stride is left out of the summaries (:func:`left_out`), checked in this order."""


def left_out(strides: list[dict], stride_objects: list[Stride],
             bouts: list[tuple[float, float]] | None) -> list[str]:
    """Per stride (the report's rows and the evaluator's strides, in the same order): why it is left
    out of the summaries, a :data:`LEFT_OUT` key, or "" when it is used (module docstring, Strides
    used). ``bouts``: :func:`walking_bouts` (None: no activity monitor, every plausible stride walks)."""
    walking = None if bouts is None else [_inside(row, bouts) for row in strides]
    return left_out_reasons([(s.side, s.start_ns, s.end_ns, row["plausible"], row["turning_angle"])
                             for s, row in zip(stride_objects, strides, strict=True)], walking)


def mean_sd_n(values: list[float]) -> tuple[float, float, int]:
    """(mean, SD, n) of the finite values; SD NaN below two, (NaN, NaN, 0) without any."""
    v = np.array([x for x in values if math.isfinite(x)], dtype=float)
    if not len(v):
        return math.nan, math.nan, 0
    return float(v.mean()), float(v.std(ddof=1)) if len(v) > 1 else math.nan, len(v)


def discrete_values(joints: dict[str, np.ndarray], recovering: np.ndarray, row: dict,
                    t: np.ndarray) -> list[dict]:
    """joints.csv rows of one stride (``row``: the report's, :func:`~gait_biofeedback.report.extract.
    stride_row`): the values (rad) of its side's joint angles over it, if covered: ``at_ic``,
    ``at_tc``, ``min``, ``max``, ``range_of_motion``, ``peak_swing`` (the largest from TC to the closing
    IC), each ``angle`` named without the side. ``joints``: name → angles (rad, NaN: none) at the
    times ``t`` (s from the session's start, as the row's); samples ``recovering`` left out."""
    t0, t1, tc = row["start_s"], row["end_s"], row["terminal_contact_s"]
    inside = (t >= t0 - 0.02) & (t <= t1 + 0.02) & ~recovering
    out = []
    for name, values in joints.items():
        if any(name.startswith(f"{other}_") for other in SIDES if other != row["side"]):
            continue
        keep = inside & np.isfinite(values)
        tt, vv = t[keep], values[keep]
        if (
            len(tt) < 3
            or tt[0] > t0 + MAX_GAP_S / 2
            or tt[-1] < t1 - MAX_GAP_S / 2
            or np.diff(tt).max() > MAX_GAP_S
        ):
            continue
        swing = vv[tt >= tc] if math.isfinite(tc) else vv[:0]
        out.append(
            {
                "side": row["side"],
                "stride_index": row["stride_index"],
                "start_s": t0,
                "angle": name[len(row["side"]) + 1 :] if name.startswith(row["side"]) else name,
                "at_ic": float(np.interp(t0, tt, vv)),
                "at_tc": float(np.interp(tc, tt, vv)) if math.isfinite(tc) else math.nan,
                "min": float(vv.min()),
                "max": float(vv.max()),
                "range_of_motion": float(vv.max() - vv.min()),
                "peak_swing": float(swing.max()) if len(swing) else math.nan,
            }
        )
    return out


def gait_variable_score(curve: np.ndarray, reference: np.ndarray) -> float:
    """Baker et al. 2009: RMS over the gait cycle of ``curve - reference`` (same percent grid)."""
    return float(np.sqrt(np.mean(np.square(np.asarray(curve) - np.asarray(reference)))))


def gait_profile_score(scores: list[float]) -> float:
    """Baker et al. 2009: the RMS of the Gait Variable Scores."""
    s = np.array([x for x in scores if math.isfinite(x)], dtype=float)
    return float(np.sqrt(np.mean(np.square(s)))) if len(s) else math.nan


def _stride_side(used: list[dict], cue: dict) -> str:
    """The side of the stride a bilateral cue (no side on the wire) was given on: of the used strides
    with its stride index, the one that closed nearest to the cue's stamp."""
    candidates = [r for r in used if r["stride_index"] == cue["stride_index"]]
    if not candidates:
        return ""
    return min(candidates, key=lambda r: abs(cue["t"] - r["end_s"]))["side"]


def _cue_summary(cues: list[dict], durations: dict[tuple[str, int], float]) -> dict[str, dict]:
    """Per quantity (and side): cues, in band %, severe, and the walking time of in-band strides. A
    quantity of both sides (cadence, gait speed, symmetries) is cued at every stride of either foot,
    and the two feet's strides overlap: each such cue counts half its stride's time, so the walking
    time is counted once."""
    out: dict[str, dict] = {}
    for c in cues:
        key = c["quantity"] + (f" ({c['side']})" if c["side"] else "")
        entry = out.setdefault(
            key, {"cues": 0, "in_band": 0, "severe": 0, "time_s": 0.0, "time_in_band_s": 0.0}
        )
        entry["cues"] += 1
        entry["in_band"] += c["severity"] == SEVERITY_IN_BAND
        entry["severe"] += c["severity"] == 2
        stride_time = durations.get((c.get("stride_side") or c["side"], c["stride_index"]), 0.0)
        if not c["side"]:
            stride_time *= 0.5
        entry["time_s"] += stride_time
        entry["time_in_band_s"] += stride_time if c["severity"] == SEVERITY_IN_BAND else 0.0
    for entry in out.values():
        entry["in_band_percent"] = 100.0 * entry["in_band"] / entry["cues"]
    return out


def _why_no_curves(data: SessionData, names: list[str], stride: Stride) -> str:
    """The :data:`NO_CURVES` reason of a stride the evaluator gave no curves."""
    if not all(n in data.joints for n in names):
        return "no_sensors"
    inside = (data.joint_t >= stride.start_ns) & (data.joint_t <= stride.end_ns)
    if not np.all([np.isfinite(data.joints[n]) for n in names], axis=0)[inside].any():
        return "not_published"
    return "holes"


def analyse_session(data: SessionData, targets: Targets) -> SessionAnalysis:
    """The report's figures of ``data`` (module docstring); ``targets`` give the offline cues when the
    recording has none."""
    bouts = walking_bouts(data)
    reasons = left_out(data.strides, data.stride_objects, bouts)
    plausible = [
        (row, s) for row, s in zip(data.strides, data.stride_objects, strict=True) if row["plausible"]
    ]
    chosen = [(row, s) for row, s, why in zip(data.strides, data.stride_objects, reasons, strict=True)
              if not why]
    notes = []
    if bouts is None:
        notes.append("no activity/state in the recording: every plausible stride is used")
    rate = len(data.joint_t) / max(data.duration_s, 1e-9)
    evaluator = BiofeedbackEvaluator(
        targets, max_gap_s=MAX_GAP_S, history_s=data.duration_s + 10.0, rate_hz=max(rate, 1.0)
    )
    names = {side: [f"{side}_{n}" for n in SAGITTAL] for side in SIDES}
    for side in SIDES:
        if not all(n in data.joints for n in names[side]):
            continue
        hip, knee, ankle = (data.joints[n] for n in names[side])
        for k in np.flatnonzero(np.isfinite(hip) & np.isfinite(knee) & np.isfinite(ankle) & ~data.recovering):
            evaluator.add_angles(side, int(data.joint_t[k]), float(hip[k]), float(knee[k]), float(ankle[k]))
    t = (data.joint_t - data.start_ns) * 1e-9
    curves: dict[str, dict[str, list]] = {side: {n: [] for n in SAGITTAL} for side in SIDES}
    used, discrete, offline_cues = [], [], []
    without: dict[str, int] = {}
    chosen_ids = {id(s) for _, s in chosen}
    for row, stride in sorted(plausible, key=lambda rs: rs[1].end_ns):
        result = evaluator.evaluate(stride)  # every plausible stride, in order, as the node evaluates them
        if id(stride) not in chosen_ids:
            continue
        row = dict(
            row,
            step_length=result.spatial.get("step_length", math.nan),
            **{k: v for k, v in result.kinematics.items()},
        )
        used.append(row)
        if result.curves:
            for n in SAGITTAL:
                curves[stride.side][n].append(result.curves[n])
        else:
            reason = _why_no_curves(data, names[stride.side], stride)
            without[reason] = without.get(reason, 0) + 1
        discrete.extend(discrete_values(data.joints, data.recovering, row, t))
        offline_cues.extend(
            {
                "quantity": c.quantity,
                "side": c.side,
                "severity": c.severity,
                "stride_index": c.stride_index,
                "stride_side": stride.side,
            }
            for c in result.cues
        )
    percent = normative.percent_grid(2.0)
    stacked = {
        side: {n: np.array(v).reshape(-1, len(percent)) for n, v in c.items()} for side, c in curves.items()
    }
    table = {}
    for name in TABLE:
        table[name] = {side: mean_sd_n([r[name] for r in used if r["side"] == side]) for side in SIDES}
    symmetry = {}
    for name in SYMMETRY:
        per_side = {
            side: [r[name] for r in used if r["side"] == side and math.isfinite(r[name])] for side in SIDES
        }
        symmetry[name] = symmetry_index(per_side["left"], per_side["right"])
    gvs: dict[str, dict[str, float]] = {side: {} for side in SIDES}
    for side in SIDES:
        for n in SAGITTAL:
            if len(stacked[side][n]):
                gvs[side][n] = gait_variable_score(
                    stacked[side][n].mean(axis=0), normative.reference_curve(n, percent)
                )
    gps = {side: gait_profile_score(list(gvs[side].values())) for side in SIDES}
    gps["overall"] = gait_profile_score([v for side in SIDES for v in gvs[side].values()])
    durations = {(r["side"], r["stride_index"]): r["stride_time"] for r in used}
    if data.cues:
        cue_source = "the cues given live during the session"
        cue_rows = [dict(c, stride_side=c["side"] or _stride_side(used, c)) for c in data.cues]
    else:
        cue_source = (
            "none were given live in this session: computed from the recording against the targets, as "
            "the live feedback would have given them"
        )
        cue_rows = offline_cues
    return SessionAnalysis(
        strides=[dict(r) for r in data.strides],
        used=used,
        left_out_outside_walking=reasons.count("outside_walking"),
        left_out_turning=reasons.count("turning"),
        left_out_ends=reasons.count("walk_start_or_end"),
        walking_bouts=bouts,
        curves=stacked,
        percent=percent,
        discrete=discrete,
        table=table,
        symmetry=symmetry,
        gvs=gvs,
        gps=gps,
        cues=_cue_summary(cue_rows, durations),
        cue_source=cue_source,
        strides_without_curves=without,
        notes=notes,
    )
