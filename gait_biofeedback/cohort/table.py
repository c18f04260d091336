"""The cohort table: one row per session (``session``, ``recording``, ``status``, ``error``, the
session's duration and stride counts, each spatiotemporal parameter's mean per side with its SI unit
in the column name, symmetry indices, the Gait Profile Score in rad, processing time and the worker's
peak memory), as ``cohort.csv`` and ``cohort.parquet`` (pyarrow). Unknown values are empty in the
CSV and null in Parquet."""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

FIRST = ("session", "recording", "status", "error", "duration_s", "strides", "strides_used", "calibrated",
         "warnings")
LAST = ("analysis_s", "worker_peak_rss_mb")


def columns(rows: list[dict[str, Any]]) -> list[str]:
    """Every column of ``rows``: the identifying ones first, the parameters in first-seen order."""
    seen = [c for c in FIRST if any(c in r for r in rows)]
    for row in rows:
        seen += [c for c in row if c not in seen and c not in LAST]
    return seen + [c for c in LAST if any(c in r for r in rows)]


def _known(value: Any) -> Any:
    return None if isinstance(value, float) and not math.isfinite(value) else value


def write_cohort(rows: list[dict[str, Any]], out: Path) -> tuple[Path, Path]:
    """``out/cohort.csv`` and ``out/cohort.parquet`` of ``rows`` (sorted by session)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    rows = sorted(rows, key=lambda r: r["session"])
    names = columns(rows)
    csv_path, parquet_path = out / "cohort.csv", out / "cohort.parquet"
    with csv_path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=names)
        writer.writeheader()
        for row in rows:
            writer.writerow({c: "" if _known(row.get(c)) is None else row[c] for c in names})
    arrays = {}
    for c in names:
        values = [_known(r.get(c)) for r in rows]
        numeric = all(v is None or (isinstance(v, (int, float)) and not isinstance(v, bool)) for v in values)
        kind = pa.float64() if numeric and any(isinstance(v, float) for v in values) else None
        arrays[c] = pa.array(values, type=kind)
    pq.write_table(pa.table(arrays), parquet_path)
    return csv_path, parquet_path
