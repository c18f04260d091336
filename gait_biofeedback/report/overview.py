"""The report's first section (issue 48): what a clinician reads in 30 seconds, in plain words.

Walking (speed, cadence, stride length: medians of the strides used, as ``analyze`` prints them,
against the normative bands), symmetry, stance and double support, the joint angles' deviation from
the reference (Gait Profile Score, the largest Gait Variable Score), activity, whether the
calibration and the data can be trusted, and what this kit did not measure and why. The sections
after it give the details.
"""

from __future__ import annotations

import math

import numpy as np

from gait_biofeedback.core.biofeedback.advice import quantity_label
from gait_biofeedback.core.segments import SIDES
from gait_biofeedback.report.analysis import SessionAnalysis
from gait_biofeedback.report.content import DISPLAY, band_text, shown
from gait_biofeedback.report.document import Bullets, Section
from gait_biofeedback.report.extract import SessionData
from gait_biofeedback.report.figures import TRANSITIONS
from gait_biofeedback.report.norms import NormBand
from gait_biofeedback.report.session import calibration_outcome

TRUNK = ("chest", "pelvis")
LEG_JOINT_SEGMENTS = ("thigh", "shank", "foot")


def _median(analysis: SessionAnalysis, name: str) -> float:
    values = [r[name] for r in analysis.used if math.isfinite(r[name])]
    return float(np.median(values)) if values else math.nan


def _against(value_text: str, band: NormBand, value: float, band_text: str) -> str:
    word = {"low": "below", "high": "above"}.get(band.status(value))
    return f"{value_text} ({word} the normal {band_text})" if word else value_text


def _walking(analysis: SessionAnalysis, norms: dict[str, NormBand]) -> list[str]:
    parts = []
    for name in ("gait_speed", "cadence", "stride_length"):
        value = _median(analysis, name)
        if math.isfinite(value):
            text = f"{DISPLAY[name][0]} {shown(name, value, unit=True)}"
            parts.append(_against(text, norms[name], value, band_text(name, norms[name])))
    if not parts:
        return []
    return [f"Walking: {', '.join(parts)}; medians of {len(analysis.used)} steady, straight strides."]


def _symmetry(analysis: SessionAnalysis, norms: dict[str, NormBand]) -> list[str]:
    band = norms["symmetry"]
    parts = []
    for name in ("step_length", "stance_time"):
        value = analysis.symmetry.get(name, math.nan)
        if math.isfinite(value):
            parts.append(f"{name.replace('_', ' ')} {100 * value:+.1f} %"
                         + (" (asymmetric)" if band.status(value) in ("low", "high") else ""))
    if not parts:
        return []
    return [f"Symmetry, left against right: {', '.join(parts)}; within ±{100 * band.high:.0f} % is "
            "symmetric."]


def _stance(analysis: SessionAnalysis, norms: dict[str, NormBand]) -> list[str]:
    sides = []
    for side in SIDES:
        mean, _, n = analysis.table["stance_fraction"][side]
        if n:
            band = norms["stance_fraction"]
            sides.append(_against(f"{shown('stance_fraction', mean)} % {side}", band, mean,
                                  band_text("stance_fraction", band)))
    if not sides:
        return []
    means = [analysis.table["double_support_fraction"][s][0] for s in SIDES
             if analysis.table["double_support_fraction"][s][2]]
    support = float(np.mean(means)) if means else math.nan
    tail = ""
    if math.isfinite(support):
        band = norms["double_support_fraction"]
        tail = "; " + _against(f"double support {shown('double_support_fraction', support)} %", band, support,
                               band_text("double_support_fraction", band))
    return [f"Stance: {', '.join(sides)}{tail}."]


def _joints(analysis: SessionAnalysis, has_curves: bool, kit: set[str]) -> list[str]:
    if not has_curves:
        missing = [f"{side} {seg}" for side in SIDES for seg in LEG_JOINT_SEGMENTS
                   if f"{side}_{seg}" not in kit]
        why = (f"this kit has no {', '.join(missing)} sensor" if missing
               else "no stride used had hip, knee and ankle angles (see Joint angles)")
        return [f"Joint angles: not measured: {why}."]
    worst = max(((v, side, n) for side in SIDES for n, v in analysis.gvs[side].items() if math.isfinite(v)),
                default=None)
    scores = ", ".join(f"{math.degrees(analysis.gps[side]):.1f}° {side}" for side in SIDES
                       if math.isfinite(analysis.gps[side]))
    text = f"Joint angles against the reference curves: Gait Profile Score {scores}"
    if worst is not None:
        value, side, name = worst
        text += f"; the largest deviation is the {side} {name.replace('_', ' ')} ({math.degrees(value):.1f}°)"
    return [text + "."]


def _activity(data: SessionData, analysis: SessionAnalysis, kit: set[str]) -> list[str]:
    if not data.activity:
        if not set(TRUNK) & kit:
            return ["Activity: not measured: this kit has no chest or lower-back sensor."]
        return ["Activity: not measured in this recording."]
    bouts = analysis.walking_bouts or []
    walking = sum(b - a for a, b in bouts)
    changes = ", ".join(f"{TRANSITIONS.get(code, '?')} at {t:.1f} s" for t, code in data.transitions)
    return [f"Activity: {walking:.0f} s of walking in {len(bouts)} bout{'s' * (len(bouts) != 1)}, "
            f"{data.steps} steps; " + (f"posture changes: {changes}." if changes else "no posture change.")]


def _feedback(data: SessionData, analysis: SessionAnalysis) -> list[str]:
    if not data.cues:
        return ["Feedback: none was given live in this session."]
    rates = sorted((entry["in_band_percent"], quantity) for quantity, entry in analysis.cues.items())
    low = ", ".join(f"{quantity_label(*key.rstrip(')').split(' ('))} {p:.0f} %" for p, key in rates[:3])
    return [f"Feedback given live: {len(data.cues)} cues; the least often in the target band: {low} of their "
            "strides (see Time in the target band)."]


def _trust(data: SessionData) -> list[str]:
    lines = []
    if data.calibration:
        outcome = {seg: calibration_outcome(e["valid"], e["message"] or "")
                   for seg, e in data.calibration.items()}
        refused = [seg.replace("_", " ") for seg, o in outcome.items() if o == "REFUSED"]
        lacking = [seg.replace("_", " ") for seg, o in outcome.items() if o not in ("ok", "REFUSED")]
        quality = [e["quality"] for e in data.calibration.values() if e["valid"]]
        line = (f"Calibration: {len(quality)} of {len(data.calibration) - len(lacking)} segments accepted"
                + (f" (quality {min(quality):.2f}–{max(quality):.2f}, 1 = best)" if quality else ""))
        if refused:
            line += f"; REFUSED: {', '.join(refused)} (see Calibration quality)"
        if lacking:
            line += f"; {', '.join(lacking)}: needs sensors this kit does not have"
        lines.append(line + ".")
    elif not any(seg.endswith(LEG_JOINT_SEGMENTS) for seg in data.kit()):
        lines.append("Calibration: none needed: this kit has no leg or foot sensor, and the activity monitor "
                     "finds its own upright reference.")
    problems = sorted(name for name, s in data.diagnostics.items() if not s.fine(data.duration_s))
    if data.damage:
        lines.append("Data quality: the recording is damaged; this report covers only what could be read.")
    elif data.diagnostics:
        lines.append("Data quality: no sensor or processing problem reported." if not problems else
                     f"Data quality: problems reported by {len(problems)} of {len(data.diagnostics)} "
                     "sensors or stages (see Data quality).")
    return lines


def summary(data: SessionData, analysis: SessionAnalysis, norms: dict[str, NormBand], *, has_curves: bool,
            no_strides: str = "") -> Section:
    """The first section (module docstring); ``no_strides``: why there are no strides, when there are
    none."""
    kit = data.kit()
    items: list[str] = []
    if not analysis.used:
        items.append(f"Gait: {no_strides or 'no steady, straight strides to describe.'}")
    else:
        items += _walking(analysis, norms)
        items += _symmetry(analysis, norms)
        items += _stance(analysis, norms)
    items += _joints(analysis, has_curves, kit)
    items += _activity(data, analysis, kit)
    items += _feedback(data, analysis)
    items += _trust(data)
    return Section("Summary").add(Bullets(items))
