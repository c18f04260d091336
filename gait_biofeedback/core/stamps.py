"""Time in the core: a sample is identified by its stamp, an integer count of nanoseconds.

``docs/conventions.md`` (Time): stamps are int ns (the header stamps of the wire, exactly); durations
and rates derived from them are float seconds, computed as ``(ns_b - ns_a) / 1e9`` or ``ns / 1e9``
with Python's correctly rounded int division, so every path that starts from the same stamps
computes the same floats. "In force from" (a calibration, a forward axis) is a stamp in ns too.
"""

from __future__ import annotations

import math

import numpy as np

NS_PER_S = 1_000_000_000


def ns_to_s(ns: int) -> float:
    """Stamp (int ns) → the float nearest to its exact value in seconds."""
    return ns / NS_PER_S


def s_to_ns(t: float) -> int:
    """Float seconds → the nearest int ns (exact split into whole and fractional seconds)."""
    whole = math.floor(t)
    return int(whole) * NS_PER_S + round((t - whole) * 1e9)


def seconds_to_ns(t: np.ndarray) -> np.ndarray:
    """Float seconds (array) → nearest int64 ns, element by element as :func:`s_to_ns`."""
    t = np.asarray(t, dtype=float)
    whole = np.floor(t)
    return whole.astype(np.int64) * NS_PER_S + np.rint((t - whole) * 1e9).astype(np.int64)


def ns_to_seconds(ns: np.ndarray) -> np.ndarray:
    """Int ns (array) → float seconds, element by element as :func:`ns_to_s` (correctly rounded)."""
    return np.array([n / NS_PER_S for n in np.asarray(ns, dtype=np.int64).tolist()], dtype=float)


def sample_stamps(n: int, rate_hz: float) -> np.ndarray:
    """Stamps (int64 ns) of ``n`` samples at ``rate_hz`` starting at 0: the batch entry points' time
    base, ``seconds_to_ns(k / rate_hz)``."""
    return seconds_to_ns(np.arange(n) / rate_hz)


def lost_between(last_ns: int, ns: int, rate_hz: float) -> list[tuple[int, float]]:
    """The samples lost between two consecutive stamps at ``rate_hz``: (stamp ns, fraction of the
    way from ``last_ns`` to ``ns``) of each, evenly spaced; none when the gap is under 1.5 periods."""
    gap = ns - last_ns
    missing = round(gap * rate_hz / NS_PER_S) - 1
    return [(last_ns + round(j / (missing + 1) * gap), j / (missing + 1)) for j in range(1, missing + 1)]
