"""One segment's live orientation: an orientation filter plus the care a real stream needs.

:class:`SegmentOrientationTracker` wraps a filter of :mod:`gait_biofeedback.core.filters` and owns
what is not the filter's job: time from sample stamps, the start-up step, magnetometer samples that
arrive on their own stream, and bad input. The ``orientation_filter`` node and the offline path
(:func:`track_orientation`) both drive this class, so they give the same numbers.

Rules (issue 3):
- dt comes from the stamps. A NaN/inf sample is skipped and counted. A repeated stamp (duplicate
  packet) is skipped and counted. A stamp going backwards (a bag that loops, a driver restart)
  resets the filter and the start-up step, with a message. A gap > ``max_gap`` s re-initialises the
  attitude from the accelerometer (+ magnetometer); the gyro bias estimate is kept.
- Start-up (thesis §5.3.1): the first ``startup_s`` seconds are buffered; if the sensor was still,
  they give the static gyro bias, reference norms and initial attitude
  (:func:`~gait_biofeedback.core.filters.calibrate_from_rest`); if it moved, a message says so and
  the filter starts from the accelerometer alone. Then the buffered samples are filtered and released
  together, so no sample is lost; only the first ``startup_s`` s come out late, once.
- Magnetometer: the IMU sample at ``t`` uses the newest magnetometer sample stamped at or before
  ``t - mag_delay``, if it is not older than ``mag_delay + mag_max_age``; without one the filter runs
  in 6D mode for that sample. The fixed look-back ``mag_delay`` (50 ms) makes the pairing depend on
  stamps only, not on whether the magnetometer message of an instant arrives before or after the IMU
  message (DDS does not order across topics), so the live graph and the offline path agree exactly
  while the magnetometer stream lags by less than ``mag_delay``. A 50 ms old magnetic field costs
  nothing measurable: it only corrects the slow heading drift.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np

from gait_biofeedback.core.filters import (
    ALGORITHMS,
    DEFAULT_ALGORITHM,
    calibrate_from_rest,
    quiet_samples,
)
from gait_biofeedback.core.filters.config import load_tuned
from gait_biofeedback.core.segments import ImuSeries


@dataclass(frozen=True)
class OrientationSample:
    """One filtered sample: time (s), q (w, x, y, z) sensor→world, bias-corrected gyro, raw acc, and
    the caller's original ``stamp`` object passed through untouched (exact header stamps)."""

    t: float
    q: np.ndarray
    gyr: np.ndarray
    acc: np.ndarray
    stamp: Any = None


class SegmentOrientationTracker:
    """Streaming orientation of one segment's IMU (see module docstring)."""

    def __init__(self, segment: str, rate_hz: float = 100.0, algorithm: str | None = None,
                 params: dict[str, Any] | None = None, startup_s: float = 1.0, max_gap: float = 0.5,
                 mag_max_age: float = 0.05, mag_delay: float = 0.05) -> None:
        self.segment = segment
        self.algorithm = algorithm or DEFAULT_ALGORITHM
        if self.algorithm not in ALGORITHMS:
            raise ValueError(f"{segment}: unknown orientation algorithm {self.algorithm!r}; "
                             f"choose one of {sorted(ALGORITHMS)}")
        self.params = {**load_tuned().get(self.algorithm, {}), **(params or {})}
        self.rate_hz = float(rate_hz)
        self.startup_s = float(startup_s)
        self.max_gap = float(max_gap)
        self.mag_max_age = float(mag_max_age)
        self.mag_delay = float(mag_delay)
        self.filter = ALGORITHMS[self.algorithm](self.rate_hz, **self.params)
        self.counts = {"samples": 0, "published": 0, "nan_skipped": 0, "duplicates": 0,
                       "time_resets": 0, "gaps": 0, "mag_samples": 0}
        self.startup_quiet: bool | None = None
        self._messages: list[tuple[str, str]] = []
        self._mag: deque[tuple[float, tuple[float, float, float]]] = deque(maxlen=64)
        self._restart()

    def _restart(self) -> None:
        self._t_last: float | None = None
        self._startup: list[tuple[float, tuple, tuple, tuple | None]] | None = []

    def _say(self, level: str, text: str) -> None:
        self._messages.append((level, f"{self.segment}: {text}"))

    def pop_messages(self) -> list[tuple[str, str]]:
        """(level, text) messages since the last call; level is "info", "warn" or "error"."""
        out, self._messages = self._messages, []
        return out

    def add_mag(self, t: float, mag: Any) -> None:
        """A magnetometer sample (any unit, tesla on the wire) stamped ``t`` s."""
        m = tuple(float(v) for v in mag)
        if all(math.isfinite(v) for v in m):
            self._mag.append((float(t), m))
            self.counts["mag_samples"] += 1

    def _mag_for(self, t: float) -> tuple | None:
        newest = t - self.mag_delay
        for t_mag, m in reversed(self._mag):
            if t_mag <= newest:
                return m if newest - t_mag <= self.mag_max_age else None
        return None

    def update(self, t: float, gyr: Any, acc: Any, stamp: Any = None) -> list[OrientationSample]:
        """One IMU sample (rad/s, m/s²) at ``t`` s → the samples ready now (usually one); ``stamp``
        is handed back with the sample."""
        self.counts["samples"] += 1
        g = tuple(float(v) for v in gyr)
        a = tuple(float(v) for v in acc)
        if not all(math.isfinite(v) for v in g + a) or not math.isfinite(t):
            self.counts["nan_skipped"] += 1
            return []
        if self._t_last is not None:
            dt = t - self._t_last
            if dt == 0.0:
                self.counts["duplicates"] += 1
                return []
            if dt < 0.0:
                self.counts["time_resets"] += 1
                self._say("warn", f"time went back {-dt:.3f} s (bag loop or driver restart): "
                                  "orientation filter reset, start-up step repeated")
                self.filter.reset()
                self._restart()
            elif dt > self.max_gap:
                self.counts["gaps"] += 1
                self._say("warn", f"{dt:.2f} s without data: attitude re-initialised from the accelerometer")
                self.filter.initialize(a, self._mag_for(t))
        m = self._mag_for(t)
        if self._startup is not None:
            self._startup.append((t, g, a, m, stamp))
            self._t_last = t
            if t - self._startup[0][0] + 1.0 / self.rate_hz < self.startup_s:
                return []
            return self._finish_startup()
        dt = t - self._t_last if self._t_last is not None else None
        self._t_last = t
        return [self._step(t, g, a, m, dt, stamp)]

    def _finish_startup(self) -> list[OrientationSample]:
        samples, self._startup = self._startup, None
        gyr = np.array([s[1] for s in samples])
        acc = np.array([s[2] for s in samples])
        n = quiet_samples(gyr, acc, self.rate_hz, max_s=self.startup_s)
        self.startup_quiet = n >= 0.5 * len(samples)
        if self.startup_quiet:
            mags = [s[3] for s in samples[:n]]
            have = sum(m is not None for m in mags)
            mag = (np.array([m if m is not None else (np.nan,) * 3 for m in mags])
                   if have >= 0.5 * n else None)
            self.filter.calibrate(calibrate_from_rest(gyr[:n], acc[:n], mag))
        else:
            self._say("warn", f"sensor moved during the first {self.startup_s:g} s: gyro bias not "
                              "estimated; start sessions with the patient standing still")
            self.filter.initialize(samples[0][2], samples[0][3])
        out = []
        previous = None
        for t, g, a, m, stamp in samples:
            out.append(self._step(t, g, a, m, None if previous is None else t - previous, stamp))
            previous = t
        return out

    def _step(self, t: float, g: tuple, a: tuple, m: tuple | None, dt: float | None,
              stamp: Any) -> OrientationSample:
        q = self.filter.update(g, a, m, dt)
        bias = self.filter.gyro_bias()
        self.counts["published"] += 1
        return OrientationSample(t, q, np.array(g) - bias, np.array(a), stamp)

    def diagnostics(self) -> dict[str, Any]:
        """Counters and filter state for /diagnostics."""
        state = self.filter.state()
        return {
            "algorithm": self.algorithm,
            **self.counts,
            "initialized": bool(state["initialized"]),
            "startup_quiet": self.startup_quiet,
            "gyro_bias": np.asarray(state["gyro_bias"]).round(5).tolist(),
            "rest": bool(state["rest"]),
            "mag_disturbed": bool(state["mag_disturbed"]),
            "filter_skipped": state.get("skipped_samples", 0),
        }


def track_orientation(series: ImuSeries, **options: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Offline: the same tracker over a whole recording → (t (M,), q (M, 4), gyr (M, 3)).

    Magnetometer samples are taken to share the IMU stamps (as the project's recordings do).
    ``options`` are the tracker's keyword arguments; ``rate_hz`` defaults to the series' median rate
    rounded to 1 µHz (so a 100 Hz recording gives exactly the 100.0 the live node is configured with:
    the filters use 1/rate_hz as the dt of a first sample).
    """
    options.setdefault("rate_hz", round(series.rate_hz, 6))
    tracker = SegmentOrientationTracker(series.segment, **options)
    out: list[OrientationSample] = []
    mag = series.mag
    for k, t in enumerate(series.t.tolist()):
        if mag is not None:
            tracker.add_mag(t, mag[k])
        out.extend(tracker.update(t, series.gyr[k], series.acc[k]))
    if not out:
        return np.zeros(0), np.zeros((0, 4)), np.zeros((0, 3))
    return (np.array([s.t for s in out]), np.array([s.q for s in out]), np.array([s.gyr for s in out]))
