"""One session of a batch, as a Dask task: ``analyze`` (:func:`~gait_biofeedback.analyze.analyze_recording`)
into ``<out>/<session>/analysis``, the report (:func:`~gait_biofeedback.report.build.write_report`)
into ``<out>/<session>/report``, and the session's row of the cohort table. What happened is written
last, atomically, to ``<out>/<session>/session.json``: a re-run skips a session whose file says
``done`` for the same recording (:func:`~gait_biofeedback.cohort.sessions.fingerprint`); a failed one
is tried again. A recording that fails gives a ``failed`` row with the error, never an exception, so
the batch goes on."""

from __future__ import annotations

import json
import os
import resource
import time
import traceback
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from gait_biofeedback.cohort.sessions import Recording, fingerprint

SESSION_FILE = "session.json"
ANALYSIS = "analysis"
REPORT = "report"
UNITS = {"gait_speed": "m_per_s", "stride_length": "m", "step_length": "m", "cadence": "steps_per_s",
         "stride_time": "s", "step_time": "s", "stance_fraction": "ratio", "swing_fraction": "ratio",
         "double_support_fraction": "ratio"}
"""The SI unit of each spatiotemporal parameter, in its column names (``gait_speed_m_per_s_left``)."""


@dataclass(frozen=True)
class BatchOptions:
    """What every session of a batch is analysed with: ``calibrate_at`` as ``analyze
    --calibrate-at`` takes it (default: found in the movement), ``params`` node → values from a
    checked parameter file, ``report`` whether each session gets its report files."""

    calibrate_at: tuple[str, ...] = ("auto",)
    params: dict[str, dict[str, Any]] = field(default_factory=dict)
    report: bool = True


def session_dir(out: Path, recording: Recording) -> Path:
    return out / recording.name


def previous(out: Path, recording: Recording) -> dict | None:
    """The row of an earlier run when it analysed this same recording successfully, else None."""
    path = session_dir(out, recording) / SESSION_FILE
    try:
        done = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if done.get("status") != "done" or done.get("fingerprint") != fingerprint(recording.path):
        return None
    if not (session_dir(out, recording) / ANALYSIS).is_dir():
        return None
    return done.get("row")


def analyse_one(recording: Recording, out: str | Path, options: BatchOptions) -> dict[str, Any]:
    """Analyse one recording (module docstring) → its cohort row (``status`` done or failed)."""
    from gait_biofeedback.analyze import analyze_recording, parse_calibrate_at

    where = session_dir(Path(out), recording)
    where.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    row: dict[str, Any] = {"session": recording.name, "recording": str(recording.path)}
    record = {"fingerprint": fingerprint(recording.path)}
    try:
        requests = [parse_calibrate_at(text) for text in options.calibrate_at]
        result = analyze_recording(recording.path, where / ANALYSIS, calibrate_at=requests,
                                   params=options.params, overwrite=True)
        row.update(_parameters(where, options.report))
        row["calibrated"] = any(c.success for c in result.calibrations)
        row["warnings"] = len(result.warnings)
        row["status"], row["error"] = "done", ""
        record["warnings"] = result.warnings[:50]
    except Exception as err:  # one bad recording must not end the batch
        row["status"], row["error"] = "failed", f"{type(err).__name__}: {err}"
        record["traceback"] = traceback.format_exc()
    row["analysis_s"] = round(time.perf_counter() - started, 3)
    row["worker_peak_rss_mb"] = round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)
    record.update(status=row["status"], row=row, options=asdict(options))
    _write_atomically(where / SESSION_FILE, json.dumps(record, indent=1, default=str, allow_nan=True))
    return row


def _parameters(where: Path, with_report: bool) -> dict[str, Any]:
    """The cohort columns of an analysed session: the report's own figures (same code, same numbers)."""
    from gait_biofeedback.core.biofeedback.evaluator import default_targets_path, load_targets
    from gait_biofeedback.report.analysis import TABLE, analyse_session
    from gait_biofeedback.report.build import write_report
    from gait_biofeedback.report.extract import read_session

    if with_report:  # the session read once, for the report and the row
        files = write_report([where / ANALYSIS], where / REPORT, overwrite=True)
        data, analysis = files.sessions[-1], files.analyses[-1]
    else:
        data = read_session(where / ANALYSIS)
        analysis = analyse_session(data, load_targets(default_targets_path()))
    row: dict[str, Any] = {"duration_s": round(data.duration_s, 3), "strides": len(analysis.strides),
                           "strides_used": len(analysis.used)}
    for name in TABLE:
        for side, (mean, _sd, _n) in analysis.table[name].items():
            row[f"{name}_{UNITS[name]}_{side}"] = mean
    for name, value in analysis.symmetry.items():
        row[f"symmetry_{name}_ratio"] = value
    for part, value in analysis.gps.items():
        row[f"gait_profile_score_rad_{part}"] = value
    return row


def _write_atomically(path: Path, text: str) -> None:
    temporary = path.with_name(path.name + ".part")
    temporary.write_text(text)
    os.replace(temporary, path)
