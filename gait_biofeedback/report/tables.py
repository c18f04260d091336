"""A session's outputs as tables a researcher loads into pandas: Parquet files (pyarrow) of the strides,
the joint angles, the gait events and the activity states of a recording of the graph or of what
``analyze`` wrote (issue 46). ``analyze`` writes them into ``OUT/tables/``; ``gait-biofeedback tables
BAG`` writes them for a bag analysed before.

Every time is given twice: ``..._s``, s from the recording's first message (its log time, the zero of
``--calibrate-at`` and of the report), and ``..._ns``, the message stamp as integer ns since the epoch
(exact; join tables on these). Units are in the column names (``_s``, ``_ns``, ``_m``, ``_m_per_s``,
``_steps_per_s``, ``_rad``, ``_pct`` = percent of the stride time); values are SI as on the wire
(percentages are the wire's fractions × 100). An unknown value (NaN on the wire, a stride without a
single toe-off, an angle not published at that instant) is null. Nothing is recomputed: the columns are
the messages' fields, decoded by :mod:`gait_biofeedback.wire`, and the report's per-stride figures
(:mod:`gait_biofeedback.report.analysis`).

``strides.parquet``: one row per ``gait/cycles`` message (a stride of one foot, IC to the next IC of
that foot), in log order, with the smoothed spatial values of its ``gait/stride_space`` revision
(:func:`~gait_biofeedback.wire.gait.revised_cycles`, as the report takes them):

- ``side`` (``left``/``right``), ``stride_index`` (running count of that foot's strides);
- ``initial_contact_s``/``_ns`` (the IC that opens the stride), ``terminal_contact_s``/``_ns`` (its
  toe-off; null when the stride has no single one), ``next_initial_contact_s``/``_ns`` (the IC that
  closes it);
- ``stride_time_s``, ``stance_time_s`` (IC to TC), ``swing_time_s`` (TC to next IC), ``stance_pct``,
  ``swing_pct``, ``step_time_s`` (the other foot's last IC to this stride's closing IC),
  ``cadence_steps_per_s`` (2 / stride time; × 60 for steps/min), ``double_support_time_s``,
  ``double_support_pct`` (both feet on the ground; null when unknown),
  ``step_time_symmetry_index_pct`` ((left − right) / mean of the two, over a moving window);
- ``plausible`` and ``implausible_reason`` (the message's ``flag``: why not, empty when plausible);
- ``stride_length_m``, ``gait_speed_m_per_s``, ``max_foot_height_m`` (highest sensor position in the
  swing above the stance before), ``min_toe_clearance_m``, ``foot_angle_ic_rad`` (foot pitch at the
  strike, toes up positive), ``foot_angle_tc_rad`` (at push-off), ``turning_angle_rad`` (heading change
  of the foot, positive left), ``lateral_excursion_m``, ``spatial_flag`` (why they are unknown or
  doubtful, empty otherwise), ``spatial_provisional`` (true: no smoothed revision came, the values are
  the provisional ones);
- ``used`` (the report's summaries use the stride: plausible, inside a walking bout of the activity
  monitor, straight, steady) and ``left_out_reason`` (empty when used, else a key of
  :data:`~gait_biofeedback.report.analysis.LEFT_OUT`: ``implausible``, ``outside_walking``,
  ``turning``, ``walk_start_or_end``);
- per joint angle of the stride's side (named without the side, e.g. ``knee_flexion``), where its
  samples cover the stride (:func:`~gait_biofeedback.report.analysis.discrete_values`, as the report's
  joints.csv): ``<angle>_at_ic_rad``, ``<angle>_at_tc_rad``, ``<angle>_min_rad``, ``<angle>_max_rad``,
  ``<angle>_range_of_motion_rad`` and ``<angle>_peak_swing_rad`` (largest from toe-off to the next IC,
  e.g. the knee flexion peak in swing); null when not covered.

``joint_angles.parquet``: one row per stamp of the ``joint_states`` messages, in log order (messages of
one stamp that follow each other are one row): ``time_s``, ``stamp_ns``, ``recovering`` (the message
was marked: the orientation of ``recovering_segments``, comma-separated, was being re-acquired after a
sensor dropout; no biofeedback is computed from it), and one column per joint angle in the recording,
``<name>_rad`` (e.g. ``left_knee_flexion_rad``; the names of
``gait_biofeedback.core.joints.angles.JOINT_NAMES``), null where that row has no value for it.

``events.parquet``: one row per ``gait/events`` message, in log order: ``side``, ``kind`` (``ic``
initial contact, ``tc`` terminal contact/toe-off), ``event_index`` (running count of that side's
events of that kind), ``time_s``, ``stamp_ns`` (the sample at which it happened),
``detection_latency_s``, ``flag`` (why it is doubtful, empty otherwise).

``activity.parquet``: one row per ``activity/state`` message, in log order: ``time_s``, ``stamp_ns``,
``posture`` (``unknown``, ``standing``, ``sitting``, ``lying``), ``locomotion`` (``none``, ``level``,
``upstairs``, ``downstairs``), ``step_count`` (steps since the start), ``trunk_inclination_rad``,
``last_transition`` (e.g. ``sit_to_stand``; null before the first) and ``last_transition_s``/``_ns``,
``delay_s`` (how far the state lags the newest sample).

The recording is read once, by :func:`~gait_biofeedback.report.recording.read_recording` (``analyze``
reads it once for its printed summary and these tables). Memory: the joint angles are columns of
numbers (:class:`~gait_biofeedback.report.recording.JointRows`, about 100 bytes a stamp: 36 MB for an
hour at 100 Hz), never a Python object per message; the strides, events and activity states are a few
per second.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gait_biofeedback.core.joints.angles import JOINT_NAMES
from gait_biofeedback.core.segments import SIDES
from gait_biofeedback.io.bag_writer import TABLES_FOLDER
from gait_biofeedback.report.analysis import discrete_values, left_out, locomotion_bouts
from gait_biofeedback.report.extract import stride_row
from gait_biofeedback.report.recording import JointRows, Recording, read_recording_file
from gait_biofeedback.wire.activity import state_of
from gait_biofeedback.wire.gait import event_of

STRIDES, JOINT_ANGLES, EVENTS_TABLE, ACTIVITY_TABLE = (
    "strides.parquet", "joint_angles.parquet", "events.parquet", "activity.parquet")
TABLE_FILES = (STRIDES, JOINT_ANGLES, EVENTS_TABLE, ACTIVITY_TABLE)
"""The files :func:`write_tables` writes (module docstring)."""
START_KEY = b"gait_biofeedback.recording_start_ns"
"""Schema metadata of every table: the recording's first log time (ns), the zero of its ``_s`` columns."""

STRIDE_VALUES = (
    ("stride_time_s", "stride_time", 1.0),
    ("stance_time_s", "stance_time", 1.0),
    ("swing_time_s", "swing_time", 1.0),
    ("stance_pct", "stance_fraction", 100.0),
    ("swing_pct", "swing_fraction", 100.0),
    ("step_time_s", "step_time", 1.0),
    ("cadence_steps_per_s", "cadence", 1.0),
    ("double_support_time_s", "double_support_time", 1.0),
    ("double_support_pct", "double_support_fraction", 100.0),
    ("step_time_symmetry_index_pct", "step_time_symmetry_index", 100.0),
    ("stride_length_m", "stride_length", 1.0),
    ("gait_speed_m_per_s", "gait_speed", 1.0),
    ("max_foot_height_m", "max_foot_height", 1.0),
    ("min_toe_clearance_m", "min_toe_clearance", 1.0),
    ("foot_angle_ic_rad", "foot_angle_ic", 1.0),
    ("foot_angle_tc_rad", "foot_angle_tc", 1.0),
    ("turning_angle_rad", "turning_angle", 1.0),
    ("lateral_excursion_m", "lateral_excursion", 1.0),
)
"""(column, GaitCycle field, factor from the wire's unit) of the strides' numbers."""
JOINT_STATISTICS = ("at_ic", "at_tc", "min", "max", "range_of_motion", "peak_swing")
"""Per stride and joint angle (:func:`~gait_biofeedback.report.analysis.discrete_values`), rad."""

WINDOW_MARGIN_S = 0.05
"""Joint samples this far outside a stride are handed to the per-stride values (they take 0.02 s)."""


@dataclass
class TableFiles:
    """What :func:`write_tables` wrote: the folder and, per file name, its rows."""

    folder: Path
    rows: dict[str, int] = field(default_factory=dict)
    damage: list[str] = field(default_factory=list)  # the bag was damaged: what was lost, in words

    def summary(self) -> str:
        """``strides.parquet 40 rows, ...`` in the order written."""
        return ", ".join(f"{name} {n} rows" for name, n in self.rows.items())


def _without_side(name: str) -> str:
    side, _, rest = name.partition("_")
    return rest if side in SIDES and rest else name


def _seconds(ns: np.ndarray, start_ns: int) -> np.ndarray:
    return (np.asarray(ns, dtype=np.int64) - start_ns) / 1e9


def _numbers(values: Sequence[float] | np.ndarray) -> Any:
    """A float64 column, NaN as null."""
    import pyarrow as pa

    return pa.array(np.asarray(values, dtype=float), type=pa.float64(), from_pandas=True)


def _stamps(values: Sequence[int | None]) -> Any:
    import pyarrow as pa

    return pa.array(values, type=pa.int64())


def _text(values: Sequence[str | None]) -> Any:
    import pyarrow as pa

    return pa.array(values, type=pa.string())


def _flags(values: Sequence[bool] | np.ndarray) -> Any:
    import pyarrow as pa

    return pa.array(np.asarray(values, dtype=bool), type=pa.bool_())


def _counts(values: Sequence[int]) -> Any:
    import pyarrow as pa

    return pa.array(np.asarray(values, dtype=np.int64), type=pa.int64())


def strides_table(recording: Recording) -> dict[str, Any]:
    """The columns of ``strides.parquet`` (module docstring)."""
    start_ns = recording.start_ns
    rows, strides = [], []
    for msg in recording.cycles:
        row, stride = stride_row(msg, start_ns)
        rows.append(row)
        strides.append(stride)
    states = [((stamp_ns - start_ns) / 1e9, locomotion) for stamp_ns, _, locomotion, *_ in recording.activity]
    reasons = left_out(rows, strides, locomotion_bouts(states))
    stamps, angles, recovering = _joint_columns(recording.joint_rows())
    t = _seconds(stamps, start_ns)
    order = np.argsort(t, kind="stable")  # log order is stamp order, but a live recording may differ
    t_sorted = t[order]
    unsided = dict.fromkeys(_without_side(n) for n in angles)  # in JOINT_NAMES order
    per_stride = {f"{a}_{stat}_rad": np.full(len(rows), math.nan)
                  for a in unsided for stat in JOINT_STATISTICS}
    for k, row in enumerate(rows):  # each stride's own samples (and a margin), not the whole session's
        lo = np.searchsorted(t_sorted, row["start_s"] - WINDOW_MARGIN_S)
        hi = np.searchsorted(t_sorted, row["end_s"] + WINDOW_MARGIN_S, "right")
        near = order[lo:hi]
        window = {n: v[near] for n, v in angles.items()}
        for found in discrete_values(window, recovering[near], row, t[near]):
            for stat in JOINT_STATISTICS:
                per_stride[f"{found['angle']}_{stat}_rad"][k] = found[stat]
    columns: dict[str, Any] = {
        "side": _text([s.side for s in strides]),
        "stride_index": _counts([s.index for s in strides]),
        "initial_contact_s": _numbers([r["start_s"] for r in rows]),
        "initial_contact_ns": _stamps([s.start_ns for s in strides]),
        "terminal_contact_s": _numbers([r["terminal_contact_s"] for r in rows]),
        "terminal_contact_ns": _stamps([s.tc_ns for s in strides]),
        "next_initial_contact_s": _numbers([r["end_s"] for r in rows]),
        "next_initial_contact_ns": _stamps([s.end_ns for s in strides]),
    }
    for column, name, factor in STRIDE_VALUES[:10]:
        columns[column] = _numbers([factor * r[name] for r in rows])
    columns["plausible"] = _flags([r["plausible"] for r in rows])
    columns["implausible_reason"] = _text([r["flag"] for r in rows])
    for column, name, factor in STRIDE_VALUES[10:]:
        columns[column] = _numbers([factor * r[name] for r in rows])
    columns["spatial_flag"] = _text([r["spatial_flag"] for r in rows])
    columns["spatial_provisional"] = _flags([r["spatial_provisional"] for r in rows])
    columns["used"] = _flags([not why for why in reasons])
    columns["left_out_reason"] = _text(reasons)
    columns.update({c: _numbers(v) for c, v in per_stride.items()})
    return columns


def joint_angles_table(recording: Recording) -> dict[str, Any]:
    """The columns of ``joint_angles.parquet`` (module docstring)."""
    stamps, angles, recovering = _joint_columns(recording.joint_rows())
    columns: dict[str, Any] = {
        "time_s": _numbers(_seconds(stamps, recording.start_ns)),
        "stamp_ns": _counts(stamps),
        "recovering": _flags(recovering),
        "recovering_segments": _text(recording.joint_rows().recovering_segments),
    }
    columns.update({f"{name}_rad": _numbers(values) for name, values in angles.items()})
    return columns


def events_table(recording: Recording) -> dict[str, Any]:
    """The columns of ``events.parquet`` (module docstring)."""
    events = [event_of(msg) for msg in recording.event_messages]
    stamps = [stamp_ns for _, _, stamp_ns, _ in events]
    return {
        "side": _text([side for side, *_ in events]),
        "kind": _text([kind for _, kind, *_ in events]),
        "event_index": _counts([index for *_, index in events]),
        "time_s": _numbers(_seconds(np.array(stamps, dtype=np.int64), recording.start_ns)),
        "stamp_ns": _stamps(stamps),
        "detection_latency_s": _numbers([msg.detection_latency for msg in recording.event_messages]),
        "flag": _text([msg.flag for msg in recording.event_messages]),
    }


def activity_table(recording: Recording) -> dict[str, Any]:
    """The columns of ``activity.parquet`` (module docstring)."""
    states = [state_of(msg) for msg in recording.activity_messages]
    stamps = np.array([s["stamp_ns"] for s in states], dtype=np.int64)
    transition_ns = [s["last_transition_ns"] if s["last_transition"] else None for s in states]
    return {
        "time_s": _numbers(_seconds(stamps, recording.start_ns)),
        "stamp_ns": _counts(stamps),
        "posture": _text([s["posture"] for s in states]),
        "locomotion": _text([s["locomotion"] for s in states]),
        "step_count": _counts([s["step_count"] for s in states]),
        "trunk_inclination_rad": _numbers([s["trunk_inclination"] for s in states]),
        "last_transition": _text([s["last_transition"] for s in states]),
        "last_transition_s": _numbers([math.nan if ns is None else (ns - recording.start_ns) / 1e9
                                       for ns in transition_ns]),
        "last_transition_ns": _stamps(transition_ns),
        "delay_s": _numbers([msg.delay for msg in recording.activity_messages]),
    }


TABLES: dict[str, Callable[[Recording], dict[str, Any]]] = {
    STRIDES: strides_table, JOINT_ANGLES: joint_angles_table, EVENTS_TABLE: events_table,
    ACTIVITY_TABLE: activity_table}


ROW_GROUP_ROWS = 100_000
"""Rows per Parquet row group (the joint angles of an hour: four)."""


def write_tables(bag: str | Path, folder: str | Path | None = None,
                 recording: Recording | None = None) -> TableFiles:
    """Write :data:`TABLE_FILES` of ``bag`` into ``folder`` (default ``BAG/tables``, beside it for a bare
    .mcap file; created, the files replaced): the module docstring says what they hold. ``recording``:
    ``bag`` as :func:`~gait_biofeedback.report.recording.read_recording` read it (else read here, once)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    bag = Path(bag)
    if folder is None:
        folder = (bag if bag.is_dir() else bag.parent) / TABLES_FOLDER
    folder = Path(folder)
    if recording is None:
        recording = read_recording_file(bag)
    folder.mkdir(parents=True, exist_ok=True)
    out = TableFiles(folder, damage=recording.damage)
    metadata = {START_KEY: str(recording.start_ns).encode()}
    for name, build in TABLES.items():
        table = pa.table(build(recording)).replace_schema_metadata(metadata)
        staging = folder / f".{name}.writing"  # a file is whole or not there
        try:
            pq.write_table(table, staging, row_group_size=ROW_GROUP_ROWS)
            staging.replace(folder / name)
        finally:
            staging.unlink(missing_ok=True)
        out.rows[name] = table.num_rows
    return out


def _joint_columns(rows: JointRows) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]:
    """(stamps ns, name → angles rad (NaN: none) in ``JOINT_NAMES`` order then any other, recovering)."""
    columns = rows.columns()
    names = [n for n in JOINT_NAMES if n in columns] + [n for n in columns if n not in JOINT_NAMES]
    return (np.array(rows.stamps, dtype=np.int64), {n: columns[n] for n in names},
            np.array(rows.recovering, dtype=bool))
