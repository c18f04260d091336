"""What the session report says (issues 18, 48): after the summary (:mod:`.overview`), the
spatiotemporal table against the normative bands, joint curves over the reference with the contacts
marked, GPS and MAP, strides and events over time, activity, calibration, data quality, time in band,
sources; sections without data are one sentence, and what is all well is one line, not a table.
Degrees, % and steps/min only here, for display; clinical words, not the software's."""

from __future__ import annotations

import math
import re
from collections import Counter

from gait_biofeedback.core.biofeedback import normative
from gait_biofeedback.core.biofeedback.advice import quantity_label
from gait_biofeedback.core.biofeedback.evaluator import Targets
from gait_biofeedback.core.gait.cycles import TURN_LIMIT, WHOLE_TURN_LIMIT, flag_kinds
from gait_biofeedback.core.segments import SIDES
from gait_biofeedback.core.words import plural
from gait_biofeedback.report import figures
from gait_biofeedback.report.analysis import GPS_MISSING, NO_CURVES, TABLE, SessionAnalysis
from gait_biofeedback.report.document import Bullets, Figure, Paragraph, Section, Table
from gait_biofeedback.report.extract import LEVELS, SessionData
from gait_biofeedback.report.norms import BAKER_2009, BAKER_2012, MCID, NormBand
from gait_biofeedback.report.session import SessionReport, calibration_outcome

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


def band_text(name: str, band: NormBand) -> str:
    """A normative band as displayed: ``low–high unit``."""
    return f"{shown(name, band.low)}–{shown(name, band.high)} {DISPLAY[name][2]}"


_AUTHOR_YEAR = re.compile(r"^(\w+).*?\b((?:19|20)\d\d)\b", re.S)


def short_source(band: NormBand) -> str:
    """``Perry 2010`` of a band's source (how the band was made from it: :func:`range_notes`)."""
    match = _AUTHOR_YEAR.search(band.source)
    return f"{match.group(1)} {match.group(2)}" if match else band.source


def range_notes(norms: dict[str, NormBand], names: tuple[str, ...]) -> str:
    """How the ranges of ``names`` were made from their sources, one clause per way."""
    ways: dict[str, list[str]] = {}
    for name in names:
        if norms[name].note:
            ways.setdefault(norms[name].note, []).append(DISPLAY[name][0])
    return "; ".join(f"{', '.join(labels)}: {note}" for note, labels in ways.items())


def spatiotemporal(analysis: SessionAnalysis, norms: dict[str, NormBand]) -> Section:
    section = Section("Spatiotemporal parameters")
    where = ("steady, straight walking inside the walking bouts" if analysis.walking_bouts is not None
             else "steady, straight walking (no activity monitor in this recording)")
    used = plural(len(analysis.used), "stride")
    section.add(Paragraph(f"Mean ± SD (number of strides) of the {used} used: {where}; what was left out is "
                          "under Strides over time.", "note"))
    rows = []
    for name in TABLE:
        if not any(analysis.table[name][side][2] for side in SIDES):
            continue  # no value on either side (step length without joint angles)
        band = norms[name]
        cells = [f"{DISPLAY[name][0]} ({DISPLAY[name][2]})"]
        for side in SIDES:
            mean, sd, n = analysis.table[name][side]
            text = f"{shown(name, mean)} ± {shown(name, sd)} ({n})" if n else "–"
            cells.append((text, band.status(mean)))
        cells += [band_text(name, band), short_source(band)]
        rows.append(cells)
    section.add(
        Table(
            ["parameter", "left", "right", "normal range", "range from"],
            rows,
        )
    )
    band = norms["symmetry"]
    values = ", ".join(f"{n.replace('_', ' ')} {shown('symmetry', v)} %"
                       + ("" if band.status(v) == "in" else " (asymmetric)")
                       for n, v in analysis.symmetry.items() if math.isfinite(v))
    within = (f"±{shown('symmetry', band.high)} %" if band.low == -band.high else band_text("symmetry", band))
    section.add(Paragraph(f"Symmetry index (L − R) / (0.5 (L + R)), symmetric within {within}: {values}.",
                          "note"))
    section.add(
        Paragraph(
            "Colours: green inside the normal range, orange below, red above. Ranges: "
            f"{range_notes(norms, TABLE)}. Gait speed and stride length come from each foot's trajectory; "
            "step length splits the stride by the legs' angles at the two initial contacts (as the live "
            "feedback does).",
            "note",
        )
    )
    return section


def no_strides_reason(data: SessionData) -> str:
    """Why a recording has no stride, in one sentence."""
    if any(seg.endswith("_foot") for seg in data.kit()):
        return "no strides: the foot sensors gave no gait events (no walking, or no calibration in force)."
    return "not measured: this kit has no foot sensor, and gait events and strides come from the feet."


def has_joint_curves(analysis: SessionAnalysis) -> bool:
    """Whether any stride used has joint-angle curves (a feet-only kit has none)."""
    return any(len(curve) for side in analysis.curves.values() for curve in side.values())


def no_joint_curves(analysis: SessionAnalysis) -> list[Section]:
    """The joint-angle sections of a recording without any: one sentence instead of empty plots;
    nothing when the kit lacks the sensors (the summary says which)."""
    if set(analysis.strides_without_curves) <= {"no_sensors"}:
        return []
    section = Section("Joint angles over the stride")
    reasons = "; ".join(f"{plural(n, 'stride')}: {NO_CURVES[r]}"
                        for r, n in analysis.strides_without_curves.items())
    section.add(Paragraph("No joint angles: no stride used has hip, knee and ankle angles"
                          + (f" ({reasons})" if reasons else "") + ". The Gait Profile Score needs them too.",
                          "note"))
    return [section]


def toe_off_percent(analysis: SessionAnalysis) -> dict[str, float]:
    """Per side, the mean terminal contact of the strides used, in % of the stride (NaN without)."""
    out = {}
    for side in SIDES:
        values = [100.0 * (r["terminal_contact_s"] - r["start_s"]) / (r["end_s"] - r["start_s"])
                  for r in analysis.used if r["side"] == side and r["end_s"] > r["start_s"]
                  and math.isfinite(r["terminal_contact_s"])]
        out[side] = float(sum(values) / len(values)) if values else math.nan
    return out


def joint_curves(analysis: SessionAnalysis, targets: Targets) -> Section:
    section = Section("Joint angles over the stride")
    tol = {n: math.degrees(v) for n, v in targets.reference_tolerance.items()}
    section.add(
        Figure(
            figures.joint_curves(analysis, targets.reference_tolerance, toe_off_percent(analysis)),
            "Sagittal hip, knee and ankle angles from initial contact (IC) to the next one of the same "
            "foot, toe-off (TC) at its mean: mean ± SD of the strides used, on the reference curve "
            f"(dashed) ± the tolerance of the targets (hip {tol['hip_flexion']:.0f}°, knee "
            f"{tol['knee_flexion']:.0f}°, ankle {tol['ankle_dorsiflexion']:.0f}°). Coarse reference: "
            "textbook key values every 5 % of the stride (Perry & Burnfield 2010; Kadaba et al. 1990), "
            "the band a tolerance, not a published SD: check it before training a patient towards it.",
            width=0.6,
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
            "from the reference over the stride) of each variable and side, and the Gait Profile Score "
            f"(GPS; both sides: {shown('gait_profile_score', analysis.gps['overall'])}°), as defined by "
            f"Baker et al. 2009 over the 3 of its 9 variables that have a reference here (missing: "
            f"{', '.join(GPS_MISSING)}). Its minimal clinically important difference is "
            f"{math.degrees(MCID['gait_profile_score'].value):.1f}° (Baker et al. 2012). Against the coarse "
            "reference curves it is for following one patient over sessions, not for comparing with a "
            "laboratory's GPS.",
            width=0.6,
        )
    )
    return section


def strides_section(data: SessionData, analysis: SessionAnalysis) -> Section:
    section = Section("Strides over time")
    section.add(
        Figure(
            figures.strides_over_time(data, analysis),
            "Each stride at its closing initial contact (filled: used; hollow: left out), the "
            "walking bouts of the activity monitor shaded.",
            width=0.75,
        )
    )
    plausible = sum(r["plausible"] for r in data.strides)
    items = [
        f"{len(data.strides)} strides detected ({sum(1 for _, k, _ in data.events if k == 'ic')} initial and "
        f"{sum(1 for _, k, _ in data.events if k == 'tc')} terminal contacts), {plausible} plausible, "
        f"{len(analysis.used)} used",
    ]
    if analysis.walking_bouts is not None:
        bouts = ", ".join(f"{a:.1f}–{b:.1f} s" for a, b in analysis.walking_bouts) or "none"
        outside = analysis.left_out_outside_walking
        items.append(f"walking bouts (activity monitor): {bouts}" + (
            f"; {outside} plausible strides outside them left out (e.g. events of calibration moves)"
            if outside else ""))
    if analysis.left_out_turning:
        items.append(f"{plural(analysis.left_out_turning, 'turning stride')} left out (the foot turned by "
                     f"over {math.degrees(TURN_LIMIT):.0f}° in the stride, or over "
                     f"{math.degrees(WHOLE_TURN_LIMIT):.0f}° with the strides around it)")
    if analysis.left_out_ends:
        items.append(f"{plural(analysis.left_out_ends, 'stride')} starting or ending a walk left out (each "
                     "foot's first stride after a standing and last before a stop)")
    flags = Counter(kind for r in data.strides if not r["plausible"] for kind in flag_kinds(r["flag"]))
    items += [f"not plausible: {n} × {flag}" for flag, n in flags.most_common()]
    spatial = Counter(r["spatial_flag"].split(":")[0] for r in analysis.used if r["spatial_flag"])
    items += [f"no spatial values: {n} × {flag}" for flag, n in spatial.most_common()]
    items += analysis.notes
    section.add(Bullets(items, "note"))
    return section


def activity_section(data: SessionData) -> Section:
    section = Section("Activity")
    if not data.activity:
        return section.add(Paragraph("No activity in this recording.", "note"))
    changes = "".join(f"; {figures.TRANSITIONS.get(code, code)} at {t:.1f} s" for t, code in data.transitions)
    section.add(
        Figure(
            figures.activity_timeline(data),
            "Posture and locomotion of the trunk activity monitor, its postural transitions and the steps "
            f"it counted: {data.steps} steps{changes}.",
            width=0.7,
        )
    )
    return section


def calibration_section(data: SessionData, report: SessionReport) -> list[Section]:
    """The calibration's table, or nothing when every segment was accepted (the summary says so in a
    line; a simulated session keeps its table, for the error to the true mounting)."""
    section = Section("Calibration quality")
    if not data.calibration:
        legs = [seg for seg in data.kit() if seg.endswith(("_thigh", "_shank", "_foot"))]
        if not legs:  # a trunk sensor alone needs none: information, in the summary
            return []
        return [section.add(
            Paragraph("No calibration in force: no joint angles and no gait events.", "warning")
        )]
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
    simulated = any(report.calibration.get(seg, {}).get("error") is not None for seg in data.calibration)
    if not simulated:
        if all(calibration_outcome(e["valid"], e["message"] or "") != "REFUSED"
               for e in data.calibration.values()):
            return []  # the summary's line says so, and what the kit lacks
        header, rows = header[:-1], [row[:-1] for row in rows]  # a real recording: no true mounting
    return [section.add(Table(header, rows))]


STAGE_WORDS = {
    "orientation_filter": "orientation",
    "imu_driver": "sensor link",
    "imu_replayer": "replay",
    "calibration": "calibration",
    "joint_angles": "joint angles",
    "gait_events": "gait events",
    "activity_monitor": "activity monitor",
    "biofeedback": "feedback",
    "recorder": "recording",
}


def status_name(name: str) -> str:
    """A status of the recording's sensor and processing reports in words: ``orientation_filter: left_foot``
    → ``left foot (orientation)``."""
    stage, _, what = name.partition(": ")
    stage_words = STAGE_WORDS.get(stage, stage.replace("_", " "))
    return f"{what.replace('_', ' ')} ({stage_words})" if what else stage_words


def quality_section(data: SessionData) -> list[Section]:
    """The sensor and processing reports of the session: a table of those that reported a problem, one
    line for the others; nothing when none did (the summary says so in a line)."""
    section = Section("Data quality")
    for text in data.damage:
        section.add(Paragraph(f"DAMAGED RECORDING: {text}. This report covers only what could be read.",
                              "warning"))
    if not data.diagnostics:
        return [section.add(Paragraph("The recording holds no sensor or processing reports: data quality "
                                      "unknown.", "warning"))]
    rows = []
    for name, summary in sorted(data.diagnostics.items()):
        if summary.fine(data.duration_s):
            continue
        counters = ", ".join(f"{k.replace('_', ' ')} {v:g}" for k, v in summary.counted().items())
        base = summary.counters.get("samples", summary.counters.get("received", math.nan))
        rows.append(
            [
                status_name(name),
                (
                    LEVELS.get(summary.worst, str(summary.worst)),
                    "in" if summary.worst == 0 else "warn" if summary.worst == 1 else "bad",
                ),
                f"{base:g}" if math.isfinite(base) else "",
                counters or "none",
            ]
        )
    fine = len(data.diagnostics) - len(rows)
    if rows:
        section.add(Table(["sensor or stage", "worst level", "samples", "problems counted"], rows))
    if fine:
        which = plural(fine, "sensor or stage", "sensors or stages")
        section.add(Paragraph(f"{'The other' if rows else 'All'} {which} reported no problem.", "note"))
    problems = [
        f"{status_name(name)}: {line}"
        for name, s in sorted(data.diagnostics.items())
        for line in grouped_problems(s.news(data.duration_s), s.seen)
    ]
    recovering = int(data.recovering.sum())
    if recovering:
        problems.append(
            f"{recovering} joint-angle samples marked recovering (a sensor back from a dropout): shown, "
            "never evaluated"
        )
    if problems:
        section.add(Bullets(problems))
    return [section] if rows or problems or data.damage else []


def cues_section(analysis: SessionAnalysis, targets_name: str) -> Section:
    """Per quantity, the share of strides in the target band, each side in one row."""
    section = Section("Time in the target band")
    section.add(Paragraph(f"Feedback: {analysis.cue_source} (targets: {targets_name}).", "note"))
    by_quantity: dict[str, dict[str, dict]] = {}
    for key, entry in analysis.cues.items():
        quantity, _, side = key.partition(" (")
        by_quantity.setdefault(quantity, {})[side.rstrip(")") or "both"] = entry
    rows = []
    for quantity, sides in sorted(by_quantity.items()):
        row: list = [quantity_label(quantity)]
        for side in (*SIDES, "both"):
            e = sides.get(side)
            row.append((f"{e['in_band_percent']:.0f} % of {e['cues']}", "in" if e["in_band_percent"] >= 80
                        else "warn") if e else "")
        severe = sum(e["severe"] for e in sides.values())
        row.append(str(severe))
        rows.append(row)
    if rows:
        section.add(Table(["quantity", "left: strides in band", "right: strides in band",
                           "both feet: strides in band", "far outside"], rows))
    else:
        section.add(Paragraph("No stride was compared with a target.", "note"))
    return section


def sources_section(norms: dict[str, NormBand]) -> Section:
    """Every source the report cites, once (a source cited with what was taken from it, such as Perry's
    figures, is listed as the reference alone)."""
    refs = {
        re.sub(r" \([^()]*\)\.$", ".", source)
        for source in {b.source for b in norms.values()} | {m.source for m in MCID.values()}
        | set(normative.REFERENCE_SOURCES) | {BAKER_2009, BAKER_2012}
    }
    return Section("Sources").add(Paragraph(" · ".join(sorted(refs)), "small"))
