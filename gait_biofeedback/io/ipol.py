"""Importer of the IPOL gait data set (Voisard et al., IPOL 2023): foot and lower-back Xsens MTw IMUs.

One trial is ``<subject>-<trial>.json`` (metadata, reference steps) with ``<subject>-<trial>_lf.txt.gz``,
``_rf`` and ``_lb`` (left foot, right foot, lower back): gzip text, a line "Acquisition frequency:
100 Hz", a tab-separated header ``PacketCounter Acc_X Acc_Y Acc_Z Gyr_X Gyr_Y Gyr_Z Mag_X Mag_Y Mag_Z``,
then one row per sample (acc m/s², gyr rad/s). The magnetometer is in the vendor's normalised units,
not tesla, so it is not imported (the recording is 6D). The lower back becomes ``pelvis``.

The wireless sensors lose packets (up to 18 % of a trial in the development subjects, holes of up to
0.1 s): the sample times come from the packet counter (unwrapped), not from the row number; the
reference events are on that time base (with row numbers as time, one trial's strides came out 16 %
short of the reference's). The holes stay holes (the graph bridges short ones, ``max_gap_s``); the import
says how many samples are missing.
"""

from __future__ import annotations

import gzip
import json
import re
from pathlib import Path

import numpy as np

from gait_biofeedback.core.segments import ImuSeries
from gait_biofeedback.io.recording import Recording

IPOL_FILES = {"lf": "left_foot", "rf": "right_foot", "lb": "pelvis"}
TRIAL_NAME = re.compile(r"^(\d+-\d+)(\.json|_(lf|rf|lb)\.txt\.gz)$")
_COLUMNS = ("PacketCounter", "Acc_X", "Acc_Y", "Acc_Z", "Gyr_X", "Gyr_Y", "Gyr_Z")
COUNTER_WRAP = 65536  # the MTw packet counter is 16 bit


def trial_base(path: str | Path) -> Path:
    """``.../<subject>-<trial>`` of any file of a trial (or of the base itself); ValueError otherwise."""
    path = Path(path)
    match = TRIAL_NAME.match(path.name)
    if match is None and re.fullmatch(r"\d+-\d+", path.name):
        return path
    if match is None:
        raise ValueError(f"{path}: not an IPOL gait trial file (<subject>-<trial>.json or "
                         "<subject>-<trial>_lf.txt.gz)")
    return path.with_name(match.group(1))


def _read_sensor(path: Path) -> tuple[float, np.ndarray]:
    with gzip.open(path, "rt") as f:
        first = f.readline()
        rate = re.search(r"([\d.]+)\s*Hz", first)
        if rate is None:
            raise ValueError(f"{path}: first line {first.strip()!r} does not give the acquisition frequency")
        header = f.readline().rstrip("\n").split("\t")
        missing = [c for c in _COLUMNS if c not in header]
        if missing:
            raise ValueError(f"{path}: columns {missing} missing from the header {header}")
        rows = np.loadtxt(f, delimiter="\t", ndmin=2)
    return float(rate.group(1)), rows[:, [header.index(c) for c in _COLUMNS]]


def import_ipol_gait(path: str | Path) -> Recording:
    """Read one IPOL gait trial (any of its files, or ``<subject>-<trial>``) → a
    :class:`~gait_biofeedback.io.importers.Recording` with ``left_foot``, ``right_foot`` and ``pelvis``.

    ``reference``: ``events`` {"left"/"right": {"ic": s, "tc": s}} from the JSON's per-footstep
    [toe-off, heel-strike] sample indices; ``trial`` (start, end) s and ``u_turn`` (start, end) s
    (``TrialBoundaries``, ``UTurnBoundaries``); ``subject``: the other metadata (age, sex, height).
    Times from 0 at each sensor's first packet (the counters of a trial's sensors start together)."""
    base = trial_base(path)
    imu, rates = {}, set()
    warnings: list[str] = []
    for suffix, segment in IPOL_FILES.items():
        file = base.with_name(f"{base.name}_{suffix}.txt.gz")
        if not file.is_file():
            raise FileNotFoundError(f"{file} not found (an IPOL trial has _lf, _rf and _lb files)")
        rate, data = _read_sensor(file)
        rates.add(rate)
        counter = np.concatenate([[0], np.cumsum(np.mod(np.diff(data[:, 0]), COUNTER_WRAP))])
        imu[segment] = ImuSeries(segment, counter / rate, data[:, 1:4], data[:, 4:7])
        lost = int(counter[-1] + 1 - len(counter))
        if lost:
            worst = float(np.max(np.diff(counter)) - 1) / rate
            share = 100 * lost / (counter[-1] + 1)
            warnings.append(f"{segment}: {lost} samples lost by the radio ({share:.1f} %, the longest hole "
                            f"{worst:.2f} s)")
    if len(rates) != 1:
        raise ValueError(f"{base}: the sensors have different rates {sorted(rates)}")
    rate = rates.pop()
    meta = json.loads(base.with_name(f"{base.name}.json").read_text())
    events = {}
    for side, key in (("left", "LeftFootEvents"), ("right", "RightFootEvents")):
        steps = np.asarray(meta.get(key, []), dtype=float).reshape(-1, 2)
        events[side] = {"tc": steps[:, 0] / rate, "ic": steps[:, 1] / rate}
    u_turn = meta.get("UTurnBoundaries", [np.nan, np.nan])
    reference = {"events": events,
                 "trial": tuple(np.asarray(meta["TrialBoundaries"], dtype=float) / rate),
                 "u_turn": tuple(np.asarray(u_turn, dtype=float) / rate),
                 "subject": {k: v for k, v in meta.items() if not k.endswith(("Events", "Boundaries"))}}
    return Recording(imu, f"ipol_gait {base}", reference, warnings,
                     ["magnetometer not imported (vendor-normalised units, not tesla): the recording is 6D"])
