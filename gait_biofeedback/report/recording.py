"""One read of a session recording for everything the report says of it (issue 46).

The graph's outputs (``gait/cycles``, ``gait/stride_space``, ``gait/events``, ``joint_states``,
``activity/state``, ``calibration/sensor_to_segment``, ``biofeedback/cues``, ``biofeedback/given``,
``/diagnostics``) and,
for a simulated session, its ``/ground_truth/...`` topics, read once in log order into a
:class:`Recording`: what :func:`~gait_biofeedback.report.extract.read_session` (the report's data) and
:func:`~gait_biofeedback.report.session.summarise` (its figures against the truth) are made of.
"""

from __future__ import annotations

import math
import warnings
from array import array
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gait_biofeedback.io.bag import BagReader, BagRecoveryWarning
from gait_biofeedback.wire import topics
from gait_biofeedback.wire.activity import add_transition
from gait_biofeedback.wire.gait import event_of, revised_cycles
from gait_biofeedback.wire.joints import angles_of, joint_state_of, recovering_of
from gait_biofeedback.wire.stamps import stamp_to_ns

CALIBRATION, TRUE_CALIBRATION = topics.CALIBRATION.absolute(), topics.truth(topics.CALIBRATION)
JOINTS, TRUE_JOINTS = topics.JOINT_STATES.absolute(), topics.truth(topics.JOINT_STATES)
EVENTS, TRUE_EVENTS = topics.GAIT_EVENTS.absolute(), topics.truth(topics.GAIT_EVENTS)
CYCLES, SPACE = topics.GAIT_CYCLES.absolute(), topics.STRIDE_SPACE.absolute()
ACTIVITY, CUES, GIVEN = topics.ACTIVITY.absolute(), topics.CUES.absolute(), topics.GIVEN.absolute()
DIAGNOSTICS = topics.DIAGNOSTICS.absolute()


class JointRows:
    """One ``joint_states`` topic as columns: per stamp (consecutive messages of one stamp merged) the
    angles (rad; NaN where a row has no value for a joint) and whether its first message was marked
    recovering (``recovering``) and which segments it named (``recovering_segments``, comma-separated).
    Columns of machine numbers, not a dict per row: an hour holds 360,000 stamps."""

    def __init__(self) -> None:
        self.stamps = array("q")
        self.recovering = array("b")
        self.recovering_segments: list[str] = []
        self._columns: dict[str, array] = {}

    def add(self, stamp_ns: int, angles: dict[str, float], recovering: Sequence[str]) -> None:
        """One message, in log order (``recovering``: the segments it marks)."""
        if not (self.stamps and stamp_ns == self.stamps[-1]):
            self.stamps.append(stamp_ns)
            self.recovering.append(bool(recovering))
            self.recovering_segments.append(",".join(recovering))
            for column in self._columns.values():
                column.append(math.nan)
        rows = len(self.stamps)
        for name, value in angles.items():
            column = self._columns.get(name)
            if column is None:
                column = self._columns[name] = array("d", [math.nan]) * rows
            column[-1] = value

    def columns(self) -> dict[str, np.ndarray]:
        """Joint name → its angle per stamp (rad, NaN where absent), names sorted."""
        return {name: np.array(self._columns[name], dtype=float) for name in sorted(self._columns)}

    def by_stamp(self, name: str) -> dict[int, float]:
        """Stamp → the angle ``name``, every message of a stamp merged in log order (also ones not
        consecutive: the last value given wins); stamps in the order first seen."""
        out: dict[int, float] = {}
        column = self._columns.get(name)
        if column is not None:
            for stamp_ns, value in zip(self.stamps, column, strict=True):
                if not math.isnan(value):
                    out[stamp_ns] = value
        return out


@dataclass
class Recording:
    """What one read of a session recording kept; stamps and log times in ns.

    ``cycles``: the ``gait/cycles`` messages with their ``gait/stride_space`` revisions applied
    (:func:`~gait_biofeedback.wire.gait.revised_cycles`); ``events``: (topic, side,
    kind, stamp) of the detected and true gait events; ``joints``: topic → rows (detected and true);
    ``activity``: (stamp, posture, locomotion, step count, trunk inclination) of each state and
    ``transitions`` (stamp, code), ``steps`` the most counted; ``calibrations``: (topic, message, log
    time), estimated and true; ``cues``, ``given`` (the feedback given, the dose): the messages;
    ``diagnostics``: (message, log time);
    ``event_messages``, ``activity_messages``: the detected events' and the activity states' messages
    (the tables, :mod:`~gait_biofeedback.report.tables`)."""

    path: Path
    start_ns: int
    duration_ns: int
    counts: dict[str, int]
    recorded: dict[str, str]
    damage: list[str] = field(default_factory=list)
    cycles: list[Any] = field(default_factory=list)
    events: list[tuple[str, str, str, int]] = field(default_factory=list)
    joints: dict[str, JointRows] = field(default_factory=dict)
    activity: list[tuple[int, int, int, int, float]] = field(default_factory=list)
    transitions: list[tuple[int, int]] = field(default_factory=list)
    steps: int = 0
    calibrations: list[tuple[str, Any, int]] = field(default_factory=list)
    cues: list[Any] = field(default_factory=list)
    given: list[Any] = field(default_factory=list)
    diagnostics: list[tuple[Any, int]] = field(default_factory=list)
    event_messages: list[Any] = field(default_factory=list)
    activity_messages: list[Any] = field(default_factory=list)

    def joint_rows(self, topic: str = JOINTS) -> JointRows:
        """The rows of ``topic`` (empty when it was not recorded or not read)."""
        return self.joints.get(topic) or JointRows()


def _summary_topics(recorded: dict[str, str]) -> set[str]:
    """What the figures alone need: the truth and what it is compared with, the strides, activity."""
    wanted = {CALIBRATION, TRUE_CALIBRATION, TRUE_EVENTS, ACTIVITY}
    if TRUE_JOINTS in recorded:
        wanted |= {JOINTS, TRUE_JOINTS}
    if TRUE_EVENTS in recorded:
        wanted.add(EVENTS)
    if CYCLES in recorded:
        wanted |= {CYCLES, SPACE}
    return wanted


ALL_TOPICS = frozenset({CYCLES, SPACE, EVENTS, JOINTS, ACTIVITY, CALIBRATION, CUES, GIVEN, DIAGNOSTICS,
                        TRUE_CALIBRATION, TRUE_EVENTS, TRUE_JOINTS})
"""What the report reads: the outputs and the truth."""


def read_recording(reader: BagReader, summary_only: bool = False) -> Recording:
    """Read ``reader``'s recording once (see module docstring); ``summary_only``: only the topics the
    figures need (:func:`~gait_biofeedback.report.session.session_report`). BagRecoveryWarnings are
    the caller's to route; what they said is in :attr:`Recording.damage`."""
    recorded = reader.topics()
    rec = Recording(reader.path, reader.start_time_ns, reader.duration_ns, reader.message_counts(), recorded)
    wanted = _summary_topics(recorded) if summary_only else ALL_TOPICS
    cycles: list[tuple[str, Any]] = []
    for topic, type_name, data, log_ns in reader.raw_messages([t for t in recorded if t in wanted]):
        if topic in (JOINTS, TRUE_JOINTS):  # most of them: read without an rclpy message
            fields = joint_state_of(data)
            if fields is None:
                msg = reader.decode(topic, type_name, data)
                fields = (*angles_of(msg), recovering_of(msg))
            stamp_ns, angles, recovering = fields
            rows = rec.joints.get(topic)
            if rows is None:
                rows = rec.joints[topic] = JointRows()
            rows.add(stamp_ns, angles, recovering)
            continue
        msg = reader.decode(topic, type_name, data)
        if topic in (CYCLES, SPACE):
            cycles.append((topic, msg))
        elif topic in (EVENTS, TRUE_EVENTS):
            side, kind, stamp_ns, _ = event_of(msg)
            rec.events.append((topic, side, kind, stamp_ns))
            if topic == EVENTS:
                rec.event_messages.append(msg)
        elif topic == ACTIVITY:
            rec.activity_messages.append(msg)
            rec.activity.append((stamp_to_ns(msg.header.stamp), msg.posture, msg.locomotion, msg.step_count,
                                 msg.trunk_inclination))
            rec.steps = max(rec.steps, msg.step_count)
            add_transition(rec.transitions, msg)
        elif topic in (CALIBRATION, TRUE_CALIBRATION):
            rec.calibrations.append((topic, msg, log_ns))
        elif topic == CUES:
            rec.cues.append(msg)
        elif topic == GIVEN:
            rec.given.append(msg)
        else:
            rec.diagnostics.append((msg, log_ns))
    rec.cycles = revised_cycles(cycles)
    rec.damage = list(dict.fromkeys(reader.warnings))
    return rec


def read_recording_file(path: str | Path) -> Recording:
    """:func:`read_recording` of the recording at ``path`` (every topic the report and the tables use);
    a damaged file is read as far as it can be, what was lost in :attr:`Recording.damage` (its
    BagRecoveryWarnings are not raised)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BagRecoveryWarning)
        with BagReader(path) as reader:
            return read_recording(reader)
