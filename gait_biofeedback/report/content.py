"""What the session report says (issue 18): header, spatiotemporal table against the normative bands,
joint curves over the reference, GPS and MAP, strides and events over time, activity, calibration,
data quality, cues and time in band, sources. Degrees, % and steps/min only here, for display."""

from __future__ import annotations

import math
import re
from collections import Counter

from gait_biofeedback.core.biofeedback import normative
from gait_biofeedback.core.biofeedback.evaluator import Targets
from gait_biofeedback.core.gait.cycles import TURN_LIMIT, WHOLE_TURN_LIMIT, flag_kinds
from gait_biofeedback.core.segments import SIDES
from gait_biofeedback.core.words import plural
from gait_biofeedback.report import figures
from gait_biofeedback.report.analysis import GPS_MISSING, NO_CURVES, TABLE, SessionAnalysis
from gait_biofeedback.report.document import Bullets, Figure, Paragraph, Section, Table
from gait_biofeedback.report.extract import LEVELS, SessionData
from gait_biofeedback.report.norms import BAKER_2009, BAKER_2012, MCID, NormBand
from gait_biofeedback.report.session import SessionReport, calibration_outcome, format_report
from gait_biofeedback.wire.topics import segment_of

# parameter → (label, display factor from SI, display unit, decimals)
DISPLAY: dict[str, tuple[str, float, str, int]] = {
    "gait_speed": ("gait speed", 1.0, "m/s", 2),
    "stride_length": ("stride length", 1.0, "m", 2),
    "step_length": ("step length", 1.0, "m", 2),
    "cadence": ("cadence", 60.0, "steps/min", 0),
    "stride_time": ("stride time", 1.0, "s", 2),
    "step_time": ("step time", 1.0, "s", 2),
    "stance_fraction": ("stance", 100.0, "%", 1),
    "swing_fraction": ("swing", 100.0, "%", 1),
    "double_support_fraction": ("double support", 100.0, "%", 1),
    "symmetry": ("symmetry index", 100.0, "%", 1),
    "gait_profile_score": ("Gait Profile Score", 180.0 / math.pi, "°", 1),
}
STATUS_WORD = {"in": "in band", "low": "below band", "high": "above band", "unknown": ""}


def shown(name: str, value: float, unit: bool = False) -> str:
    """``value`` (SI) of parameter ``name`` as displayed; "–" for NaN."""
    _, factor, u, decimals = DISPLAY[name]
    if not math.isfinite(value):
        return "–"
    return f"{factor * value:.{decimals}f}" + (f" {u}" if unit else "")


_NUMBER = re.compile(r"\d+(?:\.\d+)?")
_COUNT = re.compile(r"\d+ of \d+")  # "2 of 10 missing": a count, each said as it was


def grouped_problems(problems: dict[str, float], seen: dict[str, tuple[float, int]] | None = None
                     ) -> list[str]:
    """Each condition of a status's WARN/ERROR messages (``"LEVEL: a; b"`` → first seen at ``t`` s;
    ``seen``: → (last seen, reports)) once, in the order first seen: the same words with other
    numbers (a share missing per report) are one line, each number as its range, with when it was
    first and last said and in how many reports."""
    seen = seen or {}
    groups: dict[tuple[str, str], list] = {}
    for text, t in problems.items():
        last, reports = seen.get(text, (t, 1))
        level, _, message = text.partition(": ")
        for condition in message.split("; "):
            key = condition if _COUNT.search(condition) else _NUMBER.sub("#", condition)
            group = groups.setdefault((level, key), [t, last, 0, [], condition])
            group[0], group[1], group[2] = min(group[0], t), max(group[1], last), group[2] + reports
            group[3].append([float(v) for v in _NUMBER.findall(condition)])
    lines = []
    for (level, _), (first, last, reports, numbers, example) in sorted(groups.items(),
                                                                       key=lambda kv: kv[1][0]):
        ranges = iter(zip(*numbers, strict=True))

        def span(match: re.Match, ranges=ranges) -> str:
            low, high = (min(values := next(ranges)), max(values))
            return match.group() if low == high else f"{low:g}–{high:g}"

        text = _NUMBER.sub(span, example) if len(numbers) > 1 else example
        when = (f"at {first:.1f} s" if reports == 1 else
                f"{reports} reports, first at {first:.1f} s, last at {last:.1f} s")
        lines.append(f"{level}: {text} ({when})")
    return lines


def _band_text(name: str, band: NormBand) -> str:
    return f"{shown(name, band.low)}–{shown(name, band.high)} {DISPLAY[name][2]}"


def spatiotemporal(analysis: SessionAnalysis, norms: dict[str, NormBand]) -> Section:
    section = Section("Spatiotemporal parameters")
    where = (
        "the plausible ones inside the activity monitor's walking bouts"
        if analysis.walking_bouts is not None
        else "every plausible one: no activity/state in the recording"
    )
    section.add(
        Paragraph(
            f"{plural(len(analysis.used), 'stride')}: {where}"
            + (
                f"; {plural(analysis.left_out_outside_walking, 'plausible stride')} outside walking left out "
                "(the summary above counts them)"
                if analysis.left_out_outside_walking
                else ""
            )
            + (
                f"; {plural(analysis.left_out_turning, 'turning stride')} (in a turn) left out: steady "
                "straight walking"
                if analysis.left_out_turning
                else ""
            )
            + (
                f"; {plural(analysis.left_out_ends, 'stride')} starting or ending a walk left out"
                if analysis.left_out_ends
                else ""
            )
            + ". The summary gives medians, the table means.",
            "note",
        )
    )
    rows = []
    for name in TABLE:
        band = norms[name]
        cells = [f"{DISPLAY[name][0]} ({DISPLAY[name][2]})"]
        for side in SIDES:
            mean, sd, n = analysis.table[name][side]
            text = f"{shown(name, mean)} ± {shown(name, sd)} ({n})" if n else "–"
            cells.append((text, band.status(mean)))
        cells += [_band_text(name, band), band.note or "see sources"]
        rows.append(cells)
    section.add(
        Table(
            [
                "parameter",
                "left: mean ± SD (strides)",
                "right: mean ± SD (strides)",
                "normative band",
                "band",
            ],
            rows,
        )
    )
    band = norms["symmetry"]
    sym_rows = [
        [
            f"{n.replace('_', ' ')} symmetry index (%)",
            (shown("symmetry", v), band.status(v)),
            _band_text("symmetry", band),
        ]
        for n, v in analysis.symmetry.items()
    ]
    section.add(Table(["symmetry (L - R) / (0.5 (L + R))", "value", "band"], sym_rows))
    section.add(
        Paragraph(
            "Colours: green inside the normative band, orange below, red above. Gait speed and "
            "stride length come from each foot's trajectory; step length splits the stride by "
            "the legs' angles at the two initial contacts (as the biofeedback node does).",
            "note",
        )
    )
    return section


def _kit(data: SessionData) -> set[str]:
    """The segments whose IMU topics the recording has."""
    return {seg for t in data.counts if (seg := segment_of(t)) is not None}


def no_strides(data: SessionData) -> Section:
    """The gait sections of a recording without any stride: one sentence instead of empty tables."""
    feet = [seg for seg in _kit(data) if seg.endswith("_foot")]
    why = ("the foot sensors gave no gait events (no walking, or no calibration in force)" if feet
           else "this kit has no foot sensor, and gait events and strides come from the feet")
    return Section("Spatiotemporal parameters").add(Paragraph(f"No strides: {why}.", "note"))


def has_joint_curves(analysis: SessionAnalysis) -> bool:
    """Whether any stride used has joint-angle curves (a feet-only kit has none)."""
    return any(len(curve) for side in analysis.curves.values() for curve in side.values())


def no_joint_curves(analysis: SessionAnalysis) -> Section:
    """The joint-angle sections of a recording without any: one sentence instead of empty plots."""
    section = Section("Joint angles over the stride")
    reasons = "; ".join(f"{plural(n, 'stride')}: {NO_CURVES[r]}"
                        for r, n in analysis.strides_without_curves.items())
    section.add(Paragraph("No joint angles: no stride used has hip, knee and ankle angles"
                          + (f" ({reasons})" if reasons else "") + ". The Gait Profile Score needs them too.",
                          "note"))
    return section


def joint_curves(analysis: SessionAnalysis, targets: Targets) -> Section:
    section = Section("Joint angles over the stride", new_page=True)
    tol = {n: math.degrees(v) for n, v in targets.reference_tolerance.items()}
    section.add(
        Figure(
            figures.joint_curves(analysis, targets.reference_tolerance),
            "Sagittal hip, knee and ankle angles, time-normalised from initial contact to the next "
            "one of the same foot: mean ± SD of the strides used, on the reference curve (dashed) "
            f"± the tolerance of the targets (hip {tol['hip_flexion']:.0f}°, knee "
            f"{tol['knee_flexion']:.0f}°, ankle {tol['ankle_dorsiflexion']:.0f}°).",
        )
    )
    section.add(
        Paragraph(
            "Coarse reference: the curves are typed in from textbook key values every 5 % of the "
            "stride (Perry & Burnfield 2010; Kadaba et al. 1990) and the band is a tolerance, not "
            "a published standard deviation. Check them before training a patient towards them.",
            "warning",
        )
    )
    for reason, count in analysis.strides_without_curves.items():
        section.add(Paragraph(f"{plural(count, 'stride')} used {'has' if count == 1 else 'have'} "
                              f"no curves: {NO_CURVES[reason]}.", "note"))
    return section


def profile_score(analysis: SessionAnalysis) -> Section:
    section = Section("Gait Profile Score and Movement Analysis Profile")
    section.add(
        Figure(
            figures.movement_analysis_profile(analysis),
            "Movement Analysis Profile: the Gait Variable Score (RMS difference of the mean curve "
            "from the reference over the stride) of each variable and side, and the GPS.",
        )
    )
    rows = []
    for side in SIDES:
        rows.append(
            [side]
            + [
                shown("gait_profile_score", analysis.gvs[side].get(n, math.nan))
                for n in ("hip_flexion", "knee_flexion", "ankle_dorsiflexion")
            ]
            + [shown("gait_profile_score", analysis.gps[side])]
        )
    rows.append(["both", "", "", "", shown("gait_profile_score", analysis.gps["overall"])])
    section.add(
        Table(
            ["side", "hip flexion GVS (°)", "knee flexion GVS (°)", "ankle dorsiflexion GVS (°)", "GPS (°)"],
            rows,
        )
    )
    mcid = math.degrees(MCID["gait_profile_score"].value)
    section.add(
        Paragraph(
            f"Gait Profile Score as defined by Baker et al. 2009 over the 3 of its 9 variables that have a "
            f"reference here; missing: {', '.join(GPS_MISSING)}. Its minimal clinically important difference "
            f"is {mcid:.1f}° (Baker et al. 2012). Against the coarse reference curves the score is for "
            "following one patient over sessions, not for comparing with a laboratory's GPS.",
            "note",
        )
    )
    return section


def strides_section(data: SessionData, analysis: SessionAnalysis) -> Section:
    section = Section("Strides and events over time", new_page=True)
    section.add(
        Figure(
            figures.strides_over_time(data, analysis),
            "Each stride at its closing initial contact (filled: used; hollow: left out), the "
            "walking bouts of the activity monitor shaded, the detected IC and TC below.",
        )
    )
    plausible = sum(r["plausible"] for r in data.strides)
    items = [
        f"{len(data.strides)} strides detected, {plausible} plausible, {len(analysis.used)} used",
        f"{sum(1 for _, k, _ in data.events if k == 'ic')} initial and "
        f"{sum(1 for _, k, _ in data.events if k == 'tc')} terminal contacts",
    ]
    if analysis.walking_bouts is not None:
        bouts = ", ".join(f"{a:.1f}–{b:.1f} s" for a, b in analysis.walking_bouts) or "none"
        items.append(
            f"walking bouts (activity monitor): {bouts}; {analysis.left_out_outside_walking} plausible "
            "strides outside them left out (e.g. events of calibration moves)"
        )
    if analysis.left_out_turning:
        items.append(f"{plural(analysis.left_out_turning, 'turning stride')} left out (the foot's heading "
                     f"changed by more than {math.degrees(TURN_LIMIT):.0f}° in the stride, or a foot's by "
                     f"more than {math.degrees(WHOLE_TURN_LIMIT):.0f}° over it and the strides around it)")
    if analysis.left_out_ends:
        items.append(f"{plural(analysis.left_out_ends, 'stride')} starting or ending a walk left out (each "
                     "foot's first stride after a standing and last before a stop)")
    flags = Counter(kind for r in data.strides if not r["plausible"] for kind in flag_kinds(r["flag"]))
    items += [f"not plausible: {n} × {flag}" for flag, n in flags.most_common()]
    spatial = Counter(r["spatial_flag"].split(":")[0] for r in analysis.used if r["spatial_flag"])
    items += [f"no spatial values: {n} × {flag}" for flag, n in spatial.most_common()]
    items += analysis.notes
    section.add(Bullets(items))
    return section


def activity_section(data: SessionData) -> Section:
    section = Section("Activity")
    section.add(
        Figure(
            figures.activity_timeline(data),
            "Posture and locomotion of the trunk activity monitor, "
            "its postural transitions and the steps it counted.",
        )
    )
    items = [f"{figures.TRANSITIONS.get(code, code)} at {t:.1f} s" for t, code in data.transitions]
    section.add(
        Bullets(
            [f"{data.steps} steps counted", *items]
            if data.activity
            else ["no activity/state in this recording"]
        )
    )
    return section


def calibration_section(data: SessionData, report: SessionReport) -> Section:
    section = Section("Calibration quality")
    if not data.calibration:
        legs = [seg for seg in _kit(data) if seg.endswith(("_thigh", "_shank", "_foot"))]
        if not legs:  # a trunk sensor alone needs none: information
            return section.add(Paragraph("No calibration: this kit has no leg or foot sensor, and the "
                                         "activity monitor finds its own upright reference.", "note"))
        return section.add(
            Paragraph("No calibration in force: no joint angles and no gait events.", "warning")
        )
    rows = []
    for seg, entry in data.calibration.items():
        error = report.calibration.get(seg, {}).get("error")
        rows.append(
            [
                seg.replace("_", " "),
                (outcome := calibration_outcome(entry["valid"], entry["message"] or ""),
                 "in" if entry["valid"] else "bad" if outcome == "REFUSED" else ""),
                f"{entry['quality']:.3f}",
                entry["message"] or "",
                f"{math.degrees(error):.1f}" if error is not None else "–",
            ]
        )
    header = ["segment", "status", "quality (0-1)", "message", "error to true mounting (°, simulated)"]
    if not any(report.calibration.get(seg, {}).get("error") is not None for seg in data.calibration):
        header, rows = header[:-1], [row[:-1] for row in rows]  # a real recording: no true mounting
    section.add(Table(header, rows))
    return section


def quality_section(data: SessionData) -> Section:
    section = Section("Data quality")
    for text in data.damage:
        section.add(Paragraph(f"DAMAGED RECORDING: {text}. This report covers only what could be read.",
                              "warning"))
    if not data.diagnostics:
        return section.add(Paragraph("No /diagnostics in the recording: data quality unknown.", "warning"))
    rows = []
    for name, summary in sorted(data.diagnostics.items()):
        counters = ", ".join(
            f"{k} {v:g}"
            for k, v in summary.counters.items()
            if v and k not in ("samples", "published", "received")
        )
        base = summary.counters.get("samples", summary.counters.get("received", math.nan))
        rows.append(
            [
                name,
                (
                    LEVELS.get(summary.worst, str(summary.worst)),
                    "in" if summary.worst == 0 else "warn" if summary.worst == 1 else "bad",
                ),
                f"{base:g}" if math.isfinite(base) else "",
                counters or "none",
            ]
        )
    section.add(Table(["status (/diagnostics)", "worst level", "samples", "problems counted"], rows))
    problems = [
        f"{name}: {line}"
        for name, s in sorted(data.diagnostics.items())
        for line in grouped_problems({t: v for t, v in s.problems.items() if "start-up" not in t}, s.seen)
    ]
    recovering = int(data.recovering.sum())
    if recovering:
        problems.append(
            f"{recovering} joint_states marked recovering (a sensor back from a dropout): shown, "
            "never evaluated"
        )
    section.add(Bullets(problems or ["no warning or error besides the filters' start-up"]))
    return section


def cues_section(analysis: SessionAnalysis, targets_name: str) -> Section:
    section = Section("Biofeedback cues and time in band")
    section.add(Paragraph(f"Cues: {analysis.cue_source} (targets: {targets_name}).", "note"))
    rows = [
        [
            q,
            str(e["cues"]),
            (f"{e['in_band_percent']:.0f} %", "in" if e["in_band_percent"] >= 80 else "warn"),
            str(e["severe"]),
            f"{e['time_in_band_s']:.0f} of {e['time_s']:.0f} s",
        ]
        for q, e in sorted(analysis.cues.items())
    ]
    if rows:
        section.add(
            Table(["quantity", "strides compared", "in band", "severe", "walking time in band"], rows)
        )
    else:
        section.add(Paragraph("No stride was compared with a target.", "note"))
    return section


def sources_section(norms: dict[str, NormBand]) -> Section:
    refs = sorted(
        {b.source for b in norms.values()}
        | {m.source for m in MCID.values()}
        | set(normative.REFERENCE_SOURCES)
        | {BAKER_2009, BAKER_2012}
    )
    return Section("Sources").add(Bullets(refs))


def summary_section(report: SessionReport) -> Section:
    return Section("Summary (as `gait-biofeedback analyze` prints it)").add(Bullets(format_report(report)))
