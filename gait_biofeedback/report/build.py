"""``gait-biofeedback report SESSION [SESSION ...] -o DIR``: report.html, report.pdf, strides.csv, joints.csv.

The last session is reported in full, its summary first; with several (one patient's, in the order
given, the first the baseline) the progress across them follows the summary. The CSVs hold every
session's strides, with a ``session`` column.
strides.csv: one row per stride, every GaitCycle field as on the wire (SI), the side, the stamps as s
into the session, ``used`` (plausible and inside a walking bout), ``step_length`` and the kinematic cue
quantities (rad). joints.csv: per stride and joint angle, the values at IC and TC, min, max, range of
motion and peak in swing, in rad (``*_deg`` columns repeat them in degrees for a spreadsheet).

The patient is named only by a pseudonymous id (``patient:`` block of the session parameters or
``--patient-id``): nothing else about the patient is written, and the id is not logged.
"""

from __future__ import annotations

import csv
import datetime as dt
import math
import re
from dataclasses import dataclass
from pathlib import Path

import yaml

from gait_biofeedback.core.biofeedback.evaluator import STROKE, default_targets_path, load_targets
from gait_biofeedback.core.safe_yaml import describe, load_yaml_file
from gait_biofeedback.parameters import PATIENT_BLOCK, PATIENT_KEYS, patient_block
from gait_biofeedback.report import content, dose, overview
from gait_biofeedback.report.analysis import SessionAnalysis, analyse_session
from gait_biofeedback.report.document import Document
from gait_biofeedback.report.extract import GAIT_CYCLE_FIELDS, SessionData, read_session
from gait_biofeedback.report.html import render_html
from gait_biofeedback.report.norms import NORMS, load_norms
from gait_biofeedback.report.pdf import render_pdf
from gait_biofeedback.report.progress import progress_section

_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,31}$")
KINEMATIC = (
    "knee_flexion_peak_swing",
    "knee_flexion_at_ic",
    "hip_extension_peak_stance",
    "ankle_dorsiflexion_at_ic",
    *STROKE,
)
JOINT_VALUES = ("at_ic", "at_tc", "min", "max", "range_of_motion", "peak_swing")


@dataclass(frozen=True)
class Patient:
    """Pseudonymous patient id and session label (module docstring)."""

    id: str = ""
    session: str = ""

    def __post_init__(self) -> None:
        for key in PATIENT_KEYS:
            value = getattr(self, key)
            if value and not _ID.match(value):
                raise ValueError(
                    f"patient {key} {value!r}: use a pseudonymous code of letters, digits, '_', '-' "
                    "or '.' (at most 32), never a name"
                )


def patient_from_params(path: str | Path) -> Patient:
    """The ``patient:`` block of a session parameter file
    (:func:`~gait_biofeedback.parameters.patient_block`); empty without one."""
    try:
        document = load_yaml_file(path) or {}
    except OSError as exc:
        raise ValueError(f"{path}: cannot read the patient block: {exc}") from None
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: cannot read the patient block: {describe(exc)}") from None
    if not isinstance(document, dict) or PATIENT_BLOCK not in document:
        return Patient()
    return Patient(**patient_block(path, document[PATIENT_BLOCK]))


@dataclass
class ReportFiles:
    html: Path
    pdf: Path
    strides_csv: Path
    joints_csv: Path
    analyses: list[SessionAnalysis]
    damage: list[str]  # what the sessions' damaged files lost, in words (also in the report's Data quality)
    sessions: list[SessionData]  # what was read of each session (once)


def _recorded(data: SessionData, date: str | None = None) -> str:
    """The session's date: ``date`` when given, else the recording's clock, unless that starts before
    2000 (a simulated or imported time base, which holds no date)."""
    if date:
        return date
    if data.start_ns < 946684800 * 10**9:
        return "not in the recording (imported or simulated); give it with the report's date option"
    return dt.datetime.fromtimestamp(data.start_ns * 1e-9, dt.UTC).strftime("%Y-%m-%d %H:%M UTC")


_DATE = re.compile(r"^\d{4}-\d{2}-\d{2}( \d{2}:\d{2})?$")


def check_date(date: str) -> str:
    """A session date as given (``YYYY-MM-DD`` or ``YYYY-MM-DD HH:MM``), checked."""
    if not _DATE.match(date):
        raise ValueError(f"report: date {date!r}: write it as YYYY-MM-DD or 'YYYY-MM-DD HH:MM'")
    try:
        dt.datetime.strptime(date, "%Y-%m-%d %H:%M" if " " in date else "%Y-%m-%d")
    except ValueError:
        raise ValueError(f"report: date {date!r} is no calendar date") from None
    return date


def _write_csvs(out: Path, labels: list[str], analyses: list[SessionAnalysis]) -> tuple[Path, Path]:
    strides, joints = out / "strides.csv", out / "joints.csv"
    used_keys = [{(r["side"], r["stride_index"]): r for r in a.used} for a in analyses]
    with strides.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(
            [
                "session",
                "side",
                "start_s",
                "terminal_contact_s",
                "end_s",
                *GAIT_CYCLE_FIELDS,
                "used",
                "step_length",
                *KINEMATIC,
            ]
        )
        for label, a, used in zip(labels, analyses, used_keys, strict=True):
            for r in a.strides:
                u = used.get((r["side"], r["stride_index"]))
                w.writerow(
                    [
                        label,
                        r["side"],
                        r["start_s"],
                        r["terminal_contact_s"],
                        r["end_s"],
                        *(r[k] for k in GAIT_CYCLE_FIELDS),
                        u is not None,
                        *((u.get(k, math.nan) if u else math.nan) for k in ("step_length", *KINEMATIC)),
                    ]
                )
    with joints.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(
            [
                "session",
                "side",
                "stride_index",
                "start_s",
                "angle",
                *JOINT_VALUES,
                *(f"{k}_deg" for k in JOINT_VALUES),
            ]
        )
        for label, a in zip(labels, analyses, strict=True):
            for r in a.discrete:
                w.writerow(
                    [
                        label,
                        r["side"],
                        r["stride_index"],
                        r["start_s"],
                        r["angle"],
                        *(r[k] for k in JOINT_VALUES),
                        *(round(math.degrees(r[k]), 3) for k in JOINT_VALUES),
                    ]
                )
    return strides, joints


REPORT_FILES = ("report.html", "report.pdf", "strides.csv", "joints.csv")


def write_report(
    sessions: list[str | Path],
    output: str | Path,
    patient: Patient | None = None,
    labels: list[str] | None = None,
    norms_file: str | Path | None = None,
    targets_file: str | Path | None = None,
    overwrite: bool = False,
    date: str | None = None,
    paretic_side: str = "none",
) -> ReportFiles:
    """The report files of ``sessions`` in ``output`` (module docstring). A folder that already holds a
    report is refused unless ``overwrite``; so is a session given twice. ``date``: the last session's
    (``YYYY-MM-DD[ HH:MM]``), for a recording whose clock holds none. ``paretic_side``: the patient's
    ("none", "left", "right"), for the targets' paretic bands and the paretic asymmetry ratios."""
    if not sessions:
        raise ValueError("report: give at least one session (a recording of the graph or an analyze output)")
    resolved = [Path(s).resolve() for s in sessions]
    twice = [s for s, r in zip(sessions, resolved, strict=True) if resolved.count(r) > 1]
    if twice:
        raise ValueError(f"report: session {twice[0]} is given twice; give each session once, oldest first")
    out = Path(output)
    if out.exists() and not out.is_dir():
        raise FileExistsError(f"report: {out} is a file; the report is written to a folder")
    taken = [name for name in REPORT_FILES if (out / name).exists()]
    if taken and not overwrite:
        raise FileExistsError(f"report: {out} already holds a report ({', '.join(taken)}): write to another "
                              "folder, or pass --overwrite to replace it")
    date = check_date(date) if date else None
    patient = patient or Patient()
    labels = list(labels) if labels else [Path(s).name for s in sessions]
    if len(labels) != len(sessions):
        raise ValueError(f"report: {len(labels)} labels for {len(sessions)} sessions")
    if patient.session:
        labels[-1] = patient.session
    norms = load_norms(norms_file) if norms_file else dict(NORMS)
    targets_path = Path(targets_file) if targets_file else default_targets_path()
    targets = load_targets(targets_path, paretic_side)
    datas = [read_session(s) for s in sessions]
    analyses = [analyse_session(d, targets) for d in datas]
    data, analysis = datas[-1], analyses[-1]
    summary = data.summary
    out.mkdir(parents=True, exist_ok=True)
    header = [
        ("patient", patient.id or "not given"),
        ("session", labels[-1]),
        ("recorded", _recorded(data, date)),
        ("duration", f"{data.duration_s:.0f} s"),
        ("recording", data.path.name + (" (DAMAGED: only what could be read, see Data quality)"
                                        if data.damage else "")),
        ("report made", dt.datetime.now(dt.UTC).strftime("%Y-%m-%d %H:%M UTC")),
    ]
    if len(sessions) > 1:
        header.append(("sessions compared", ", ".join(labels)))
    curves = content.has_joint_curves(analysis)
    gait = []  # none without strides: the summary says why
    if data.strides:
        gait = [content.spatiotemporal(analysis, norms),
                *((content.profile_score(analysis), content.joint_curves(analysis, targets))
                  if curves else content.no_joint_curves(analysis)),
                content.strides_section(data, analysis)]
    why_none = "" if data.strides else content.no_strides_reason(data)
    sections = [
        overview.summary(data, analysis, norms, has_curves=curves, no_strides=why_none),
        *([progress_section(labels, analyses)] if len(sessions) > 1 else []),
        *gait,
        content.activity_section(data),
        *content.calibration_section(data, summary),
        *content.quality_section(data),
        *([content.cues_section(analysis, targets_path.name)] if data.cues else []),
        *([dose.dose_section(data)] if dose.instructions_recorded(data) else []),
        content.sources_section(norms),
    ]
    doc = Document("Gait session report", header, sections)
    html = out / "report.html"
    html.write_text(render_html(doc))
    pdf = render_pdf(doc, out / "report.pdf")
    strides, joints = _write_csvs(out, labels, analyses)
    return ReportFiles(html, pdf, strides, joints, analyses, [text for d in datas for text in d.damage],
                       datas)
