"""Tuned default parameters shipped in ``config/orientation_filters.yaml``, and the one rule that
gives an algorithm its parameters (:func:`filter_params`).

Layout: ``algorithms: {name: {params: {...}, tuning: {...}}}`` (one set for every sensor) and, optional,
``locations: {location: {name: {params: {...}, tuning: {...}}}}``: parameters tuned for the sensors of
one body location (thesis §4.3: "the optimal gains for one IMU may result in poor performance for
another IMU"), which override the algorithm's own for the segments there (:func:`segment_location`).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from gait_biofeedback.core.safe_yaml import load_yaml_file
from gait_biofeedback.core.segments import SIDES
from gait_biofeedback.resources import config_path

TUNED_PATH = config_path("orientation_filters.yaml")


def segment_location(segment: str) -> str:
    """Body location of a segment, the side dropped (``left_shank`` → ``shank``)."""
    for side in SIDES:
        if segment.startswith(side + "_"):
            return segment[len(side) + 1:]
    return segment


def read_tuned(path: Path | str | None = None) -> dict[str, Any]:
    """The whole YAML document ({} if the file is absent)."""
    p = Path(path) if path is not None else TUNED_PATH
    if not p.is_file():
        return {}
    return load_yaml_file(p) or {}


def load_tuned(path: Path | str | None = None, location: str | None = None) -> dict[str, dict[str, Any]]:
    """Per-algorithm parameter dicts (``{algorithm: {param: value}}``); with ``location``, that location's
    tuned parameters override each algorithm's own."""
    data = read_tuned(path)
    out = {name: dict(entry.get("params", {})) for name, entry in (data.get("algorithms") or {}).items()}
    if location is not None:
        for name, entry in ((data.get("locations") or {}).get(location) or {}).items():
            out[name] = {**out.get(name, {}), **dict(entry.get("params", {}))}
    return out


def filter_params(algorithm: str, location: str | None = None, params: Mapping[str, Any] | None = None, *,
                  tuned: bool = True, path: Path | str | None = None) -> dict[str, Any]:
    """Every parameter ``algorithm`` runs with in the node, ``analyze`` and the batch functions.

    The filter class's ``DEFAULTS`` (the untuned starting point), over them the tuned ones of the
    YAML (:func:`load_tuned`; those of ``location``'s body location when it has its own, a segment name
    such as ``left_shank`` or a location such as ``shank``), over them ``params``. ``tuned=False``
    leaves the YAML out (what tuning starts from). Names are checked by the filter class.
    """
    from gait_biofeedback.core.orientation.filters import ALGORITHMS

    if algorithm not in ALGORITHMS:
        raise ValueError(f"unknown algorithm {algorithm!r}; expected one of {sorted(ALGORITHMS)}")
    own = load_tuned(path, None if location is None else segment_location(location)) if tuned else {}
    return {**ALGORITHMS[algorithm].DEFAULTS, **own.get(algorithm, {}), **(params or {})}
