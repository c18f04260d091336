"""Particle swarm optimisation with the thesis' settings (thesis §4.2.3, orientation.md §3.6).

Population 50, 50 iterations, inertia weight 0.73 damped by 0.99 per iteration, personal and global
learning coefficients 1.5. Choices the thesis does not state (READING, the common "Yarpiz" form of
PSO that these settings come from): positions live in the unit box of the normalised decision
variables (:mod:`~gait_biofeedback.tuning.space`), velocities are limited to ±0.1 of the box and start
at zero, a particle that leaves the box is put back on the bound with its velocity reversed, and the
swarm can be seeded with known points (the thesis' later rounds seed with the previous optima).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class PsoSettings:
    """Thesis §4.2.3 values by default."""

    particles: int = 50
    iterations: int = 50
    inertia: float = 0.73
    inertia_damping: float = 0.99
    personal: float = 1.5
    social: float = 1.5
    max_velocity: float = 0.1
    seed: int = 0

    def __post_init__(self) -> None:
        if self.particles < 1 or self.iterations < 1:
            raise ValueError(
                f"PSO needs at least one particle and one iteration, got {self.particles} "
                f"particles and {self.iterations} iterations"
            )


@dataclass
class PsoResult:
    """Best point (unit box), its cost, the best cost after each iteration, the evaluations made and the
    costs of the ``seeds`` given (their first evaluation)."""

    best: np.ndarray
    cost: float
    history: list[float] = field(default_factory=list)
    evaluations: int = 0
    seed_costs: list[float] = field(default_factory=list)


def particle_swarm(
    cost: Callable[[np.ndarray], float],
    dims: int,
    settings: PsoSettings | None = None,
    seeds: Sequence[np.ndarray] = (),
    progress: Callable[[int, float], None] | None = None,
) -> PsoResult:
    """Minimise ``cost`` over the unit box [0, 1]^dims; ``seeds`` replace the first random particles.
    A cost that is not finite (a diverged filter) counts as +inf."""
    settings = settings or PsoSettings()
    rng = np.random.default_rng(settings.seed)
    x = rng.random((settings.particles, dims))
    for i, s in enumerate(seeds[: settings.particles]):
        x[i] = np.clip(np.asarray(s, dtype=float), 0.0, 1.0)
    v = np.zeros_like(x)

    def evaluate(p: np.ndarray) -> float:
        c = float(cost(p))
        return c if np.isfinite(c) else np.inf

    f = np.array([evaluate(p) for p in x])
    best_x, best_f = x.copy(), f.copy()
    g = int(np.argmin(best_f))
    result = PsoResult(
        best_x[g].copy(),
        float(best_f[g]),
        [float(best_f[g])],
        settings.particles,
        [float(c) for c in f[: min(len(seeds), settings.particles)]],
    )
    w = settings.inertia
    for it in range(settings.iterations):
        r1 = rng.random(x.shape)
        r2 = rng.random(x.shape)
        v = w * v + settings.personal * r1 * (best_x - x) + settings.social * r2 * (result.best - x)
        v = np.clip(v, -settings.max_velocity, settings.max_velocity)
        x = x + v
        out = (x < 0.0) | (x > 1.0)
        v[out] = -v[out]
        x = np.clip(x, 0.0, 1.0)
        f = np.array([evaluate(p) for p in x])
        result.evaluations += settings.particles
        better = f < best_f
        best_x[better], best_f[better] = x[better], f[better]
        g = int(np.argmin(best_f))
        if best_f[g] < result.cost:
            result.best, result.cost = best_x[g].copy(), float(best_f[g])
        result.history.append(result.cost)
        w *= settings.inertia_damping
        if progress is not None:
            progress(it + 1, result.cost)
    return result
