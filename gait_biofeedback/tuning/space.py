"""Decision variables of each filter and scheme (thesis Table 5, orientation.md §4.5) and their ranges.

A variable is a filter parameter (or one entry of a fuzzy-set list) with a search range, searched in
log space when it spans decades (gains, noise levels, thresholds) and linearly otherwise (membership
function parameters, decay factors). :class:`SearchSpace` maps the PSO's unit box to parameter dicts and
back. The thesis gives no ranges; these cover the defaults by a wide margin in the project's units
(deviations as fractions of the reference norm, σ_A in g, σ_M in field units, rates in rad/s).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gait_biofeedback.core.orientation.filters import ALGORITHMS


@dataclass(frozen=True)
class Var:
    """One decision variable: ``name`` (``index``: entry of a list parameter), range, log spacing."""

    name: str
    low: float
    high: float
    log: bool = True
    index: int | None = None

    @property
    def label(self) -> str:
        return self.name if self.index is None else f"{self.name}[{self.index}]"


def _scalars(ranges: Mapping[str, tuple[float, float]], names: Sequence[str]) -> list[Var]:
    return [Var(n, *ranges[n.rstrip("123")] if n.rstrip("123") in ranges else ranges[n]) for n in names]


def _sets(name: str, low: float, high: float, count: int = 8) -> list[Var]:
    return [Var(name, low, high, log=False, index=i) for i in range(count)]


_CF_RANGES = {
    "beta": (1e-4, 1.0),
    "kp": (1e-3, 10.0),
    "s_acc": (1e-3, 1.0),
    "s_mag": (1e-3, 1.0),
    "zeta": (1e-8, 0.1),
    "ki": (1e-6, 1.0),
}
_KF_RANGES = {
    "p0": (1e-8, 0.1),
    "sigma_g": (1e-4, 1.0),
    "sigma_a": (1e-3, 10.0),
    "sigma_m": (1e-3, 10.0),
    "s_g": (0.01, 10.0),
    "s_a": (1e-3, 1.0),
    "s_m": (1e-3, 1.0),
}


def _cf(gain: str, drift: str) -> dict[str, list[Var]]:
    r = _CF_RANGES
    return {
        "fixed": _scalars(r, [f"{gain}1", drift]),
        "two_level": _scalars(r, [f"{gain}1", f"{gain}2", "s_acc1", "s_mag1", drift]),
        "three_level": _scalars(
            r, [f"{gain}1", f"{gain}2", "s_acc1", "s_mag1", f"{gain}3", "s_acc2", "s_mag2", drift]
        ),
        "fuzzy": [
            *_sets("fuzzy_acc", 0.0, 0.5),
            *_sets("fuzzy_mag", 0.0, 0.5),
            *_sets(f"fuzzy_{gain}", 0.0, r[gain][1] / 2),
        ],
    }


def _kf_levels(levels: int, s: str) -> list[str]:
    names = [f"sigma_{s}1"]
    for i in range(2, levels + 1):
        names += [f"sigma_{s}{i}", f"s_{s}{i - 1}"]
    return names


_GUO = {
    "fixed": _scalars(_KF_RANGES, ["p0", "sigma_g1", "sigma_a1", "sigma_m1"]),
    "two_level": _scalars(_KF_RANGES, ["p0", *_kf_levels(2, "g"), *_kf_levels(2, "a"), *_kf_levels(2, "m")]),
    "three_level": _scalars(
        _KF_RANGES, ["p0", *_kf_levels(3, "g"), *_kf_levels(3, "a"), *_kf_levels(3, "m")]
    ),
    "fuzzy": [
        *_sets("fuzzy_gyr", 0.0, 10.0),
        *_sets("fuzzy_acc", 0.0, 0.5),
        *_sets("fuzzy_mag", 0.0, 0.5),
        *_sets("fuzzy_sigma_g", 1e-4, 0.5),
        *_sets("fuzzy_sigma_a", 1e-3, 5.0),
        *_sets("fuzzy_sigma_m", 1e-3, 5.0),
    ],
    "iae": [
        *_sets("iae_input", -1.0, 1.0, 24),
        *_sets("iae_output", -0.05, 0.05, 24),
        *_scalars(_KF_RANGES, ["p0", "sigma_a1", "sigma_m1"]),
    ],
}
_ROETENBERG_MODEL = [
    Var("gyro_drift_noise", 1e-14, 1e-4),
    Var("lin_acc_noise", 1e-6, 1.0),
    Var("mag_disturbance_noise", 1e-8, 1.0),
    Var("mag_disturbance_decay", 0.0, 1.0, log=False),
    Var("expected_field", 0.5, 2.0, log=False),
]
_ROETENBERG = {
    "fixed": [*_scalars(_KF_RANGES, ["p0", "sigma_g1", "sigma_a1", "sigma_m1"]), *_ROETENBERG_MODEL],
    "two_level": [
        *_scalars(
            _KF_RANGES,
            [
                "p0",
                "sigma_g1",
                "sigma_g2",
                "s_g",
                "sigma_a1",
                "sigma_a2",
                "s_a",
                "sigma_m1",
                "sigma_m2",
                "s_m",
            ],
        ),
        *_ROETENBERG_MODEL,
    ],
}
SPACES: dict[str, dict[str, list[Var]]] = {
    "madgwick": _cf("beta", "zeta"),
    "mahony": _cf("kp", "ki"),
    "guo_fkf": _GUO,
    "roetenberg_ikf": _ROETENBERG,
}
"""Thesis Table 5: per filter and scheme, its decision variables (``len`` = the table's # vars)."""


class SearchSpace:
    """The decision variables of one filter and scheme; unit box ↔ parameter dicts."""

    def __init__(self, algorithm: str, scheme: str) -> None:
        if algorithm not in SPACES:
            raise ValueError(
                f"{algorithm!r} has no thesis-ch.-4 decision variables; choose one of {sorted(SPACES)}"
            )
        if scheme not in SPACES[algorithm]:
            raise ValueError(
                f"{algorithm} has no scheme {scheme!r}; choose one of {sorted(SPACES[algorithm])}"
            )
        self.algorithm = algorithm
        self.scheme = scheme
        self.vars = SPACES[algorithm][scheme]
        self.base = {**ALGORITHMS[algorithm].DEFAULTS, "scheme": scheme}

    def __len__(self) -> int:
        return len(self.vars)

    def params(self, u: np.ndarray, base: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """Filter parameters for the unit-box point ``u`` (other parameters from ``base``/defaults)."""
        out = {**self.base, **(base or {}), "scheme": self.scheme}
        lists: dict[str, list[float]] = {}
        for v, x in zip(self.vars, np.clip(u, 0.0, 1.0), strict=True):
            value = (
                math.exp(math.log(v.low) + x * (math.log(v.high) - math.log(v.low)))
                if v.log
                else v.low + x * (v.high - v.low)
            )
            if v.index is None:
                out[v.name] = float(value)
            else:
                lists.setdefault(v.name, list(out[v.name]))[v.index] = float(value)
        out.update({k: tuple(val) for k, val in lists.items()})
        return out

    def point(self, params: Mapping[str, Any]) -> np.ndarray:
        """Unit-box point of ``params`` (missing entries from the defaults), clipped into the ranges."""
        merged = {**self.base, **params}
        u = np.empty(len(self.vars))
        for i, v in enumerate(self.vars):
            value = float(merged[v.name] if v.index is None else merged[v.name][v.index])
            if v.log:
                value = min(max(value, v.low), v.high)
                u[i] = (math.log(value) - math.log(v.low)) / (math.log(v.high) - math.log(v.low))
            else:
                u[i] = (value - v.low) / (v.high - v.low)
        return np.clip(u, 0.0, 1.0)
