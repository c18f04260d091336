"""The calibration file (``calibration.yaml``): written with a digest of its entries, checked when loaded.

Fields, in the order written: those of :meth:`SessionCalibration.to_dict` (``protocol``, ``success``,
``message``, ``standing``, ``motion``, ``looks_like``, ``segments``: one entry per segment, its
``rotation`` r (w, x, y, z; segment → sensor) written as Python's shortest round-trip repr, so read
back bit for bit), ``saved_at`` (ISO time), ``digest`` and, last, ``complete: true``. ``digest`` holds
``algorithm: sha256``, ``file``: the SHA-256 of the canonical JSON (:func:`canonical`) of every field
above it, and ``segments``: one SHA-256 per segment entry, which names the segment whose entry changed.

The digest detects edits and corruption since the file was written; it is not a signature: whoever
edits the file on purpose can recompute it. So every entry's values are checked too
(:func:`entry_problems`), digest or not. A file without ``digest`` (written before digests were
added) is accepted, with a note saying so: refusing it would throw away a patient's earlier
calibrations, and it gains no protection from a digest that anyone can delete or recompute; its
values are checked all the same.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.calibration.sensor_to_segment import (
    SegmentCalibrationResult,
    SessionCalibration,
    label,
)
from gait_biofeedback.core.safe_yaml import clip, load_yaml_file, shown
from gait_biofeedback.core.segments import SEGMENTS

CALIBRATION_FILE = "calibration.yaml"
"""The file a session's calibration is saved to (in ``session_dir``) and reloaded from."""

UNIT_TOLERANCE = 1e-6
"""Largest | |r| − 1 | of a rotation loaded. The writer keeps every bit (YAML of Python's shortest
round-trip repr, up to 17 significant digits) of rotations normalised to within about 3e-16 (the
calibration's ``quat.from_matrix``), so this leaves a margin of 10 orders of magnitude; an edit that
moves |r| by less is caught by the digest only."""

DIGEST_ALGORITHM = "sha256"
_NOT_ENTRIES = ("digest", "complete")  # the fields the file digest does not cover


@dataclass(frozen=True)
class LoadedCalibration:
    """A calibration file that passed every check: the calibration as written, ``saved_at``,
    ``missing`` (the session's segments it has no entry for: not calibrated by it) and ``notes``
    (things to log at info level, e.g. a file without digest)."""

    calibration: SessionCalibration
    saved_at: str
    missing: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()


def canonical(value: Any) -> bytes:
    """UTF-8 JSON of ``value`` with sorted keys, no spaces, floats as their shortest round-trip repr."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=False,
                      allow_nan=True).encode("utf-8")


def _sha256(value: Any) -> str:
    return hashlib.sha256(canonical(value)).hexdigest()


def file_digest(body: Mapping[str, Any]) -> dict[str, Any]:
    """The ``digest`` field of a file whose other fields (all but ``digest`` and ``complete``) are
    ``body`` as read back: SHA-256 of the whole, and of each segment entry."""
    entries = body.get("segments") or {}
    return {"algorithm": DIGEST_ALGORITHM, "file": _sha256(dict(body)),
            "segments": {str(s): _sha256(e) for s, e in entries.items()}}


def _real(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def entry_problems(name: Any, entry: Any) -> list[str]:
    """What is wrong with one segment entry as read from the file (empty: nothing). Checked: a known
    segment name matching the entry's ``segment``, ``rotation`` four finite numbers with
    | |r| − 1 | <= :data:`UNIT_TOLERANCE`, ``valid`` a boolean, ``quality`` in [0, 1] and
    ``standing_motion`` >= 0 (either may be NaN, not measured, only in an invalid entry)."""
    if name not in SEGMENTS:
        return [f"not a segment name (known: {', '.join(SEGMENTS)})"]
    if not isinstance(entry, Mapping):
        return ["its entry is not a mapping"]
    problems = []
    if entry.get("segment") != name:
        problems.append(f"its entry says segment {shown(entry.get('segment'))}")
    r = entry.get("rotation")
    if not (isinstance(r, list) and len(r) == 4 and all(_real(v) for v in r)):
        problems.append("rotation is not four numbers (w, x, y, z)")
    elif not all(math.isfinite(v) for v in r):
        problems.append("rotation has a value that is not a finite number")
    else:
        norm = math.sqrt(math.fsum(float(v) * float(v) for v in r))
        if abs(norm - 1.0) > UNIT_TOLERANCE:
            problems.append(f"rotation is not a unit quaternion (|r| = {norm:.9g}, "
                            f"allowed 1 ± {UNIT_TOLERANCE:g})")
    valid = entry.get("valid")
    if not isinstance(valid, bool):
        problems.append("'valid' is not true or false")
    for key, low, high in (("quality", 0.0, 1.0), ("standing_motion", 0.0, math.inf)):
        v = entry.get(key)
        if not _real(v) or (math.isnan(v) and valid is not False) or not (
                math.isnan(v) or (math.isfinite(v) and low <= v <= high)):
            problems.append(f"'{key}' is {shown(v)}, not a finite number in [{low:g}, {high:g}]")
    if not isinstance(entry.get("quality_metric"), str) or not isinstance(entry.get("message", ""), str):
        problems.append("'quality_metric' or 'message' is not text")
    if not isinstance(entry.get("details", {}), Mapping):
        problems.append("'details' is not a mapping")
    return problems


def _header_problems(document: Mapping[str, Any]) -> list[str]:
    problems = []
    if not isinstance(document.get("success"), bool):
        problems.append("'success' is not true or false")
    for key in ("standing", "motion"):
        window = document.get(key)
        if window is not None and not (isinstance(window, list) and len(window) == 2
                                       and all(_real(v) and math.isfinite(v) for v in window)
                                       and window[0] <= window[1]):
            problems.append(f"'{key}' is {window!r}, not null or a window [start, end] in s")
    if not isinstance(document.get("segments"), Mapping):
        problems.append("'segments' is not a mapping")
    return problems


def _digest_problems(document: Mapping[str, Any]) -> dict[str, list[str]]:
    """Per segment ('' for the fields outside the entries) what the digest says changed."""
    digest = document["digest"]
    ok = (isinstance(digest, Mapping) and digest.get("algorithm") == DIGEST_ALGORITHM
          and isinstance(digest.get("file"), str) and isinstance(digest.get("segments"), Mapping))
    if not ok:
        return {"": [f"its digest is not an {DIGEST_ALGORITHM} digest as written (edited?)"]}
    body = {k: v for k, v in document.items() if k not in _NOT_ENTRIES}
    written, entries = digest["segments"], body.get("segments")
    entries = entries if isinstance(entries, Mapping) else {}
    problems: dict[str, list[str]] = {}
    for name in [*written, *(s for s in entries if s not in written)]:
        if name not in entries:
            why = "its entry was deleted (the digest written with the file lists it)"
        elif name not in written:
            why = "its entry was added after the file was written (the digest does not list it)"
        elif _sha256(entries[name]) != written[name]:
            why = "its entry changed since the file was written (it no longer matches its digest)"
        else:
            continue
        problems[str(name)] = [why]
    if not problems and _sha256(body) != digest["file"]:
        problems[""] = ["its fields no longer match the file's digest: edited or corrupted since it was "
                        "written (a header field, or an entry deleted with its digest line; which one cannot "
                        "be told)"]
    return problems


def _refusal(path: Path, what: str) -> ValueError:
    return ValueError(" ".join(f"{path} is not a usable calibration file: {what}; calibrate again".split()))


def check_calibration_document(document: Any) -> list[str]:
    """Every problem of a parsed calibration file (empty: usable), each ``'<segment>: <what>'`` when it
    belongs to one segment. Checks the end marker, the digest (when there is one) and every value."""
    if not isinstance(document, dict) or document.get("complete") is not True:
        return ["it is incomplete (cut off while it was written?)"]
    per_segment = _digest_problems(document) if "digest" in document else {}
    general = per_segment.pop("", []) + _header_problems(document)
    entries = document.get("segments")
    for name, entry in (entries.items() if isinstance(entries, Mapping) else ()):
        found = entry_problems(name, entry)
        if found:
            per_segment.setdefault(str(name), []).extend(found)
    return general + [f"{clip(name)}: {', '.join(found)}" for name, found in per_segment.items()]


def _calibration(document: Mapping[str, Any]) -> SessionCalibration:
    """The checked document as a calibration; rotations taken as written (no renormalising)."""
    calibration = SessionCalibration.from_dict(document)
    for name, result in calibration.segments.items():
        result.rotation = np.array(document["segments"][name]["rotation"], dtype=float)
    return calibration


def write_calibration_file(path: str | Path, calibration: SessionCalibration, saved_at: str) -> None:
    """Save a calibration atomically (a temporary file renamed over the old one, so a crash leaves the
    old file or the new one, never half of one), in the format of the module docstring. ValueError,
    nothing written, when an entry would not pass the loading checks."""
    path = Path(path)
    written = {**calibration.to_dict(), "saved_at": str(saved_at)}
    body = yaml.safe_load(yaml.safe_dump(written, sort_keys=False))  # the digest covers what is read back
    document = {**body, "digest": file_digest(body), "complete": True}
    problems = check_calibration_document(document)
    if problems:
        raise ValueError(f"calibration not saved to {path}: {'; '.join(problems)}")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        with open(tmp, "w") as f:
            f.write(yaml.safe_dump(document, sort_keys=False))
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def load_calibration_file(path: str | Path, segments: Sequence[str] = ()) -> LoadedCalibration:
    """A file :func:`write_calibration_file` wrote, checked (module docstring); ``segments``: the
    session's, those without an entry are returned in ``missing``. ValueError, one line naming the file,
    the segment and what is wrong: unreadable, cut off, edited since written (digest), a bad value, or
    no entry for any of ``segments``."""
    path = Path(path)
    try:
        document = load_yaml_file(path)
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise _refusal(path, f"not readable as YAML ({exc})") from None
    try:
        problems = check_calibration_document(document)
    except (TypeError, ValueError, RecursionError) as exc:  # keys or values JSON cannot hold
        problems = [f"a value of an unexpected type ({exc})"]
    if problems:
        raise _refusal(path, "; ".join(problems))
    try:
        calibration = _calibration(document)
    except (KeyError, TypeError, AttributeError, ValueError) as exc:
        raise _refusal(path, str(exc)) from None
    missing = tuple(s for s in segments if s not in calibration.segments)
    if segments and len(missing) == len(segments):
        raise _refusal(path, f"no entry for any of this session's segments ({', '.join(segments)})")
    notes = () if "digest" in document else (
        f"{path} carries no digest (written by an older version): its values are checked, edits to "
        "them cannot be told",)
    return LoadedCalibration(calibration, str(document.get("saved_at", "")), missing, notes)


def read_calibration_file(path: str | Path, segments: Sequence[str] = ()) -> tuple[SessionCalibration, str]:
    """(calibration, saved_at) of a file :func:`load_calibration_file` accepts with an entry for every
    one of ``segments``: ValueError otherwise (then nothing of it is used)."""
    loaded = load_calibration_file(path, segments)
    if loaded.missing:
        raise _refusal(Path(path), f"no entry for {', '.join(loaded.missing)}")
    return loaded.calibration, loaded.saved_at


def missing_text(path: str | Path, missing: Sequence[str]) -> str:
    """The warning for a file put in force without entries for ``missing``."""
    return (f"{path} has no entry for {', '.join(missing)}: not calibrated (the others are); "
            "calibrate again to calibrate every segment")


def placeholder(segment: str, path: str | Path) -> SegmentCalibrationResult:
    """An invalid entry standing for ``segment`` absent from the file at ``path`` (consumers and the
    dashboard then count it as not calibrated)."""
    return SegmentCalibrationResult(segment, quat.IDENTITY.copy(), False, 0.0, "", float("nan"),
                                    f"{label(segment)}: no entry in {path}: calibrate again")
