"""Importers of real IMU recordings (MAT/CSV files) into the project's in-memory form.

Every importer returns a :class:`Recording`: one :class:`~gait_biofeedback.core.segments.ImuSeries` per
segment in SI units (acc m/s², gyr rad/s, mag tesla or ``None``, t in s), plus whatever ground truth the
file carries in ``Recording.reference`` and human-readable ``warnings`` (NaN samples, suspicious units).

Supported sources:

- ``qmt_fullbody``: the qmt full-body walking example (``full_body_example_data.mat``, 16 IMUs, 100 Hz).
- ``gaitmap``: the gaitmap foot-IMU example (``imu_sample*.csv``, 204.8 Hz, gyr in deg/s) and its
  mocap stride events (``stride_events_sample.csv``).
- ``broad``: one trial of the BROAD orientation benchmark (``NN_*.mat``, 285.7 Hz, mag in µT).
- ``csv``: any CSV with a time column (or a known rate) and per-segment acc/gyr/mag columns, described by
  a mapping (dict or YAML file).

Use :func:`import_recording` with ``kind="auto"`` to pick the importer from the file name.
"""

from __future__ import annotations

import contextlib
import csv
import difflib
import gzip
import io
import math
import re
import shutil
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple
from warnings import catch_warnings, simplefilter

import numpy as np

from gait_biofeedback.core.safe_yaml import describe, load_yaml_file, shown
from gait_biofeedback.core.segments import GRAVITY, SEGMENTS, STANDARD_GRAVITY, ImuSeries
from gait_biofeedback.io.hapt import import_hapt, is_hapt_name
from gait_biofeedback.io.ipol import TRIAL_NAME, import_ipol_gait
from gait_biofeedback.io.pyshoe import import_pyshoe, is_pyshoe
from gait_biofeedback.io.recording import Recording

DEG_TO_RAD = math.pi / 180.0
MICROTESLA_TO_TESLA = 1e-6
GAUSS_TO_TESLA = 1e-4
GAITMAP_RATE_HZ = 204.8
QMT_FULLBODY_RATE_HZ = 100.0

# qmt struct name -> project segment (docs/conventions.md, Segments and frames).
QMT_SEGMENT_OF_STRUCT: dict[str, str] = {
    "hip": "pelvis",
    "upper_back": "chest",
    "upper_leg_left": "left_thigh",
    "upper_leg_right": "right_thigh",
    "lower_leg_left": "left_shank",
    "lower_leg_right": "right_shank",
    "foot_left": "left_foot",
    "foot_right": "right_foot",
}

# Conversion factors to SI per quantity; keys are the accepted unit spellings.
UNIT_FACTORS: dict[str, dict[str, float]] = {
    "acc": {"m/s2": 1.0, "m/s^2": 1.0, "m/s²": 1.0, "g": STANDARD_GRAVITY},
    "gyr": {"rad/s": 1.0, "deg/s": DEG_TO_RAD, "dps": DEG_TO_RAD},
    "mag": {"T": 1.0, "uT": MICROTESLA_TO_TESLA, "µT": MICROTESLA_TO_TESLA, "gauss": GAUSS_TO_TESLA},
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6, "ns": 1e-9},
}
DEFAULT_UNITS: dict[str, str] = {"acc": "m/s2", "gyr": "rad/s", "mag": "T", "time": "s"}
DEFAULT_TIME_COLUMNS: tuple[str, ...] = ("time", "t")
_VECTOR_QUANTITIES: tuple[str, ...] = ("acc", "gyr", "mag")


# --------------------------------------------------------------------------------------------------
# qmt full-body example
# --------------------------------------------------------------------------------------------------


def import_qmt_fullbody(path: str | Path, include_unmapped: bool = False) -> Recording:
    """Read qmt's ``full_body_example_data.mat`` (16 IMUs at 100 Hz, acc m/s², gyr rad/s, no mag).

    The sensors on the project's segments are renamed (``hip`` -> ``pelvis``, ``upper_back`` -> ``chest``,
    ``upper_leg_*`` -> ``*_thigh``, ``lower_leg_*`` -> ``*_shank``, ``foot_*`` -> ``*_foot``). The other
    sensors (``lower_back``, ``head``, arms, hands) are kept under their own names only when
    ``include_unmapped`` is true.

    The file's time starts at 40 s (an excerpt of a longer take); ``t`` is shifted to start at 0 and the
    shift is kept in ``reference["t_offset_s"]``. ``reference["vendor_quat"]``: segment -> (N, 4) vendor
    orientation (w, x, y, z, sensor -> the vendor's world frame, not necessarily ENU-aligned in heading).
    """
    path = Path(path)
    data = _load_mat(path, struct_as_record=False)
    if "t" not in data:
        raise ValueError(f"{path}: no 't' variable; is this qmt's full_body_example_data.mat? "
                         f"It has: {_mat_keys(data)}")
    t_file = np.asarray(data["t"], dtype=float).reshape(-1)
    missing = [name for name in QMT_SEGMENT_OF_STRUCT if name not in data]
    if missing:
        raise ValueError(f"{path}: sensor struct(s) {missing} missing; the file has {_mat_keys(data)}")

    struct_names = list(QMT_SEGMENT_OF_STRUCT)
    if include_unmapped:
        struct_names += [
            k for k in _mat_keys(data) if k not in QMT_SEGMENT_OF_STRUCT and _is_imu_struct(data[k])
        ]

    t = t_file - t_file[0]
    imu: dict[str, ImuSeries] = {}
    vendor_quat: dict[str, np.ndarray] = {}
    warnings: list[str] = []
    for struct_name in struct_names:
        sensor = data[struct_name]
        if not _is_imu_struct(sensor):
            raise ValueError(f"{path}: '{struct_name}' lacks acc/gyr fields (has {_struct_fields(sensor)})")
        segment = QMT_SEGMENT_OF_STRUCT.get(struct_name, struct_name)
        imu[segment] = ImuSeries(segment=segment, t=t, acc=sensor.acc, gyr=sensor.gyr)
        if hasattr(sensor, "quat"):
            vendor_quat[segment] = np.asarray(sensor.quat, dtype=float)
        warnings += _nan_warnings(imu[segment])

    reference: dict[str, Any] = {
        "vendor_quat": vendor_quat,
        "t_offset_s": float(t_file[0]),
        "struct_of_segment": {QMT_SEGMENT_OF_STRUCT.get(s, s): s for s in struct_names},
    }
    return Recording(imu=imu, source=f"qmt_fullbody:{path}", reference=reference, warnings=warnings)


def _is_imu_struct(value: Any) -> bool:
    return hasattr(value, "acc") and hasattr(value, "gyr")


def _struct_fields(value: Any) -> list[str]:
    return list(getattr(value, "_fieldnames", []) or [])


# --------------------------------------------------------------------------------------------------
# gaitmap example
# --------------------------------------------------------------------------------------------------

_GAITMAP_AXES: tuple[str, ...] = ("acc_x", "acc_y", "acc_z", "gyr_x", "gyr_y", "gyr_z")
_GAITMAP_EVENT_COLUMNS: tuple[str, ...] = ("start", "end", "ic", "tc", "min_vel", "pre_ic")


def import_gaitmap(path_csv: str | Path, rotated: bool | None = None, rate_hz: float = GAITMAP_RATE_HZ
                   ) -> Recording:
    """Read a gaitmap foot-IMU CSV (two header rows: sensor, axis; acc m/s², gyr deg/s) -> left/right_foot.

    ``path_csv`` is the CSV or the ``gaitmap_example`` folder. ``rotated`` selects the frame: ``True``
    gaitmap's foot frame (``imu_sample.csv``), ``False`` the raw sensor axes
    (``imu_sample_not_rotated.csv``), None (``import gaitmap FILE``) the file's own (a ``*not_rotated*``
    file: raw axes, else the foot frame). Given a folder, the file is chosen by ``rotated``; given
    ``imu_sample.csv`` with ``rotated=False``, its sibling ``imu_sample_not_rotated.csv`` is read; a
    ``*not_rotated*`` file with ``rotated=True`` is an error (the data would not be in the asked frame).

    The first column is either a sample index (``t = index / rate_hz``) or a time in s (the stair files).
    When the file is ``imu_sample.csv`` or ``imu_sample_not_rotated.csv`` and ``stride_events_sample.csv``
    lies next to it, ``reference["events"]`` holds its mocap events (see :func:`load_gaitmap_events`).
    ``reference["frame"]`` is ``"gaitmap_foot"`` or ``"sensor"``.
    """
    if rotated is None:
        rotated = "not_rotated" not in Path(path_csv).name
    path = _resolve_gaitmap_path(Path(path_csv), rotated)
    with path.open(newline="") as handle:
        reader = csv.reader(handle)
        try:
            sensor_row = next(reader)
            axis_row = next(reader)
        except StopIteration:
            raise ValueError(f"{path}: fewer than two header rows; a gaitmap IMU CSV has a sensor row "
                             "and an axis row") from None
    if set(_GAITMAP_AXES) <= {name.strip() for name in sensor_row}:
        side = "right" if "right" in path.name else "left"
        raise ValueError(
            f"{path}: one header row of axes (one sensor), not gaitmap's two (sensor, axis) of both feet: "
            f"import it with `gait-biofeedback import csv {path} --mapping MAP.yaml --units gyr=deg/s "
            f"--rate {rate_hz:g}`, MAP.yaml holding {side}_foot: {{acc: [acc_x, acc_y, acc_z], "
            "gyr: [gyr_x, gyr_y, gyr_z]}")
    data = np.genfromtxt(path, delimiter=",", skip_header=2, dtype=float)
    data = np.atleast_2d(data)
    if data.shape[1] != len(sensor_row):
        raise ValueError(f"{path}: {data.shape[1]} data columns but {len(sensor_row)} header columns")

    column_of: dict[tuple[str, str], int] = {}
    for index, (sensor, axis) in enumerate(zip(sensor_row, axis_row, strict=True)):
        if index > 0:
            column_of[(sensor.strip(), axis.strip())] = index
    sensors = sorted({sensor for sensor, _ in column_of})
    feet = {"left_foot": "left_sensor", "right_foot": "right_sensor"}
    for sensor in feet.values():
        absent = [axis for axis in _GAITMAP_AXES if (sensor, axis) not in column_of]
        if absent:
            raise ValueError(f"{path}: columns {sensor}/{absent} missing; the file has sensors {sensors} "
                             f"and axes {sorted({a for _, a in column_of})}. Expected gaitmap's two-row "
                             "header (sensor, axis)")

    t = _gaitmap_time(data[:, 0], rate_hz)
    imu: dict[str, ImuSeries] = {}
    warnings: list[str] = []
    for segment, sensor in feet.items():
        acc = data[:, [column_of[(sensor, a)] for a in ("acc_x", "acc_y", "acc_z")]]
        gyr_deg_s = data[:, [column_of[(sensor, a)] for a in ("gyr_x", "gyr_y", "gyr_z")]]
        imu[segment] = ImuSeries(segment=segment, t=t, acc=acc, gyr=gyr_deg_s * DEG_TO_RAD)
        warnings += _nan_warnings(imu[segment])

    reference: dict[str, Any] = {"frame": "sensor" if "not_rotated" in path.name else "gaitmap_foot"}
    events_path = path.with_name("stride_events_sample.csv")
    if path.name in ("imu_sample.csv", "imu_sample_not_rotated.csv") and events_path.is_file():
        reference["events"] = load_gaitmap_events(events_path, rate_hz=rate_hz)
    return Recording(imu=imu, source=f"gaitmap:{path}", reference=reference, warnings=warnings)


def _resolve_gaitmap_path(path: Path, rotated: bool) -> Path:
    wanted = "imu_sample.csv" if rotated else "imu_sample_not_rotated.csv"
    if path.is_dir():
        path = path / wanted
    elif not rotated and path.name == "imu_sample.csv":
        path = path.with_name(wanted)
    elif rotated and "not_rotated" in path.name:
        raise ValueError(f"{path} holds raw sensor axes, but rotated=True asks for gaitmap's foot frame; "
                         "pass rotated=False, or give imu_sample.csv")
    if not path.is_file():
        raise FileNotFoundError(f"{path} not found (rotated={rotated} reads {wanted} in a folder)")
    return path


def _gaitmap_time(first_column: np.ndarray, rate_hz: float) -> np.ndarray:
    """Sample index -> s, or time in s kept (shifted to start at 0)."""
    if np.any(~np.isfinite(first_column)):
        raise ValueError("gaitmap CSV: the first column (sample index or time) has empty/non-numeric rows")
    if np.all(first_column == np.round(first_column)) and first_column.size > 1 and np.all(
        np.diff(first_column) == 1
    ):
        return (first_column - first_column[0]) / rate_hz
    return first_column - first_column[0]


def load_gaitmap_events(
    path: str | Path, rate_hz: float = GAITMAP_RATE_HZ
) -> dict[str, dict[str, np.ndarray]]:
    """Read gaitmap's ``stride_events_sample.csv`` (sample indices at ``rate_hz``) -> events in s.

    Returns ``{"left": {"ic": (n,), "tc": (n,), "start": ..., "end": ..., "min_vel": ..., "pre_ic": ...},
    "right": {...}}``: per foot, arrays aligned by stride (element i belongs to stride i) in stride order,
    times in s on the IMU file's time base (index 0 = 0 s). ``ic``/``tc`` are the mocap initial/terminal
    contacts; ``start``/``end``/``min_vel`` the stride borders at the minimum foot velocity; ``pre_ic``
    the previous stride's IC.
    """
    path = Path(path)
    with path.open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    if not rows:
        raise ValueError(f"{path}: no strides (empty or header only)")
    columns = list(rows[0])
    absent = [c for c in ("foot", *_GAITMAP_EVENT_COLUMNS) if c not in columns]
    if absent:
        raise ValueError(f"{path}: column(s) {absent} missing; the file has {columns}")
    events: dict[str, dict[str, np.ndarray]] = {}
    for foot in ("left", "right"):
        foot_rows = sorted((r for r in rows if r["foot"].strip() == foot), key=lambda r: float(r["start"]))
        events[foot] = {
            name: np.array([_float_or_nan(r[name]) for r in foot_rows], dtype=float) / rate_hz
            for name in _GAITMAP_EVENT_COLUMNS
        }
    return events


def _float_or_nan(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return math.nan


# --------------------------------------------------------------------------------------------------
# BROAD
# --------------------------------------------------------------------------------------------------


def import_broad(path_mat: str | Path, segment: str = "board") -> Recording:
    """Read one BROAD trial (``NN_*.mat``: acc m/s², gyr rad/s, mag µT -> T, 285.7 Hz) as ``segment``.

    ``reference``: ``opt_quat`` (N, 4) optical orientation (w, x, y, z, IMU -> ENU, aligned to the IMU
    frame; NaN where the markers were lost), ``movement`` (N,) bool: the samples to score, ``opt_pos``
    (N, 3) m, ``rate_hz``, ``trial`` (file stem). ``t`` = sample index / sampling_rate.
    """
    path = Path(path_mat)
    data = _load_mat(path, struct_as_record=True)
    required = ("imu_acc", "imu_gyr", "imu_mag", "sampling_rate")
    absent = [k for k in required if k not in data]
    if absent:
        raise ValueError(f"{path}: variable(s) {absent} missing; is this a BROAD trial? It has "
                         f"{_mat_keys(data)}")
    rate_hz = float(data["sampling_rate"])
    acc = np.asarray(data["imu_acc"], dtype=float)
    t = np.arange(acc.shape[0]) / rate_hz
    series = ImuSeries(segment=segment, t=t, acc=acc, gyr=data["imu_gyr"],
                       mag=np.asarray(data["imu_mag"], dtype=float) * MICROTESLA_TO_TESLA)
    warnings = _nan_warnings(series)
    reference: dict[str, Any] = {"rate_hz": rate_hz, "trial": path.stem}
    if "opt_quat" in data:
        opt_quat = np.asarray(data["opt_quat"], dtype=float)
        reference["opt_quat"] = opt_quat
        lost = int(np.any(np.isnan(opt_quat), axis=1).sum())
        if lost:
            warnings.append(f"{segment}: opt_quat is NaN in {lost} of {len(opt_quat)} samples "
                            "(optical markers lost); skip them when scoring")
    if "movement" in data:
        reference["movement"] = np.asarray(data["movement"]).astype(bool).reshape(-1)
    if "opt_pos" in data:
        reference["opt_pos"] = np.asarray(data["opt_pos"], dtype=float)
    return Recording(imu={segment: series}, source=f"broad:{path}", reference=reference, warnings=warnings)


# --------------------------------------------------------------------------------------------------
# Generic CSV
# --------------------------------------------------------------------------------------------------


CSV_BLOCK_CHARS = 2 << 20
"""Characters of a CSV parsed at a time (about 50 000 rows of 40 characters): memory stays bounded for
any file size."""
CSV_MAX_LINE = 1 << 20
"""Longest line accepted in a CSV (a header of thousands of columns is far below it)."""
CSV_WINDOW_BYTES = 64 << 20
"""Memory for the first samples of a streamed import, on which its time base and units are judged."""
_SAMPLE_BYTES = 80  # t, acc, gyr, mag of one segment's sample, float64


def import_generic_csv(
    path: str | Path,
    mapping: Mapping[str, Any] | str | Path,
    units: Mapping[str, str] | None = None,
    rate_hz: float | None = None,
    trust_units: bool = False,
) -> Recording:
    """Read a CSV (one header row; ``,`` ``;`` or tab separated) with a time column and IMU columns.

    ``mapping``: segment -> ``{"acc": [col_x, col_y, col_z], "gyr": [...], "mag": [...]}`` (``mag``
    optional), plus two optional reserved keys: ``"time"``: the time column (default: a column named
    ``time`` or ``t``), and ``"units"``: the units, as in ``units``. Or the path of a YAML file holding the
    same mapping, for example::

        time: timestamp_ms          # optional; default "time" or "t"
        units: {acc: g, gyr: deg/s, mag: uT, time: ms}   # optional
        left_foot:
          acc: [lf_ax, lf_ay, lf_az]
          gyr: [lf_gx, lf_gy, lf_gz]
          mag: [lf_mx, lf_my, lf_mz]  # optional
        pelvis:
          acc: [p_ax, p_ay, p_az]
          gyr: [p_gx, p_gy, p_gz]

    ``units`` (overrides the mapping's): ``acc`` ``m/s2`` (default) | ``g`` (× 9.80665); ``gyr`` ``rad/s``
    (default) | ``deg/s``; ``mag`` ``T`` (default) | ``uT`` | ``gauss``; ``time`` ``s`` (default) | ``ms``
    | ``us``. ``rate_hz``: when the file has no time column, ``t = row / rate_hz``; given ``rate_hz``, a
    default-named time column is ignored, and naming a time column as well is an error.

    Times are kept as in the file (converted to s; absolute stamps stay absolute) and must increase
    strictly. Rows with NaN/empty IMU values are kept (downstream filters skip them) and counted in
    ``warnings``. Raises ValueError naming a missing column (and listing the file's columns) or an
    unknown unit (and listing the allowed ones), UnitsError when the data contradict the units
    (:func:`unit_contradictions`: resting acceleration, gyro range, Earth's field; with ``trust_units``
    a warning instead).

    The whole recording is held in memory; :func:`import_csv_to_bag` writes a bag of any size in
    bounded memory (the same messages).
    """
    layout = csv_layout(path, mapping, units, rate_hz)
    chunks = [chunk.imu for chunk in csv_chunks(layout)]
    if not chunks:
        raise ValueError(f"{layout.path}: no data rows after the header")
    imu = {segment: _joined([c[segment] for c in chunks]) for segment in layout.columns}
    del chunks
    _check_sample_rate(layout.path, next(iter(imu.values())).t, layout.time_unit)
    warnings: list[str] = []
    for segment, series in imu.items():
        warnings += _csv_warnings(layout, series, _nan_count(series, layout.has_gyro(segment)), len(series),
                                  trust_units)
    return Recording(imu=imu, source=f"csv:{layout.path}", reference={}, warnings=warnings)


@dataclass(frozen=True)
class CsvLayout:
    """Where the values of a mapped CSV are (:func:`csv_layout`): ``columns``: segment -> quantity ->
    the 3 column indices (None: absent), ``time``: (name, index) of the time column (None: ``rate_hz``
    gives the time), ``factors``: quantity -> factor to SI, ``units``: the unit names."""

    path: Path
    header: list[str]
    delimiter: str
    columns: dict[str, dict[str, list[int] | None]]
    time: tuple[str, int] | None
    rate_hz: float | None
    factors: dict[str, float]
    units: dict[str, str]

    @property
    def time_unit(self) -> str | None:
        """The time column's unit (None: the rate was given)."""
        return None if self.rate_hz is not None else self.units["time"]

    def has_gyro(self, segment: str) -> bool:
        return self.columns[segment]["gyr"] is not None


def csv_layout(
    path: str | Path,
    mapping: Mapping[str, Any] | str | Path,
    units: Mapping[str, str] | None = None,
    rate_hz: float | None = None,
) -> CsvLayout:
    """The mapping (see :func:`import_generic_csv`) checked against the units and the file's header
    row; ValueError naming what is wrong."""
    path = Path(path)
    mapping_dict = _load_mapping(mapping)
    segment_map = {k: v for k, v in mapping_dict.items() if k not in ("time", "units")}
    if not segment_map:
        raise ValueError(f"mapping for {path} names no segment; "
                         "give segment -> {'acc': [...], 'gyr': [...]}")
    for segment in segment_map:
        if segment not in SEGMENTS:
            close = difflib.get_close_matches(str(segment), SEGMENTS, n=1)
            raise ValueError(f"mapping for {path} names an unknown segment {shown(segment)}"
                             + (f" (did you mean '{close[0]}'?)" if close else "")
                             + f"; the segments are {list(SEGMENTS)}")
    merged_units = {**DEFAULT_UNITS, **dict(mapping_dict.get("units") or {}), **dict(units or {})}
    factors = _unit_factors(merged_units)
    header, delimiter = _read_header(path)
    column_index = {name: i for i, name in enumerate(header)}

    def index(name: Any, what: str) -> int:
        if not isinstance(name, str) or name not in column_index:
            raise ValueError(f"{path}: column {shown(name)} ({what}) not in the file; the file has "
                             f"{shown(header, 1000)}")
        return column_index[name]

    time_name = _time_column(path, mapping_dict.get("time"), header, rate_hz)
    time = None if time_name is None else (time_name, index(time_name, "time"))
    columns: dict[str, dict[str, list[int] | None]] = {}
    for segment, given in segment_map.items():
        if not isinstance(given, Mapping):
            raise ValueError(f"mapping['{segment}'] must be {{'acc': [3 columns], 'gyr': [3 columns]}}, "
                             f"got {shown(given)}")
        unknown = [k for k in given if k not in _VECTOR_QUANTITIES]
        if unknown:
            raise ValueError(f"mapping['{segment}'] has unknown key(s) {shown(unknown)}; "
                             f"allowed: {list(_VECTOR_QUANTITIES)}")
        columns[segment] = {}
        for quantity in _VECTOR_QUANTITIES:
            names = given.get(quantity)
            if names is None:
                if quantity == "acc":
                    raise ValueError(f"mapping['{segment}'] lacks 'acc' (3 column names)")
                columns[segment][quantity] = None
                continue
            if isinstance(names, str) or not isinstance(names, (list, tuple)) or len(names) != 3:
                raise ValueError(f"mapping['{segment}']['{quantity}'] must list 3 column names (x, y, z), "
                                 f"got {shown(names)}")
            columns[segment][quantity] = [index(n, f"{segment} {quantity}") for n in names]
    return CsvLayout(path, header, delimiter, columns, time, None if rate_hz is None else float(rate_hz),
                     factors, merged_units)


def _time_column(path: Path, time_column: Any, header: list[str], rate_hz: float | None) -> str | None:
    """The name of the time column, None when ``rate_hz`` gives the time."""
    if rate_hz is not None:
        if time_column is not None:
            raise ValueError(f"{path}: both rate_hz={rate_hz} and time column {shown(time_column)} given; "
                             "pass one of them")
        if not rate_hz > 0:
            raise ValueError(f"rate_hz must be > 0, got {rate_hz}")
        return None
    if time_column is None:
        found = [name for name in DEFAULT_TIME_COLUMNS if name in header]
        if not found:
            raise ValueError(f"{path}: no time column named {list(DEFAULT_TIME_COLUMNS)}; the file has "
                             f"{shown(header, 1000)}. Name it with mapping['time'], or give the rate "
                             "(--rate HZ; rate_hz in Python)")
        time_column = found[0]
    return time_column


class CsvChunk(NamedTuple):
    """Consecutive rows of a CSV: segment -> their samples, the index of the first (0 = the first data
    row), and the bytes of the file (compressed, for ``.gz``) read so far."""

    imu: dict[str, ImuSeries]
    first_row: int
    bytes_read: int


def csv_chunks(layout: CsvLayout, block_chars: int = CSV_BLOCK_CHARS) -> Iterator[CsvChunk]:
    """The data rows of ``layout.path`` in chunks of about ``block_chars`` characters, in SI units,
    their times checked (finite, strictly increasing across chunks); a chunk is the same as the rows
    of the whole file read at once. A ragged row, or a line still unended after :data:`CSV_MAX_LINE`
    characters, is refused with its line number."""
    path = layout.path
    with open(path, "rb") as raw:
        binary = gzip.GzipFile(fileobj=raw, mode="rb") if path.suffix == ".gz" else raw
        with io.TextIOWrapper(binary, encoding="utf-8-sig", errors="replace") as text:
            rows, last_t = 0, None
            for first_line, lines in _line_blocks(path, text, block_chars):
                data = _parse_rows(layout, lines, first_line)
                if not data.shape[0]:
                    continue
                t = _chunk_time(layout, data, rows, last_t)
                imu = {segment: _chunk_series(layout, segment, data, t) for segment in layout.columns}
                yield CsvChunk(imu, rows, raw.tell())
                rows, last_t = rows + len(t), t[-1]


def _line_blocks(path: Path, text: io.TextIOBase, block_chars: int) -> Iterator[tuple[int, list[str]]]:
    """(file line number of the first, lines) of the data lines (after the header), a block at a time."""
    carry, line_number, header_done = "", 1, False
    while True:
        block = text.read(block_chars)
        lines = (carry + block).split("\n")
        carry = lines.pop() if block else ""
        if len(carry) > CSV_MAX_LINE:
            raise ValueError(f"{path}: line {line_number + len(lines)} is longer than {CSV_MAX_LINE} "
                             "characters; not a CSV of IMU samples")
        if not header_done and lines:
            lines, header_done, line_number = lines[1:], True, line_number + 1
        if lines and not (len(lines) == 1 and not lines[0] and not block):
            yield line_number, lines
        line_number += len(lines)
        if not block:
            return


def _parse_rows(layout: CsvLayout, lines: list[str], first_line: int) -> np.ndarray:
    """The values of ``lines`` as ``np.genfromtxt(..., dtype=float, invalid_raise=True)`` reads them
    (an empty or non-numeric field: NaN), via the faster ``np.loadtxt`` when every field is a number."""
    with catch_warnings():
        simplefilter("ignore")  # "input contained no data": a block of blank lines
        try:
            data = np.loadtxt(lines, delimiter=layout.delimiter, dtype=float, ndmin=2)
        except ValueError:
            try:
                data = np.genfromtxt(lines, delimiter=layout.delimiter, dtype=float, invalid_raise=True,
                                     ndmin=2)
            except ValueError:
                raise ValueError(_ragged(layout, lines, first_line)) from None
    if not data.size:
        return np.zeros((0, len(layout.header)))
    if data.shape[1] != len(layout.header):
        raise ValueError(f"{layout.path}: {data.shape[1]} data columns but {len(layout.header)} header names")
    return data


def _ragged(layout: CsvLayout, lines: list[str], first_line: int) -> str:
    """The refusal of rows genfromtxt cannot read: the first whose column count is not the header's."""
    wanted = len(layout.header)
    for k, line in enumerate(lines):
        fields = line.split("#", 1)[0].strip(" \r\n")
        if fields and fields.count(layout.delimiter) + 1 != wanted:
            return (f"{layout.path}: line {first_line + k} has {fields.count(layout.delimiter) + 1} "
                    f"columns, the header {wanted}")
    return f"{layout.path}: lines {first_line}-{first_line + len(lines) - 1} cannot be read as numbers"


def _chunk_time(layout: CsvLayout, data: np.ndarray, first_row: int, last_t: float | None) -> np.ndarray:
    """The times of a chunk of rows (``first_row``: index of its first data row; ``last_t``: the time of
    the row before it), checked: finite and strictly increasing."""
    path = layout.path
    if layout.time is None:
        return np.arange(first_row, first_row + data.shape[0]) / float(layout.rate_hz)
    name, column = layout.time
    t = data[:, column] * layout.factors["time"]
    if np.any(~np.isfinite(t)):
        row = first_row + int(np.flatnonzero(~np.isfinite(t))[0])
        raise ValueError(f"{path}: time column '{name}' is empty/NaN at data row {row}; fix the file "
                         "or give the rate (--rate HZ; rate_hz in Python)")
    before = t[:-1] if last_t is None else np.concatenate([[last_t], t[:-1]])
    after = t[1:] if last_t is None else t
    bad = np.flatnonzero(after - before <= 0)
    if bad.size:
        k = int(bad[0])
        row = first_row + k + (1 if last_t is None else 0)
        raise ValueError(f"{path}: time column '{name}' does not increase at data row {row} "
                         f"({before[k]} s -> {after[k]} s); times must increase strictly")
    return t


def _chunk_series(layout: CsvLayout, segment: str, data: np.ndarray, t: np.ndarray) -> ImuSeries:
    vectors: dict[str, np.ndarray | None] = {}
    for quantity, columns in layout.columns[segment].items():
        vectors[quantity] = None if columns is None else data[:, columns] * layout.factors[quantity]
    gyr = vectors["gyr"]
    if gyr is None:  # an accelerometer alone: its rate is unknown (NaN), not zero
        gyr = np.full_like(vectors["acc"], np.nan)
    return ImuSeries(segment=segment, t=t, acc=vectors["acc"], gyr=gyr, mag=vectors["mag"])


def _joined(parts: list[ImuSeries]) -> ImuSeries:
    """One series of consecutive parts of a segment's samples."""
    if len(parts) == 1:
        return parts[0]
    first = parts[0]
    mag = None if first.mag is None else np.concatenate([p.mag for p in parts])
    return ImuSeries(first.segment, np.concatenate([p.t for p in parts]),
                     np.concatenate([p.acc for p in parts]), np.concatenate([p.gyr for p in parts]), mag,
                     first.frame_id)


def _csv_warnings(layout: CsvLayout, series: ImuSeries, nan_count: int | None, total: int,
                  trust_units: bool = False) -> list[str]:
    """A CSV segment's warnings, as :func:`import_generic_csv` gives them (``nan_count`` None: left
    out), the units judged on ``series`` (UnitsError: they contradict it, :func:`_units_checked`)."""
    segment = series.segment
    out = []
    if not layout.has_gyro(segment):
        out.append(f"{segment}: no gyro columns: its angular rate is written as unknown (NaN), so the "
                   "orientation filter gives it no orientation (nor joint angles); the activity monitor "
                   "uses its accelerometer alone")
    if nan_count is not None:
        out += _nan_text(segment, nan_count, total)
    return out + _units_checked(layout, series, trust_units)


def _load_mapping(mapping: Mapping[str, Any] | str | Path) -> dict[str, Any]:
    if isinstance(mapping, str | Path):
        import yaml

        mapping_path = Path(mapping)
        if not mapping_path.is_file():
            raise FileNotFoundError(f"mapping file {mapping_path} not found")
        try:
            loaded = load_yaml_file(mapping_path)
        except yaml.YAMLError as exc:
            raise ValueError(f"{mapping_path}: not a usable YAML mapping: {describe(exc)}") from None
        if not isinstance(loaded, Mapping):
            raise ValueError(f"{mapping_path}: expected a YAML mapping of segment -> {{acc, gyr, mag}} "
                             f"columns, got {type(loaded).__name__}")
        return dict(loaded)
    if not isinstance(mapping, Mapping):
        raise ValueError(f"mapping must be a dict or a YAML file path, got {type(mapping).__name__}")
    return dict(mapping)


def _unit_factors(units: Mapping[str, str]) -> dict[str, float]:
    factors: dict[str, float] = {}
    for quantity, unit in units.items():
        if quantity not in UNIT_FACTORS:
            raise ValueError(f"unknown quantity '{quantity}' in units; allowed: {list(UNIT_FACTORS)}")
        allowed = UNIT_FACTORS[quantity]
        if unit not in allowed:
            raise ValueError(f"unknown {quantity} unit '{unit}'; allowed: {list(allowed)}")
        factors[quantity] = allowed[unit]
    return factors


def _read_header(path: Path) -> tuple[list[str], str]:
    """(column names, delimiter) of a CSV, gzip-compressed (``.gz``) or not."""
    opener = gzip.open if path.suffix == ".gz" else open
    with opener(path, "rt", newline="", encoding="utf-8-sig") as handle:  # a BOM (Excel's) is not a name
        first_line = handle.readline(CSV_MAX_LINE + 1)
    if len(first_line) > CSV_MAX_LINE:
        raise ValueError(f"{path}: the header line is longer than {CSV_MAX_LINE} characters; expected one "
                         "row of column names")
    if not first_line.strip():
        raise ValueError(f"{path}: empty file or empty header line; expected one row of column names")
    delimiter = max((",", ";", "\t"), key=first_line.count)
    header = [name.strip() for name in next(csv.reader([first_line], delimiter=delimiter))]
    return header, delimiter


PLAUSIBLE_RATE_HZ = (5.0, 5000.0)
"""Sampling rates an IMU recording can have; outside them the time unit is wrong."""
GYRO_RANGE = 35.0  # rad/s (2000 deg/s): no body segment turns faster; beyond it the unit is deg/s
REST_GYRO = 0.3  # rad/s (17 deg/s): more than any gyro bias while the accelerometer says "at rest"
TURN_PER_SHAKE = 0.05
"""Below this 99th percentile |gyr| (rad/s) per m/s² of |acc| standard deviation a moving segment
does not turn (rad/s read as deg/s). Real recordings (hapt waist, ipol feet and back, gaitmap feet,
qmt full body) are at 0.8-2.5, the simulator's walk at 0.13 or more; read as deg/s they fall to 1/57."""


def _check_sample_rate(path: Path, t: np.ndarray, unit: str | None) -> None:
    """Refuse a time base whose median sample interval is no IMU's (ms declared as s: 0.1 Hz);
    ``unit`` None: the rate was given, not read from a column."""
    if len(t) < 2:
        return
    dt = float(np.median(np.diff(t)))
    lo, hi = PLAUSIBLE_RATE_HZ
    if lo <= 1.0 / dt <= hi:
        return
    found = f"a median sample interval of {dt:.3g} s ({1.0 / dt:.3g} Hz, {t[-1] - t[0]:.4g} s in all)"
    if unit is None:
        raise ValueError(f"{path}: the rate given gives {found}; an IMU samples at {lo:g}-{hi:g} Hz")
    raw = dt / UNIT_FACTORS["time"][unit]
    fits = [u for u in ("s", "ms", "us", "ns") if lo <= 1.0 / (raw * UNIT_FACTORS["time"][u]) <= hi]
    hint = (f": if the time column is in {fits[0]}, say so with --units time={fits[0]} "
            f"(Python: units={{'time': '{fits[0]}'}})" if fits else "")
    raise ValueError(f"{path}: the time column read in {unit} gives {found}, not an IMU's rate "
                     f"({lo:g}-{hi:g} Hz){hint}")


def _rest_blocks(series: ImuSeries) -> np.ndarray:
    """Indices of the samples in 1 s blocks where the accelerometer norm barely moves (at rest)."""
    if len(series) < 3:
        return np.zeros(0, dtype=int)
    n = max(round(series.rate_hz), 2)
    keep = []
    for start in range(0, len(series) - n + 1, n):
        norm = np.linalg.norm(series.acc[start:start + n], axis=1)
        if np.all(np.isfinite(norm)) and np.std(norm) < 0.02 * GRAVITY:
            keep.append(np.arange(start, start + n))
    return np.concatenate(keep) if keep else np.zeros(0, dtype=int)


class UnitsError(ValueError):
    """The data contradict the units they were declared in (:func:`unit_contradictions`)."""


TRUST_UNITS = "if these units are right after all, import with --trust-units (Python: trust_units=True)"


def unit_contradictions(series: ImuSeries, units: Mapping[str, str]) -> tuple[list[str], list[str]]:
    """(contradictions, doubts) of ``series`` with the units it was declared in. Contradictions: a
    median |acc| far from 1 g (below 0.3 g or above 3 g: gravity is in every accelerometer reading), gyro
    rates beyond any body segment's or moving while the accelerometer is at rest (deg/s read as rad/s),
    a median |mag| outside 1 µT-1 mT (Earth's field: 25-65 µT). Doubts: the gyro barely turns while the
    accelerometer moves (rad/s read as deg/s, or a segment that translates). Each names the ``--units``
    flag that fixes it. Silent when unsure."""
    contradictions: list[str] = []
    doubts: list[str] = []
    name = series.segment

    def unit_hint(quantity: str, unit: str) -> str:
        return f"say so with --units {quantity}={unit} (Python: units={{'{quantity}': '{unit}'}})"

    if not len(series):
        return contradictions, doubts
    acc_norm = np.linalg.norm(series.acc, axis=1)
    acc_median = np.nanmedian(acc_norm)
    if np.isfinite(acc_median) and acc_median < 0.3 * GRAVITY:
        contradictions.append(f"{name}: median |acc| is {acc_median:.3g} m/s² with acc unit '{units['acc']}' "
                              f"(gravity alone is 9.81); if the file is in g, {unit_hint('acc', 'g')}")
    elif np.isfinite(acc_median) and acc_median > 3.0 * GRAVITY:
        contradictions.append(f"{name}: median |acc| is {acc_median:.3g} m/s² with acc unit '{units['acc']}' "
                              f"(gravity alone is 9.81); if the file is in m/s², {unit_hint('acc', 'm/s2')}")
    gyr_norm = np.linalg.norm(series.gyr, axis=1)
    rest = _rest_blocks(series)
    at_rest = float(np.nanmedian(gyr_norm[rest])) if np.isfinite(gyr_norm[rest]).any() else math.nan
    fastest = float(np.nanpercentile(gyr_norm, 99)) if np.isfinite(gyr_norm).any() else math.nan
    if fastest > GYRO_RANGE or at_rest > REST_GYRO:
        what = (f"99th percentile |gyr| {fastest:.3g} rad/s" if fastest > GYRO_RANGE
                else f"median |gyr| {at_rest:.3g} rad/s while the accelerometer is at rest")
        contradictions.append(f"{name}: {what} with gyr unit '{units['gyr']}'; if the file is in deg/s, "
                              f"{unit_hint('gyr', 'deg/s')}")
    elif (units["gyr"] != "rad/s" and (shaking := np.nanstd(acc_norm)) > 0.05 * GRAVITY
          and fastest < TURN_PER_SHAKE * shaking):
        doubts.append(f"{name}: the gyro barely turns (99th percentile {fastest:.3g} rad/s) while the "
                      f"accelerometer moves, with gyr unit '{units['gyr']}'; if the file is in rad/s, "
                      f"{unit_hint('gyr', 'rad/s')}")
    if series.mag is not None:
        mag_norm = np.nanmedian(np.linalg.norm(series.mag, axis=1))
        if np.isfinite(mag_norm) and not 1e-6 <= mag_norm <= 1e-3:
            contradictions.append(f"{name}: median |mag| is {mag_norm:.3g} T with mag unit '{units['mag']}' "
                                  "(Earth: 25-65 µT); say which with --units mag=uT, mag=gauss or mag=T")
    return contradictions, doubts


def _units_checked(layout: CsvLayout, series: ImuSeries, trust_units: bool) -> list[str]:
    """The doubts about ``series``' units; UnitsError for a contradiction (unless ``trust_units``: then
    it is a warning too)."""
    contradictions, doubts = unit_contradictions(series, layout.units)
    if contradictions and not trust_units:
        raise UnitsError(f"{layout.path}: the data contradict the declared units: "
                         + "; ".join(contradictions) + f"; nothing written ({TRUST_UNITS})")
    return contradictions + doubts


# --------------------------------------------------------------------------------------------------
# Shared helpers and dispatch
# --------------------------------------------------------------------------------------------------


def _load_mat(path: Path, struct_as_record: bool) -> dict[str, Any]:
    from scipy.io import loadmat

    if not path.is_file():
        raise FileNotFoundError(f"{path} not found")
    return loadmat(path, squeeze_me=True, struct_as_record=struct_as_record)


def _mat_keys(data: Mapping[str, Any]) -> list[str]:
    return [k for k in data if not k.startswith("__")]


def _nan_warnings(series: ImuSeries, gyro: bool = True) -> list[str]:
    """Samples with NaN, counted (``gyro`` False: an accelerometer alone, its unknown rate not counted)."""
    return _nan_text(series.segment, _nan_count(series, gyro), len(series))


def _nan_count(series: ImuSeries, gyro: bool = True) -> int:
    parts = [series.acc] + ([series.gyr] if gyro else []) + ([series.mag] if series.mag is not None else [])
    return int(np.any(np.isnan(np.hstack(parts)), axis=1).sum())


def _nan_text(segment: str, count: int, total: int) -> list[str]:
    if not count:
        return []
    return [f"{segment}: {count} of {total} samples contain NaN (kept; downstream filters skip them)"]


IMPORTERS: dict[str, Callable[..., Recording]] = {
    "qmt_fullbody": import_qmt_fullbody,
    "gaitmap": import_gaitmap,
    "broad": import_broad,
    "ipol_gait": import_ipol_gait,
    "pyshoe": import_pyshoe,
    "hapt": import_hapt,
    "csv": import_generic_csv,
}

_BROAD_NAME = re.compile(r"^\d\d_.+\.mat$")


def detect_kind(path: str | Path, **options: Any) -> str:
    """Importer kind from the file name (and, for an unknown .mat name, the variables it holds).

    ``full_body*.mat`` -> ``qmt_fullbody``; ``NN_*.mat`` or a .mat with ``imu_gyr``/``opt_quat`` ->
    ``broad``; ``imu_sample*.csv`` or a ``gaitmap_example`` folder -> ``gaitmap``; ``S-T.json`` or
    ``S-T_lf.txt.gz`` -> ``ipol_gait``; a .mat with ``ts``/``imu``/``gt``/``zv_*`` -> ``pyshoe``;
    ``acc_expXX_userYY.txt``/``gyro_...`` or ``userUU_runK.csv.gz`` -> ``hapt``; any other ``.csv`` ->
    ``csv`` when a ``mapping`` option is given. Raises ValueError otherwise.
    """
    path = Path(path)
    name = path.name.lower()
    if path.is_dir() and (path / "imu_sample.csv").is_file():
        return "gaitmap"
    if TRIAL_NAME.match(path.name):
        return "ipol_gait"
    if is_hapt_name(path.name):
        return "hapt"
    if name.endswith(".mat"):
        if name.startswith("full_body"):
            return "qmt_fullbody"
        if _BROAD_NAME.match(name):
            return "broad"
        if path.is_file():
            from scipy.io import whosmat

            variables = {entry[0] for entry in whosmat(path)}
            if {"imu_gyr", "opt_quat"} <= variables:
                return "broad"
            if {"t", "hip", "foot_left"} <= variables:
                return "qmt_fullbody"
            if is_pyshoe(variables):
                return "pyshoe"
    if name.endswith((".csv", ".csv.gz")):
        if name.startswith("imu_sample"):
            return "gaitmap"
        if "mapping" in options:
            return "csv"
        raise ValueError(f"cannot tell the kind of {path}: a CSV of your own needs a column mapping (the "
                         f"command line: import csv {path} --mapping map.yaml; Python: mapping=...), see "
                         "docs/guide/sessions.md, Replaying your own recording")
    raise ValueError(f"cannot tell the kind of {path} from its name; name the kind, one of "
                     f"{list(IMPORTERS)} (known names: full_body*.mat, NN_*.mat (BROAD), imu_sample*.csv "
                     "(gaitmap), S-T.json (ipol_gait), acc_expXX_userYY.txt or userUU_runK.csv.gz (hapt); "
                     "pyshoe's and BROAD's .mat files by their variables)")


QMT_FILE = "full_body_example_data.mat"


def _file_of_kind(kind: str, path: Path) -> Path:
    """The file the importer ``kind`` reads at ``path``: qmt's .mat inside a folder given for it; a
    file whose name says it is of another built-in kind is refused naming that kind (a .mat read as a
    CSV failed on its bytes: "'utf-8' codec can't decode byte 0xec")."""
    if kind == "qmt_fullbody" and path.is_dir():
        if not (path / QMT_FILE).is_file():
            raise FileNotFoundError(f"{path}: a folder without {QMT_FILE}: give qmt's .mat file")
        return path / QMT_FILE
    if kind == "csv" or path.is_dir() or not path.exists():
        return path
    try:
        looks = detect_kind(path)
    except ValueError:  # no built-in kind of its own: the importer asked for judges it
        return path
    if looks not in (kind, "csv"):
        raise ValueError(f"{path} is a {looks} recording by its name and contents, not {kind}: import it "
                         f"with `gait-biofeedback import {looks} {path}` (or `import auto`)")
    return path


def import_recording(kind: str, path: str | Path, **options: Any) -> Recording:
    """Import ``path`` with the importer ``kind`` (a key of :data:`IMPORTERS`, or ``"auto"``).

    ``options`` go to the importer (e.g. ``include_unmapped`` for qmt_fullbody, ``rotated`` for gaitmap,
    ``segment`` for broad, ``mapping``/``units``/``rate_hz`` for csv).
    """
    ipol_base = kind == "ipol_gait" or TRIAL_NAME.match(Path(path).name)  # a trial's base name is no file
    if not Path(path).exists() and not ipol_base:
        raise FileNotFoundError(f"{path} not found: give the path of the recording to import")
    if kind == "auto":
        kind = detect_kind(path, **options)
    if kind not in IMPORTERS:
        raise ValueError(f"unknown recording kind '{kind}'; known: {[*IMPORTERS, 'auto']}")
    path = _file_of_kind(kind, Path(path))
    if kind == "csv" and "mapping" not in options:
        raise ValueError(f"{path}: a CSV of your own needs a column mapping (the command line: --mapping "
                         "map.yaml; Python: mapping=...) naming the time column and each segment's acc/gyr "
                         "columns; see docs/guide/sessions.md, Replaying your own recording")
    return IMPORTERS[kind](path, **options)


# --------------------------------------------------------------------------------------------------
# Straight to a bag, in bounded memory
# --------------------------------------------------------------------------------------------------

BYTES_PER_MESSAGE = 100
"""Upper estimate of one message's bytes in an imported bag (zstd chunks and indexes; measured: 63 for
random full-precision values, 46-60 for 4-5 digits), for the free disk an import needs."""
_WRITE_ROWS = 8192  # samples encoded at a time


def import_to_bag(kind: str, path: str | Path, output: str | Path,
                  warn: Callable[[str], None] | None = None, note: Callable[[str], None] | None = None,
                  **options: Any) -> tuple[Path, list[str]]:
    """Import ``path`` (as :func:`import_recording`) and write it to the bag folder ``output``; return
    (the folder, the segments). ``warn`` receives each warning, ``note`` each note. A CSV is streamed
    (:func:`import_csv_to_bag`: any size in bounded memory); the other kinds are read whole. An output
    the free disk cannot hold is refused before anything is written."""
    from gait_biofeedback.io.imu_bag import write_imu_bag

    warn = warn or (lambda text: None)
    note = note or (lambda text: None)
    if kind == "auto" and Path(path).exists():
        kind = detect_kind(path, **options)
    if kind == "csv" and "mapping" in options and Path(path).exists():
        return import_csv_to_bag(path, output, warn=warn, **options)
    recording = import_recording(kind, path, **options)
    for text in recording.warnings:
        warn(text)
    for text in recording.notes:
        note(text)
    check_disk_space(output, sum(len(s) * (1 if s.mag is None else 2) for s in recording.imu.values()))
    return write_imu_bag(output, recording.imu), list(recording.imu)


def check_disk_space(output: str | Path, messages: int, bytes_per_message: float = BYTES_PER_MESSAGE) -> None:
    """OSError unless the disk of ``output`` (or of its nearest existing parent) has room for
    ``messages`` IMU messages (:data:`BYTES_PER_MESSAGE` each, plus 1 MiB)."""
    folder = Path(output).absolute()
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    free = shutil.disk_usage(folder).free
    need = int(messages * bytes_per_message) + (1 << 20)
    if need > free:
        raise OSError(f"{output}: the bag would take about {_megabytes(need)} ({messages} messages) but "
                      f"the disk has {_megabytes(free)} free: free some space or write it elsewhere (-o)")


def _megabytes(n: int) -> str:
    return f"{n / 1e9:.1f} GB" if n >= 1e9 else f"{n / 1e6:.1f} MB"


def import_csv_to_bag(
    path: str | Path,
    output: str | Path,
    mapping: Mapping[str, Any] | str | Path,
    units: Mapping[str, str] | None = None,
    rate_hz: float | None = None,
    *,
    trust_units: bool = False,
    warn: Callable[[str], None] | None = None,
    block_chars: int = CSV_BLOCK_CHARS,
    window_bytes: int = CSV_WINDOW_BYTES,
) -> tuple[Path, list[str]]:
    """:func:`import_generic_csv` written straight to the bag folder ``output`` a chunk at a time, in
    memory bounded whatever the file's size; return (the folder, the segments). The bag is the one
    ``write_imu_bag(output, import_generic_csv(...).imu)`` writes, byte for byte.

    The time base and the units are judged on the first rows (``window_bytes`` of samples: the whole
    file up to about 800 000 rows of one sensor): data that contradict their units are refused
    (UnitsError, unless ``trust_units``), the warnings go to ``warn`` before anything is written, the
    NaN counts when the file has been read (before writing too, for a file within the window). A file
    the free disk cannot hold (estimated from the rows read so far and the file's size) is refused
    before writing; a refusal further on (a ragged row, a time going back) removes what was
    written."""
    from gait_biofeedback.io.bag_writer import BagWriter

    warn = warn or (lambda text: None)
    layout = csv_layout(path, mapping, units, rate_hz)
    segments = list(layout.columns)
    window_rows = max(1, window_bytes // (_SAMPLE_BYTES * len(segments)))
    with contextlib.closing(csv_chunks(layout, block_chars)) as chunks:
        held: list[CsvChunk] = []
        rows, complete = 0, True
        for chunk in chunks:
            held.append(chunk)
            rows += len(chunk.imu[segments[0]])
            if rows >= window_rows:
                complete = False
                break
        if not held:
            raise ValueError(f"{layout.path}: no data rows after the header")
        nans = {s: sum(_nan_count(c.imu[s], layout.has_gyro(s)) for c in held) for s in segments}
        window = {s: _joined([c.imu[s] for c in held]) for s in segments}
        _check_sample_rate(layout.path, window[segments[0]].t, layout.time_unit)
        for segment in segments:
            for text in _csv_warnings(layout, window[segment], nans[segment] if complete else None, rows,
                                      trust_units):
                warn(text)
        del window
        streams = sum(1 if layout.columns[s]["mag"] is None else 2 for s in segments)
        expected_rows = rows if complete else rows * layout.path.stat().st_size / max(held[-1].bytes_read, 1)
        check_disk_space(output, int(expected_rows * streams))

        out = Path(output)
        created = [p for p in (out, *out.parents) if not p.exists()]
        writer = BagWriter(out, flush_period_s=None)
        try:
            while held:
                _write_series(writer, held.pop(0).imu)
            for chunk in chunks:
                rows += len(chunk.imu[segments[0]])
                for segment in segments:
                    nans[segment] += _nan_count(chunk.imu[segment], layout.has_gyro(segment))
                _write_series(writer, chunk.imu)
                del chunk
            writer.close()
        except BaseException:
            writer.abandon()
            _remove_bag(out, writer.files, created)
            raise
    if not complete:
        for segment in segments:
            for text in _nan_text(segment, nans[segment], rows):
                warn(text)
    return writer.path, segments


def _write_series(writer: Any, imu: dict[str, ImuSeries]) -> None:
    """:func:`~gait_biofeedback.io.imu_bag.write_series` a few thousand samples at a time (the order of
    ``write_imu_bag``: by stamp; at one stamp, by segment, Imu before MagneticField)."""
    from gait_biofeedback.io.imu_bag import write_series

    n = len(next(iter(imu.values())))
    for start in range(0, n, _WRITE_ROWS):
        stop = min(start + _WRITE_ROWS, n)
        part = {segment: ImuSeries(segment, s.t[start:stop], s.acc[start:stop], s.gyr[start:stop],
                                   None if s.mag is None else s.mag[start:stop], s.frame_id)
                for segment, s in imu.items()}
        write_series(writer, part)


def _remove_bag(folder: Path, files: list[Path], created: list[Path]) -> None:
    """Remove what a failed import wrote: its files, then the folders it created."""
    for file in [*files, folder / "metadata.yaml", folder / ".metadata.yaml.tmp"]:
        with contextlib.suppress(OSError):
            file.unlink()
    for made in created:
        with contextlib.suppress(OSError):
            made.rmdir()
