"""What a session produced, and how far it is from the truth when the recording carries one.

From what :func:`~gait_biofeedback.report.recording.read_recording` read of a recording of the graph's
outputs (``joint_states``, ``gait/events``, ``gait/cycles``, ``activity/state``,
``calibration/sensor_to_segment``) and, for simulated sessions, of the ``/ground_truth/...`` topics
written with them by the simulator (sim/recording.py), :func:`summarise` gives: the calibration
and its error (helical angle to the true mounting, thesis Eq 19), joint-angle RMSE per joint
(samples matched by stamp), gait-event sensitivity/precision/timing (thesis Eq 53), stride
parameters, activity transitions and steps.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.calibration.sensor_to_segment import NOT_IN_KIT
from gait_biofeedback.core.gait.cycles import flag_kinds, left_out_reasons
from gait_biofeedback.core.gait.events import INITIAL_CONTACT, TERMINAL_CONTACT
from gait_biofeedback.core.gait.matching import EventScore, match_events
from gait_biofeedback.core.segments import SIDES
from gait_biofeedback.core.stamps import NS_PER_S
from gait_biofeedback.io.bag import BagReader
from gait_biofeedback.report.recording import (
    CYCLES,
    JOINTS,
    TRUE_CALIBRATION,
    TRUE_EVENTS,
    TRUE_JOINTS,
    JointRows,
    Recording,
    read_recording,
)
from gait_biofeedback.wire.calibration import rotation
from gait_biofeedback.wire.stamps import stamp_to_ns

REPORTED_JOINTS = ("hip_flexion", "knee_flexion", "ankle_dorsiflexion", "hip_adduction", "knee_adduction",
                   "ankle_inversion")


@dataclass
class SessionReport:
    """Figures of one session (see module docstring); NaN/empty where the recording lacks the data."""

    duration: float = 0.0
    counts: dict[str, int] = field(default_factory=dict)
    calibration: dict[str, dict] = field(default_factory=dict)
    joint_rmse: dict[str, float] = field(default_factory=dict)
    events: dict[str, EventScore] = field(default_factory=dict)
    cycles: dict[str, float] = field(default_factory=dict)
    flagged: dict[str, int] = field(default_factory=dict)
    """Implausible strides by their first reason (:func:`~gait_biofeedback.core.gait.cycles.flag_kinds`)."""
    transitions: list[tuple[float, int]] = field(default_factory=list)
    steps: int = 0
    true_steps: int = 0


def _calibration(messages: list[tuple[str, Any]]) -> dict[str, dict]:
    """The estimated and true calibrations per segment (the estimates' segments first, in their order)."""
    found: dict[str, dict] = {}
    for topic, msg in sorted(messages, key=lambda m: m[0] == TRUE_CALIBRATION):
        for seg in msg.segments:
            entry = found.setdefault(seg.segment, {})
            key = "truth" if topic == TRUE_CALIBRATION else "estimate"
            entry[key] = rotation(seg)
            if key == "estimate":
                entry.update(valid=seg.valid, quality=seg.quality, message=seg.message)
    for entry in found.values():
        if "truth" in entry and "estimate" in entry:
            entry["error"] = float(quat.angle_between(entry["estimate"], entry["truth"]))
    return found


def _joint_rmse(measured: JointRows, truth: JointRows) -> dict[str, float]:
    """RMS of (measured - true) angle per joint, over the stamps both have (rad)."""
    rmse = {}
    for name in measured.columns():
        true = truth.by_stamp(name)
        errors = [value - true[stamp] for stamp, value in measured.by_stamp(name).items() if stamp in true]
        if errors:
            rmse[name] = float(np.sqrt(np.mean(np.square(errors))))
    return rmse


def _events(times: dict[tuple[bool, str, str], list[float]]) -> dict[str, EventScore]:
    """Scores of the detected events (``times[(False, side, kind)]``, s) against the true ones
    (``times[(True, side, kind)]``)."""
    if not any(not truth for truth, _, _ in times):
        return {}
    scores: dict[str, EventScore] = {}
    for kind in (INITIAL_CONTACT, TERMINAL_CONTACT):
        total = EventScore()
        for side in SIDES:
            detected, reference = times[(False, side, kind)], times[(True, side, kind)]
            if reference:
                # score only while events were being detected at all (after calibration)
                start = min(detected) - 0.5 if detected else np.inf
                total += match_events(detected, [t for t in reference if t >= start])
        scores[kind] = total
    return scores


def _cycles(messages: list[Any]) -> dict[str, float]:
    """The strides' counts and the medians over the plausible steady straight ones (the report's rule,
    :func:`~gait_biofeedback.core.gait.cycles.left_out_reasons`, without the walking bouts), from the
    ``gait/cycles`` messages with their ``gait/stride_space`` revisions (:attr:`Recording.cycles`), in
    log order."""
    rows, spatial = [], []
    reasons = left_out_reasons([(m.side, stamp_to_ns(m.start), stamp_to_ns(m.header.stamp), m.plausible,
                                 m.turning_angle) for m in messages])
    for m, why in zip(messages, reasons, strict=True):
        if why:
            continue
        rows.append((m.stride_time, m.stance_fraction, m.cadence, m.double_support_fraction))
        if not m.spatial_flag and m.stride_length > 0:
            spatial.append((m.stride_length, m.gait_speed))
    good = np.array(rows, dtype=float).reshape(-1, 4)
    counts = {"strides": len(messages), "plausible": sum(m.plausible for m in messages),
              "turning": reasons.count("turning"), "ends": reasons.count("walk_start_or_end")}
    if not len(good):
        return counts
    space = np.array(spatial, dtype=float).reshape(-1, 2)
    return {
        **counts, "spatial": len(space),
        "stride_length": float(np.median(space[:, 0])) if len(space) else math.nan,
        "gait_speed": float(np.nanmedian(space[:, 1])) if len(space) else math.nan,
        "stride_time": float(np.median(good[:, 0])), "stance_percent": float(100 * np.median(good[:, 1])),
        "cadence_per_min": float(60 * np.median(good[:, 2])),
        # one foot only (a single shoe sensor): no double support
        "double_support_percent": (float(100 * np.nanmedian(good[:, 3])) if np.isfinite(good[:, 3]).any()
                                   else math.nan),
    }


def session_report(path: str | Path) -> SessionReport:
    """Read a session recording (once: the topics the figures need, in log order) and compute its figures."""
    with BagReader(path) as reader:
        return summarise(read_recording(reader, summary_only=True))


def summarise(recording: Recording) -> SessionReport:
    """The figures of a session from what :func:`~gait_biofeedback.report.recording.read_recording` read."""
    recorded = recording.recorded
    report = SessionReport(duration=recording.duration_ns / NS_PER_S, counts=dict(recording.counts),
                           steps=recording.steps)
    times: dict[tuple[bool, str, str], list[float]] = defaultdict(list)
    for topic, side, kind, stamp_ns in recording.events:
        times[(topic == TRUE_EVENTS, side, kind)].append(stamp_ns * 1e-9)
        report.true_steps += topic == TRUE_EVENTS and kind == INITIAL_CONTACT
    report.calibration = _calibration([(topic, msg) for topic, msg, _ in recording.calibrations])
    if TRUE_JOINTS in recorded:
        report.joint_rmse = _joint_rmse(recording.joint_rows(JOINTS), recording.joint_rows(TRUE_JOINTS))
    report.events = _events(times) if TRUE_EVENTS in recorded else {}
    report.cycles = _cycles(recording.cycles) if CYCLES in recorded else {}
    for m in recording.cycles:
        if not m.plausible:
            kind = (flag_kinds(m.flag) or ["no reason given"])[0]
            report.flagged[kind] = report.flagged.get(kind, 0) + 1
    report.transitions = [(stamp_ns * 1e-9, kind) for stamp_ns, kind in recording.transitions]
    return report


def _deg(x: float) -> str:
    return f"{np.degrees(x):5.1f}"


def calibration_outcome(valid: bool, message: str) -> str:
    """``ok``, ``REFUSED``, or, for a segment whose calibration needs sensors the kit does not have,
    ``needs sensors not in this kit`` (what the kit lacks is no refusal)."""
    return "ok" if valid else "needs sensors not in this kit" if NOT_IN_KIT in message else "REFUSED"


def format_report(report: SessionReport) -> list[str]:
    """Human-readable lines (degrees, ms, %) of a SessionReport."""
    lines: list[str] = []
    if report.calibration:
        estimated = {s: e for s, e in report.calibration.items() if "estimate" in e}
        if estimated:
            parts = [f"{s} {calibration_outcome(e['valid'], e['message'])}"
                     + (f" {_deg(e['error']).strip()}°" if "error" in e else "")
                     for s, e in estimated.items()]
            truth = any("error" in e for e in estimated.values())
            lines.append(("calibration (error to true mounting): " if truth else "calibration: ")
                         + ", ".join(parts))
        else:
            lines.append("calibration: none in force (no joint angles, no gait events)")
    if report.joint_rmse:
        lines.append("joint-angle RMSE vs truth (deg):  " + "   ".join(
            f"{j.replace('_', ' ')} L {_deg(report.joint_rmse.get('left_' + j, np.nan)).strip()}"
            f" R {_deg(report.joint_rmse.get('right_' + j, np.nan)).strip()}"
            for j in REPORTED_JOINTS[:3]))
        lines.append("                                  " + "   ".join(
            f"{j.replace('_', ' ')} L {_deg(report.joint_rmse.get('left_' + j, np.nan)).strip()}"
            f" R {_deg(report.joint_rmse.get('right_' + j, np.nan)).strip()}"
            for j in REPORTED_JOINTS[3:]))
    for name, score in report.events.items():
        lines.append(f"gait events {name.upper()}: Se {100 * score.sensitivity:5.1f} %  Pr "
                     f"{100 * score.precision:5.1f} %  timing {1000 * score.mean_error:+6.1f} ± "
                     f"{1000 * score.sd_error:4.1f} ms  ({len(score.errors)} matched, {len(score.missed)} "
                     f"missed, {len(score.extra)} extra)")
    c = report.cycles
    left_out = ", ".join(text for n, text in ((c.get("turning"), f"{c.get('turning')} turning"),
                                                (c.get("ends"), f"{c.get('ends')} starting or ending a walk"))
                         if n)
    if c.get("plausible") and "stride_time" not in c:
        lines.append(f"strides: {c['plausible']} of {c['strides']} plausible, none steady and straight "
                     f"({left_out}: left out of the medians)")
    elif c.get("plausible"):
        turns = f", {left_out} (left out)" if left_out else ""
        lines.append(f"strides: {c['plausible']} of {c['strides']} plausible{turns}; "
                     f"stride {c['stride_time']:.2f} s, cadence {c['cadence_per_min']:.0f} steps/min, "
                     f"stance {c['stance_percent']:.0f} %, " + (
                         f"double support {c['double_support_percent']:.0f} %"
                         if math.isfinite(c["double_support_percent"])
                         else "double support unknown (one foot)"))
        used = c["plausible"] - c["turning"] - c["ends"]
        lines.append(f"spatial: {c['spatial']} of {used} plausible steady straight strides with values"
                     + (f"; stride length {c['stride_length']:.2f} m, gait speed {c['gait_speed']:.2f} m/s"
                        if c["spatial"] else " (the others are flagged in gait/cycles spatial_flag)"))
    if report.flagged:
        lines.append("flagged strides, left out: " + "; ".join(
            f"{n} {kind}" for kind, n in sorted(report.flagged.items(), key=lambda item: -item[1])))
    if report.transitions or report.steps:
        lines.append(f"activity: {len(report.transitions)} transitions, {report.steps} steps counted"
                     + (f" ({report.true_steps} true)" if report.true_steps else ""))
    return lines
