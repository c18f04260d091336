"""Scoring detected gait events against reference events (thesis §6.2.4, Eq 53).

A detection matches a reference event when it lies within ``tolerance`` (±500 ms in the thesis) and
neither is matched yet; references are taken in time order and each gets its nearest free
detection. Sensitivity Se = TP / (TP + FN), precision Pr = TP / (TP + FP) (thesis Eq 53); the timing
error of a match is detection − reference.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

MATCH_TOLERANCE_S = 0.5


@dataclass
class EventScore:
    """Matches of one event type: timing errors (s), missed references, extra detections (times, s)."""

    errors: list[float] = field(default_factory=list)
    missed: list[float] = field(default_factory=list)
    extra: list[float] = field(default_factory=list)

    def __iadd__(self, other: EventScore) -> EventScore:
        self.errors += other.errors
        self.missed += other.missed
        self.extra += other.extra
        return self

    @property
    def sensitivity(self) -> float:
        """TP / (TP + FN), 0..1 (NaN without references)."""
        n = len(self.errors) + len(self.missed)
        return len(self.errors) / n if n else float("nan")

    @property
    def precision(self) -> float:
        """TP / (TP + FP), 0..1 (NaN without detections)."""
        n = len(self.errors) + len(self.extra)
        return len(self.errors) / n if n else float("nan")

    @property
    def mean_error(self) -> float:
        """Mean timing error, s."""
        return float(np.mean(self.errors)) if self.errors else float("nan")

    @property
    def sd_error(self) -> float:
        """Sample SD of the timing error, s."""
        return float(np.std(self.errors, ddof=1)) if len(self.errors) > 1 else float("nan")


def match_events(detected, reference, tolerance: float = MATCH_TOLERANCE_S) -> EventScore:
    """Greedy one-to-one matching of event times (s), references in time order (module docstring)."""
    detected = np.sort(np.asarray(detected, dtype=float))
    used = np.zeros(len(detected), dtype=bool)
    score = EventScore()
    for ref in np.sort(np.asarray(reference, dtype=float)).tolist():
        free = np.flatnonzero(~used & (np.abs(detected - ref) <= tolerance))
        if len(free):
            best = free[np.argmin(np.abs(detected[free] - ref))]
            used[best] = True
            score.errors.append(float(detected[best] - ref))
        else:
            score.missed.append(ref)
    score.extra = detected[~used].tolist()
    return score
