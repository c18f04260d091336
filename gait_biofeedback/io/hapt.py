"""Importer of the UCI HAPT data set (Reyes-Ortiz et al. 2016): a phone on the waist, activity labels.

A Samsung Galaxy S II on the waist, accelerometer (g, gravity included) and gyroscope (rad/s) at
50 Hz, the phone's x axis roughly along the body's vertical. Two layouts are read:

- the data set's own ``RawData`` folder: ``acc_expXX_userYY.txt`` and ``gyro_expXX_userYY.txt``
  (three space-separated columns per sample) and ``labels.txt`` (``experiment user activity start
  end`` per row). READING: ``start``/``end`` are taken as 1-based, inclusive sample numbers (the
  data set was labelled in MATLAB); read as 0-based they would move every label by one sample, 20 ms;
- one experiment per CSV (``userUU_runK.csv.gz``): columns ``acc-x, acc-y, acc-z, gyro-x, gyro-y,
  gyro-z, sequence, label``, the labels per sample (-1 unlabelled).

The phone becomes ``pelvis`` (a waist / lower-back placement; the activity monitor takes it as the
trunk sensor when the kit has no chest sensor).
"""

from __future__ import annotations

import gzip
import re
from pathlib import Path

import numpy as np

from gait_biofeedback.core.segments import STANDARD_GRAVITY, ImuSeries
from gait_biofeedback.io.recording import Recording

HAPT_RATE_HZ = 50.0
HAPT_SEGMENT = "pelvis"
ACTIVITY_NAMES = {1: "walking", 2: "upstairs", 3: "downstairs", 4: "sitting", 5: "standing", 6: "lying",
                  7: "stand_to_sit", 8: "sit_to_stand", 9: "sit_to_lie", 10: "lie_to_sit",
                  11: "stand_to_lie", 12: "lie_to_stand"}
"""The data set's activity codes (``activity_labels.txt``); -1 is unlabelled."""
UNLABELLED = -1
RAW_NAME = re.compile(r"^(acc|gyro)_exp(\d+)_user(\d+)\.txt$")
CSV_NAME = re.compile(r"^user(\d+)_run(\d+)\.csv(\.gz)?$")
CSV_COLUMNS = ("acc-x", "acc-y", "acc-z", "gyro-x", "gyro-y", "gyro-z", "label")
MAX_ROWS = 2_000_000  # 11 h at 50 Hz: longer than any experiment; bounds what one file may hold


def is_hapt_name(name: str) -> bool:
    """Whether a file name is one of a HAPT experiment (either layout)."""
    return bool(RAW_NAME.match(name) or CSV_NAME.match(name))


def import_hapt(path: str | Path) -> Recording:
    """Read one HAPT experiment (either layout, module docstring) → a :class:`Recording` with ``pelvis``.

    ``reference``: ``labels`` (N,) int activity codes per sample (-1 unlabelled), ``activity_names``
    code → name, ``activities`` [(name, start s, end s)] for each labelled run."""
    path = Path(path)
    if RAW_NAME.match(path.name):
        acc_g, gyr, labels = _read_raw(path)
    elif CSV_NAME.match(path.name):
        acc_g, gyr, labels = _read_csv(path)
    else:
        raise ValueError(f"{path}: not a HAPT file (acc_expXX_userYY.txt / gyro_expXX_userYY.txt of its "
                         "RawData folder, or userUU_runK.csv.gz)")
    t = np.arange(len(acc_g)) / HAPT_RATE_HZ
    series = ImuSeries(HAPT_SEGMENT, t, acc_g * STANDARD_GRAVITY, gyr)
    reference = {"labels": labels, "activity_names": dict(ACTIVITY_NAMES),
                 "activities": labelled_runs(labels, HAPT_RATE_HZ)}
    warnings = [] if (labels != UNLABELLED).any() else [f"{path.name}: no activity label (labels.txt lacks "
                                                         "this experiment)"]
    return Recording({HAPT_SEGMENT: series}, f"hapt {path}", reference, warnings)


def labelled_runs(labels: np.ndarray, rate_hz: float) -> list[tuple[str, float, float]]:
    """The runs of one activity code as (name, start s, end s), the end one sample after the last."""
    if not len(labels):
        return []
    edges = np.flatnonzero(np.diff(labels)) + 1
    starts = np.concatenate([[0], edges])
    ends = np.concatenate([edges, [len(labels)]])
    return [(ACTIVITY_NAMES.get(int(labels[s]), str(int(labels[s]))), float(s / rate_hz), float(e / rate_hz))
            for s, e in zip(starts, ends, strict=True) if labels[s] != UNLABELLED]


def _read_raw(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    _, experiment, user = RAW_NAME.match(path.name).groups()
    files = {kind: path.with_name(f"{kind}_exp{experiment}_user{user}.txt") for kind in ("acc", "gyro")}
    data = {}
    for kind, file in files.items():
        if not file.is_file():
            raise FileNotFoundError(f"{file} not found: a HAPT experiment has an acc_ and a gyro_ file")
        data[kind] = _columns(file, 3)
    if len(data["acc"]) != len(data["gyro"]):
        raise ValueError(f"{files['acc'].name} has {len(data['acc'])} samples but {files['gyro'].name} "
                         f"{len(data['gyro'])}: the two files of one experiment must have the same length")
    labels = np.full(len(data["acc"]), UNLABELLED, dtype=int)
    label_file = path.with_name("labels.txt")
    if label_file.is_file():
        rows = _columns(label_file, 5).astype(int)
        for _, _, activity, start, end in rows[(rows[:, 0] == int(experiment)) & (rows[:, 1] == int(user))]:
            if not 1 <= start <= end <= len(labels):
                raise ValueError(f"{label_file}: experiment {experiment} user {user}: label {activity} "
                                 f"spans samples {start}-{end}, outside the {len(labels)} samples of the "
                                 "experiment")
            labels[start - 1:end] = activity
    return data["acc"], data["gyro"], labels


def _columns(path: Path, count: int) -> np.ndarray:
    """A whitespace-separated numeric file of ``count`` columns (at most :data:`MAX_ROWS` rows)."""
    try:
        rows = np.loadtxt(path, ndmin=2, max_rows=MAX_ROWS + 1)
    except ValueError as exc:
        raise ValueError(f"{path}: not {count} numeric columns per row ({exc})") from None
    if rows.shape[1] != count:
        raise ValueError(f"{path}: expected {count} columns per row, got {rows.shape[1]}")
    if len(rows) > MAX_ROWS:
        raise ValueError(f"{path}: more than {MAX_ROWS} rows, longer than any HAPT experiment")
    return rows


def _read_csv(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    opener = gzip.open if path.suffix == ".gz" else open
    with opener(path, "rt") as f:
        header = f.readline().strip().split(",")
        missing = [c for c in CSV_COLUMNS if c not in header]
        if missing:
            raise ValueError(f"{path}: columns {missing} missing from the header {header} (a file named "
                             "userUU_runK.csv is read as a UCI HAPT experiment; a CSV of your own: "
                             f"`gait-biofeedback import csv {path} --mapping map.yaml`)")
        try:
            rows = np.loadtxt(f, delimiter=",", ndmin=2, max_rows=MAX_ROWS + 1)
        except ValueError as exc:
            raise ValueError(f"{path}: a row is not {len(header)} numbers ({exc})") from None
    if len(rows) > MAX_ROWS:
        raise ValueError(f"{path}: more than {MAX_ROWS} rows, longer than any HAPT experiment")
    pick = [header.index(c) for c in CSV_COLUMNS]
    return rows[:, pick[:3]], rows[:, pick[3:6]], rows[:, pick[6]].astype(int)
