"""Batch entry point: run a streaming filter over whole arrays, sample by sample."""

from __future__ import annotations

from typing import Any

import numpy as np

from gait_biofeedback.core.orientation.filters.config import filter_params
from gait_biofeedback.core.orientation.filters.startup import calibrate_from_rest, quiet_samples


def estimate_orientation(gyr: np.ndarray, acc: np.ndarray, mag: np.ndarray | None, rate_hz: float,
                         algorithm: str | None = None, *, startup_s: float = 0.0,
                         location: str | None = None, tuned: bool = True, **params: Any) -> np.ndarray:
    """Orientation (N, 4) (w, x, y, z), sensor → world ENU, of gyro (rad/s), acc (m/s²), mag (any unit).

    ``mag=None`` runs the 6D mode (heading free). ``startup_s`` > 0 applies the start-up step
    (static gyro bias, reference norms, initial attitude) on the leading quiet samples, at most
    ``startup_s`` seconds (:func:`~gait_biofeedback.core.orientation.filters.startup.quiet_samples`).
    The output is exactly what the streaming filter returns when fed the same samples one by one (NaN
    samples hold the last good estimate; rows before the first valid sample are NaN).
    Parameters: those the ``orientation_filter`` node gives a segment at ``location`` (a segment or
    a body location; None: the set tuned for every sensor), ``params`` overriding them;
    ``tuned=False``: the class's untuned defaults instead
    (:func:`~gait_biofeedback.core.orientation.filters.config.filter_params`).
    """
    from gait_biofeedback.core.orientation.filters import ALGORITHMS, DEFAULT_ALGORITHM

    name = algorithm or DEFAULT_ALGORITHM
    resolved = filter_params(name, location, params, tuned=tuned)
    gyr = np.ascontiguousarray(gyr, dtype=float)
    acc = np.ascontiguousarray(acc, dtype=float)
    if gyr.ndim != 2 or gyr.shape[1] != 3 or acc.shape != gyr.shape:
        raise ValueError(f"gyr and acc must both be (N, 3), got {gyr.shape} and {acc.shape}")
    if mag is not None:
        mag = np.ascontiguousarray(mag, dtype=float)
        if mag.shape != gyr.shape:
            raise ValueError(f"mag must be (N, 3) like gyr, got {mag.shape}")
    filt = ALGORITHMS[name](rate_hz, **resolved)
    if startup_s > 0.0:
        n = quiet_samples(gyr, acc, rate_hz, max_s=startup_s)
        if n > 0:
            filt.calibrate(calibrate_from_rest(gyr[:n], acc[:n], None if mag is None else mag[:n]))
    out = np.full((len(gyr), 4), np.nan)
    g = gyr.tolist()
    a = acc.tolist()
    m = mag.tolist() if mag is not None else [None] * len(g)
    update = filt.update
    start = 0
    for i in range(len(g)):
        out[i] = update(g[i], a[i], m[i])
        if start == i and not filt.initialized:
            start = i + 1
    out[:start] = np.nan
    return out
