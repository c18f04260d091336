"""``gait-biofeedback tune``: PSO per location, cross-validated by group, a thesis-style table, the YAML.

Per location (thesis §4.3) the recordings' groups are dealt round-robin into ``folds`` folds; for
each fold the PSO (:mod:`.pso`) minimises the mean cost (:mod:`.data`) over the other folds and the
optimum is scored on the held-out fold; the table gives, per location, the median (IQR) over the
held-out recordings of the roll, pitch and yaw RMSE (thesis §4.3, Figs 14-15), for the tuned and the
starting parameters. The parameters written are then optimised on all recordings of the location.
The swarm is seeded with the starting parameters (the shipped ones, else the defaults), as the
thesis' later rounds are seeded with earlier optima.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gait_biofeedback.core.orientation.filters import estimate_orientation
from gait_biofeedback.core.orientation.filters.config import TUNED_PATH, load_tuned, read_tuned
from gait_biofeedback.core.safe_yaml import dump_yaml
from gait_biofeedback.tuning.data import ReferenceRecording, rms_errors
from gait_biofeedback.tuning.pso import PsoSettings, particle_swarm
from gait_biofeedback.tuning.space import SearchSpace

STARTUP_S = 5.0


def run_filter(algorithm: str, params: dict[str, Any], rec: ReferenceRecording) -> np.ndarray:
    """The filter's estimate of a recording (start-up step on its leading quiet samples), ``params`` over
    the class's defaults (not the shipped tuned set: tuning starts from the parameters it is given)."""
    return estimate_orientation(
        rec.gyr, rec.acc, rec.mag, rec.rate_hz, algorithm, startup_s=STARTUP_S, tuned=False, **params
    )


def errors(algorithm: str, params: dict[str, Any], recs: Sequence[ReferenceRecording]) -> np.ndarray:
    """(len(recs), 3) RMS roll, pitch, yaw errors (rad); inf for a filter that fails."""
    out = np.empty((len(recs), 3))
    for i, rec in enumerate(recs):
        try:
            out[i] = rms_errors(run_filter(algorithm, params, rec), rec)
        except (ValueError, ArithmeticError):
            out[i] = np.inf
    return out


def cost(algorithm: str, params: dict[str, Any], recs: Sequence[ReferenceRecording]) -> float:
    """Mean over recordings of RMS(roll) + RMS(pitch) + RMS(yaw), degrees (thesis ch. 5)."""
    return float(np.degrees(errors(algorithm, params, recs).sum(1).mean()))


@dataclass
class LocationResult:
    """One location's tuned parameters, cost and held-out errors (rad, per recording)."""

    location: str
    params: dict[str, Any]
    train_cost: float
    start_cost: float
    held_out: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    held_out_start: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    evaluations: int = 0
    seconds: float = 0.0


def folds_of(recs: Sequence[ReferenceRecording], folds: int) -> list[list[int]]:
    """Recording indices per fold: the sorted groups dealt round-robin (a group never spans folds)."""
    groups = sorted({r.group for r in recs})
    if folds > len(groups):
        raise ValueError(
            f"{folds} folds need at least {folds} groups, the recordings have {len(groups)} "
            f"({', '.join(groups)}); pass --folds {max(1, len(groups))} or more recordings"
        )
    fold_of = {g: i % folds for i, g in enumerate(groups)}
    return [[i for i, r in enumerate(recs) if fold_of[r.group] == k] for k in range(folds)]


def tune_location(
    space: SearchSpace,
    recs: Sequence[ReferenceRecording],
    start: dict[str, Any],
    settings: PsoSettings,
    folds: int,
    log: Callable[[str], None] = lambda _: None,
) -> LocationResult:
    """Cross-validated PSO of one location's recordings (module docstring)."""
    t0 = time.monotonic()
    seed_point = space.point(start)
    start_params = space.params(seed_point, start)
    evaluations = 0

    def optimise(train: Sequence[ReferenceRecording], label: str) -> tuple[dict[str, Any], float, float]:
        """Tuned parameters, their cost and the starting parameters' cost (the swarm's seed)."""
        nonlocal evaluations
        result = particle_swarm(
            lambda u: cost(space.algorithm, space.params(u, start), train),
            len(space),
            settings,
            seeds=[seed_point],
            progress=lambda it, c: log(f"{label}: iteration {it}/{settings.iterations}, cost {c:.2f}°"),
        )
        evaluations += result.evaluations
        return space.params(result.best, start), result.cost, result.seed_costs[0]

    held, held_start = [], []
    if folds > 1:
        for k, test_idx in enumerate(folds_of(recs, folds)):
            train = [r for i, r in enumerate(recs) if i not in test_idx]
            test = [recs[i] for i in test_idx]
            params, _, _ = optimise(train, f"{recs[0].location} fold {k + 1}/{folds}")
            held.append(errors(space.algorithm, params, test))
            held_start.append(errors(space.algorithm, start_params, test))
    params, train_cost, start_cost = optimise(list(recs), f"{recs[0].location} all")
    return LocationResult(
        recs[0].location,
        params,
        train_cost,
        start_cost,
        np.concatenate(held) if held else np.zeros((0, 3)),
        np.concatenate(held_start) if held_start else np.zeros((0, 3)),
        evaluations,
        time.monotonic() - t0,
    )


def tune(
    algorithm: str,
    scheme: str,
    recordings: Sequence[ReferenceRecording],
    settings: PsoSettings | None = None,
    folds: int = 3,
    log: Callable[[str], None] = lambda _: None,
    tuned_path: Path | str | None = None,
) -> list[LocationResult]:
    """Tune ``algorithm`` with ``scheme`` for every location of ``recordings``."""
    space = SearchSpace(algorithm, scheme)
    settings = settings or PsoSettings()
    out = []
    for location in sorted({r.location for r in recordings}):
        recs = [r for r in recordings if r.location == location]
        start = load_tuned(tuned_path, location=location).get(algorithm, {})
        if start.get("scheme", scheme) != scheme:  # tuned for another scheme: start from the defaults
            start = {}
        out.append(tune_location(space, recs, start, settings, folds, log))
    return out


def _median_iqr(x: np.ndarray) -> str:
    if not len(x) or not np.isfinite(x).all():
        return "n/a" if not len(x) else "diverged"
    q1, med, q3 = np.percentile(np.degrees(x), [25, 50, 75])
    return f"{med:.1f} ({q3 - q1:.1f})"


def table(algorithm: str, scheme: str, results: Sequence[LocationResult]) -> str:
    """The held-out RMSE, median (IQR) in degrees, per location: tuned vs starting parameters."""
    lines = [
        f"{algorithm}, scheme {scheme}: RMSE median (IQR) over held-out recordings, degrees",
        f"{'location':<10}{'params':<10}{'n':>4}{'roll':>14}{'pitch':>14}{'yaw':>14}{'train cost':>12}",
    ]
    for r in results:
        for label, e, c in (("tuned", r.held_out, r.train_cost), ("start", r.held_out_start, r.start_cost)):
            lines.append(
                f"{r.location:<10}{label:<10}{len(e):>4}"
                + "".join(f"{_median_iqr(e[:, i]):>14}" for i in range(3))
                + f"{c:>11.2f}°"
            )
    return "\n".join(lines)


def _rounded(value: Any) -> Any:
    """4 significant digits (the optimum is not sharper than that), lists as YAML lists."""
    if isinstance(value, (list, tuple)):
        return [_rounded(v) for v in value]
    return float(f"{value:.4g}") if isinstance(value, float) else value


def write(
    algorithm: str,
    results: Sequence[LocationResult],
    command: str,
    path: Path | str | None = None,
    shared_location: str | None = None,
) -> Path:
    """Store the tuned parameters in the YAML: under ``locations`` (or, for ``shared_location``, as the
    algorithm's parameters for every sensor), with how they were obtained."""
    p = Path(path) if path is not None else TUNED_PATH
    data = read_tuned(p)
    for r in results:
        entry = {
            "params": {k: (list(v) if isinstance(v, tuple) else v) for k, v in r.params.items()},
            "tuning": {
                "optimiser": "PSO (thesis §4.2.3)",
                "train_cost_deg": round(r.train_cost, 3),
                "start_cost_deg": round(r.start_cost, 3),
                "evaluations": r.evaluations,
                "seconds": round(r.seconds),
                "command": command,
            },
        }
        if r.location == shared_location:
            data.setdefault("algorithms", {})[algorithm] = entry
        else:
            data.setdefault("locations", {}).setdefault(r.location, {})[algorithm] = entry
    header = ""
    if p.is_file():  # keep the file's leading comment lines
        lines = p.read_text().splitlines(keepends=True)
        header = "".join(
            line
            for line in lines[: next((i for i, x in enumerate(lines) if not x.startswith("#")), len(lines))]
        )
    tmp = p.with_suffix(".tmp")
    tmp.write_text(header + dump_yaml(data, sort_keys=False, allow_unicode=True))
    tmp.replace(p)
    return p
