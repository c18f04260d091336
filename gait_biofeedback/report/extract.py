"""What a session recording holds for its report: strides, events, joint angles, activity, calibration,
``/diagnostics``, the cues and the summary figures, from one read (a recording of the graph or what
``analyze`` wrote; :mod:`~gait_biofeedback.report.recording`)."""

from __future__ import annotations

import contextlib
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gait_biofeedback.core.biofeedback.evaluator import Stride
from gait_biofeedback.report.recording import CALIBRATION, EVENTS, Recording, read_recording_file
from gait_biofeedback.report.session import SessionReport, summarise
from gait_biofeedback.wire import topics
from gait_biofeedback.wire.biofeedback import given_of
from gait_biofeedback.wire.gait import stride_of
from gait_biofeedback.wire.stamps import stamp_to_ns

GAIT_CYCLE_FIELDS = (
    "stride_index",
    "stride_time",
    "stance_time",
    "swing_time",
    "stance_fraction",
    "swing_fraction",
    "step_time",
    "cadence",
    "double_support_time",
    "double_support_fraction",
    "step_time_symmetry_index",
    "plausible",
    "flag",
    "stride_length",
    "gait_speed",
    "max_foot_height",
    "min_toe_clearance",
    "foot_angle_ic",
    "foot_angle_tc",
    "turning_angle",
    "lateral_excursion",
    "spatial_flag",
    "spatial_provisional",
)
"""Every field of gait_biofeedback_msgs/GaitCycle besides the header, side and stamps (SI, as on the wire;
the spatial ones revised by gait/stride_space: :func:`~gait_biofeedback.wire.gait.revised_cycles`)."""

COUNTERS = (
    "samples",
    "published",
    "nan_skipped",
    "no_gyro",
    "out_of_range",
    "duplicates",
    "late",
    "bad_stamps",
    "time_resets",
    "gaps",
    "missing",
    "lost",
    "received",
    "reboots",
)
"""The counters of the ``/diagnostics`` statuses the report sums up as data quality."""
LEVELS = {0: "OK", 1: "WARN", 2: "ERROR", 3: "STALE"}
RESOLVED_S = 5.0
"""s: a stage's "waiting for its data" that stopped this long before the end was the start, not a fault."""
_WAITING = re.compile(r"\byet\b|\bwaiting for\b")


class NotASessionError(ValueError):
    """The recording has no outputs of the graph."""


@dataclass
class StatusSummary:
    """One ``/diagnostics`` status name over the session: worst level, its last counters, and each
    distinct WARN/ERROR/STALE message with the time (s into the session) it was first seen, and (in
    ``seen``) the last time and how many reports said it."""

    worst: int = 0
    counters: dict[str, float] = field(default_factory=dict)
    problems: dict[str, float] = field(default_factory=dict)
    seen: dict[str, tuple[float, int]] = field(default_factory=dict)

    def news(self, end_s: float = math.inf) -> dict[str, float]:
        """The problems besides what every start says: the orientation filters' start-up, and a stage
        waiting for its first data ("no ... yet", "waiting for ...") that stopped saying so more than
        :data:`RESOLVED_S` before ``end_s`` (the session's end, s): the data came. A wait that lasted to
        the end is news (the data never came)."""
        return {text: t for text, t in self.problems.items() if "start-up" not in text
                and not (_WAITING.search(text) and self.seen.get(text, (t, 1))[0] < end_s - RESOLVED_S)}

    def counted(self) -> dict[str, float]:
        """The problem counters that are not zero (samples and messages counted are no problem)."""
        return {k: v for k, v in self.counters.items() if v and k not in ("samples", "published", "received")}

    def fine(self, end_s: float = math.inf) -> bool:
        """Nothing to report until ``end_s``: no problem but those of every start (:meth:`news`), no
        problem counted."""
        return not self.news(end_s) and not self.counted()


@dataclass
class SessionData:
    """The outputs of one session; times in s from the first message."""

    path: Path
    start_ns: int
    duration_s: float
    strides: list[dict]
    events: list[tuple[str, str, float]]
    joint_t: np.ndarray
    joints: dict[str, np.ndarray]
    recovering: np.ndarray
    activity: list[tuple[float, int, int, int, float]]
    transitions: list[tuple[float, int]]
    steps: int
    calibration: dict[str, dict]
    diagnostics: dict[str, StatusSummary]
    cues: list[dict]
    counts: dict[str, int]
    given: list[dict] = field(default_factory=list)  # feedback given (the dose): given_of + "t" (s)
    stride_objects: list = field(default_factory=list)
    damage: list[str] = field(default_factory=list)  # the file was damaged: what was lost, in words
    summary: SessionReport = field(default_factory=SessionReport)  # its figures, from the same read

    def seconds(self, ns: int) -> float:
        return (ns - self.start_ns) / 1e9

    def kit(self) -> set[str]:
        """The segments whose IMU topics the recording has."""
        return {seg for t in self.counts if (seg := topics.segment_of(t)) is not None}


def _level(raw) -> int:
    return raw[0] if isinstance(raw, (bytes, bytearray)) else int(raw)


def read_session(path: str | Path) -> SessionData:
    """Read one session (once, :func:`~gait_biofeedback.report.recording.read_recording`: its data and
    its figures, :attr:`SessionData.summary`); :class:`NotASessionError` (naming what to run) when it
    holds no graph outputs. A damaged file is read as far as it can be, and what was lost is in
    :attr:`SessionData.damage`."""
    path = Path(path)
    recording = read_recording_file(path)
    outputs = [t.absolute() for t in (topics.GAIT_CYCLES, topics.JOINT_STATES, topics.ACTIVITY)]
    if not any(t in recording.counts for t in outputs):
        raise _not_a_session(path, recording.counts, recording.damage)
    return session_data(recording)


def _not_a_session(path: Path, counts: dict[str, int], damage: list[str]) -> NotASessionError:
    why = f"{path} holds no gait/cycles, joint_states or activity/state: "
    if not counts:
        damage = "; ".join(damage) or "the file holds none"
        return NotASessionError(why + f"no message could be read ({damage}); check it with `gait-biofeedback "
                                f"info {path}` and `repair` it, or report the recording it was made from")
    if not any(t.endswith("/imu/data") or t == "/diagnostics" for t in counts):
        return NotASessionError(why + f"it is a raw recording. Run `gait-biofeedback analyze {path} -o OUT "
                                "--calibrate-at auto` and report OUT")
    if counts.get(topics.CALIBRATION.absolute()):
        return NotASessionError(why + "a calibration was published, but no stride, joint angle or activity "
                                "followed it (pressed at the end of the walk, or nothing moved after it): "
                                "analyse the raw recording (`analyze --calibrate-at auto` puts the "
                                "calibration in force from the start)")
    return NotASessionError(why + "it was processed, but no calibration took effect and no trunk sensor gave "
                            "activity: analyse the raw recording again with a --calibrate-at request that "
                            "succeeds (or --calibration FILE)")


def stride_row(msg: Any, start_ns: int) -> tuple[dict[str, Any], Stride]:
    """(the report's row of a ``gait/cycles`` message: ``side``, ``start_s`` (its opening IC),
    ``terminal_contact_s`` (NaN without one), ``end_s`` (its closing IC), s from ``start_ns``, and every
    :data:`GAIT_CYCLE_FIELDS` as on the wire; the evaluator's view of it,
    :func:`~gait_biofeedback.wire.gait.stride_of`)."""
    stride = stride_of(msg)
    row = {
        "side": stride.side,
        "start_s": (stride.start_ns - start_ns) / 1e9,
        "terminal_contact_s": (math.nan if stride.tc_ns is None else (stride.tc_ns - start_ns) / 1e9),
        "end_s": (stride.end_ns - start_ns) / 1e9,
    }
    row.update({name: getattr(msg, name) for name in GAIT_CYCLE_FIELDS})
    return row, stride


def session_data(recording: Recording) -> SessionData:
    """The report's data of a session from what :func:`~gait_biofeedback.report.recording.read_recording`
    read, its figures (:func:`~gait_biofeedback.report.session.summarise`) included."""
    start_ns = recording.start_ns
    calibration: dict[str, dict] = {}
    for topic, msg, log_ns in recording.calibrations:
        if topic != CALIBRATION:
            continue
        for seg in msg.segments:
            calibration[seg.segment] = {
                "valid": bool(seg.valid),
                "quality": float(seg.quality),
                "message": seg.message,
                "at_s": (log_ns - start_ns) / 1e9,
            }
    cues = [
        {
            "t": (stamp_to_ns(msg.header.stamp) - start_ns) / 1e9,
            "quantity": msg.quantity,
            "side": msg.side,
            "unit": msg.unit,
            "measured": msg.measured,
            "error": msg.error,
            "severity": int(msg.severity),
            "stride_index": int(msg.stride_index),
        }
        for msg in recording.cues
    ]
    diagnostics: dict[str, StatusSummary] = {}
    for msg, log_ns in recording.diagnostics:
        for status in msg.status:
            summary = diagnostics.setdefault(status.name, StatusSummary())
            level = _level(status.level)
            summary.worst = max(summary.worst, level)
            if level:
                text, t = f"{LEVELS.get(level, level)}: {status.message}", (log_ns - start_ns) / 1e9
                summary.problems.setdefault(text, t)
                summary.seen[text] = (t, summary.seen.get(text, (t, 0))[1] + 1)
            for kv in status.values:
                if kv.key in COUNTERS:
                    with contextlib.suppress(ValueError):
                        summary.counters[kv.key] = float(kv.value)
    strides, stride_objects = [], []
    for msg in recording.cycles:
        row, stride = stride_row(msg, start_ns)
        strides.append(row)
        stride_objects.append(stride)
    joints = recording.joint_rows()
    return SessionData(
        path=recording.path,
        start_ns=start_ns,
        duration_s=recording.duration_ns / 1e9,
        strides=strides,
        events=[(side, kind, (stamp_ns - start_ns) / 1e9)
                for topic, side, kind, stamp_ns in recording.events if topic == EVENTS],
        joint_t=np.array(joints.stamps, dtype=np.int64),
        joints=joints.columns(),
        recovering=np.array(joints.recovering, dtype=bool),
        activity=[((stamp_ns - start_ns) / 1e9, *state) for stamp_ns, *state in recording.activity],
        transitions=[((stamp_ns - start_ns) / 1e9, kind) for stamp_ns, kind in recording.transitions],
        steps=recording.steps,
        calibration=calibration,
        diagnostics=diagnostics,
        cues=cues,
        counts=recording.counts,
        given=[{**g, "t": (g["stamp_ns"] - start_ns) / 1e9} for g in map(given_of, recording.given)],
        stride_objects=stride_objects,
        damage=recording.damage,
        summary=summarise(recording),
    )
