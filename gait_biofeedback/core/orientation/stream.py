"""One segment's live orientation: an orientation filter plus the care a real stream needs.

:class:`SegmentOrientationTracker` wraps a filter of :mod:`gait_biofeedback.core.orientation.filters` and owns
what is not the filter's job: time from sample stamps, the start-up step, magnetometer samples that
arrive on their own stream, and bad input. The ``orientation_filter`` node and the offline path
(:func:`track_orientation`) both drive this class, so they give the same numbers.

Samples are identified by their stamps, int ns (``docs/conventions.md``, Time); dt is computed from
them in float seconds. The stage's parameters are :class:`OrientationParams`.

Rules (issues 3 and 13):
- dt comes from the stamps. A NaN/inf sample is skipped and counted. A sample more than 10 %
  beyond the sensor's physical range (``acc_range``, ``gyr_range``: a glitch, not motion; a reading
  at the range is a saturated one and is kept) is rejected and counted as out of range.
- Samples pass a :class:`~gait_biofeedback.core.sequencer.StreamSequencer`: ``reorder_window_s`` s
  re-sequence samples that arrive out of order (that much latency added); a duplicate, a late
  sample or a single stamp that jumps is dropped and counted, with a message saying which. Only a
  confirmed jump back (a bag that loops, a driver restart) resets the filter and the start-up step.
  A hole in the stamps up to ``max_gap_s`` s is bridged (:meth:`SegmentOrientationTracker._bridge`);
  after a longer gap the attitude is re-acquired from the next ``recover_s`` s
  (:mod:`~gait_biofeedback.core.orientation.reacquire`), those samples marked ``recovering``.
  ``max_gap_s`` 0.15 s was chosen on the demo walk (seeds 1, 2): bridged
  holes up to 0.15 s stay within 3.4° of the clean run, a 0.2 s one reaches 8°, a 0.3 s one 28°;
  re-acquired after one gap, the attitude was as close to the truth as the clean run's. A gap
  inside the start-up or re-acquisition window ends that window and starts a new re-acquisition.
  A slow sensor's gaps are at least 3 sample periods. The start-up gyro bias is kept (an online
  bias estimate starts over).
  :meth:`SegmentOrientationTracker.flush` releases what the window still holds at the end of a
  recording.
- Rate: the rate measured from the stamps of the start-up window
  (:class:`~gait_biofeedback.core.rate.RateCheck`) replaces ``rate_hz`` when it differs by more
  than 10 %, with a message naming both.
- Start-up (thesis §5.3.1): the first ``startup_s`` seconds are buffered; if the sensor was still,
  they give the static gyro bias, reference norms and initial attitude
  (:func:`~gait_biofeedback.core.orientation.filters.calibrate_from_rest`); if it moved, a message says so and
  the filter starts from the accelerometer alone. Then the buffered samples are filtered and released
  together, so no sample is lost; only the first ``startup_s`` s come out late, once.
- Magnetometer: the IMU sample at ``t`` uses the newest magnetometer sample stamped at or before
  ``t - mag_delay``, if it is not older than ``mag_delay + mag_max_age_s``; without one the filter runs
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

from gait_biofeedback.core.notices import Notices
from gait_biofeedback.core.orientation.filters import (
    ALGORITHMS,
    DEFAULT_ALGORITHM,
    calibrate_from_rest,
    quiet_samples,
)
from gait_biofeedback.core.orientation.filters.config import filter_params
from gait_biofeedback.core.orientation.filters.guo_fkf import KF_SCHEMES
from gait_biofeedback.core.orientation.reacquire import attitude_after_gap
from gait_biofeedback.core.params import param, require
from gait_biofeedback.core.rate import MISSING_SHARE_MIN, MISSING_WARN, RateCheck, missing_samples
from gait_biofeedback.core.segments import SEGMENTS, ImuSeries
from gait_biofeedback.core.sequencer import DROPPED, StreamSequencer
from gait_biofeedback.core.stamps import NS_PER_S, ns_to_seconds, seconds_to_ns

_CHOICES = tuple(sorted(ALGORITHMS))
RANGE_MARGIN = 1.1
"""A sample is rejected beyond its range by this factor: a sensor that saturates (a heel strike on a
±16 g accelerometer reads up to 158 m/s² on gaitmap's example) is clipped, not glitching."""
UNITS_SUSPECT = 100
"""This many samples beyond the range among the first 2 × as many: the units are wrong, not a glitch."""
SIX_D = "6D (no magnetometer): heading from the gyro only, it drifts"
INFORMATION = (SIX_D,)
"""Conditions that are a kit's normal state, not a fault (a kit without magnetometers): said, at level
OK on /diagnostics and as a note by ``analyze``, never as a warning."""
STARTUP_GAP_S = 1.0
"""During start-up the rate is not known yet: a gap there is a silence of over this long."""


@dataclass(frozen=True)
class OrientationParams:
    """Parameters of the orientation stage (node ``orientation_filter``, and ``analyze``)."""

    segments: tuple[str, ...] = param(SEGMENTS, "segments whose IMUs are tracked", choices=SEGMENTS)
    algorithm: str = param(DEFAULT_ALGORITHM, "orientation filter of every segment", choices=_CHOICES)
    segment_algorithm: dict[str, str] = param(
        "", "orientation filter of this segment ('' = the 'algorithm' parameter)", choices=("", *_CHOICES),
        keys=SEGMENTS, name="{key}.algorithm")
    scheme: str = param("", "gain scheme of the filters that have one (thesis ch. 4: fixed = FOG, "
                        "two_level = VST1, three_level = VST2, fuzzy = VST3, iae = innovation adaptive, "
                        "guo_fkf only); '' = the tuned one", choices=("", *KF_SCHEMES))
    rate_hz: float = param(100.0, "nominal sample rate, for the filters' defaults (dt comes from the stamps; "
                           "the rate measured at start-up is used when it differs by over 10 %)",
                           "Hz", low=1.0, high=2000.0)
    startup_s: float = param(1.0, "quiet standing at the start used for the gyro bias and initial attitude",
                             "s", low=0.1, high=30.0)
    max_gap_s: float = param(0.15, "longest hole in the stamps bridged by interpolation; after a longer one "
                             "the attitude is re-acquired", "s", low=0.01, high=60.0)
    recover_s: float = param(2.0, "after a gap, the attitude is re-acquired from this much data (one "
                             "stride or more; the samples come out that much later, marked as recovering)",
                             "s", low=0.05, high=10.0)
    reorder_window_s: float = param(0.03, "samples out of order by less than this are re-sequenced (added "
                                    "latency)", "s", low=0.0, high=1.0)
    acc_range: float = param(16 * 9.80665, "the accelerometer's range per axis (more than 10 % beyond it: "
                             "a glitch, rejected)", "m/s^2", low=1.0, high=10000.0)
    gyr_range: float = param(2000 * math.pi / 180, "the gyro's range per axis (more than 10 % beyond it: a "
                             "glitch, rejected)", "rad/s", low=0.1, high=1000.0)
    mag_max_age_s: float = param(0.05, "oldest magnetometer sample a sample may use, beyond the fixed 50 ms "
                                 "look-back", "s", low=0.0, high=1.0)
    orientation_variance: float = param(0.0012, "diagonal of the published orientation_covariance (while "
                                        "recovering from a dropout: (10°)², which this stays below)", "rad^2",
                                        low=0.0, high=0.03)
    stale_after_s: float = param(1.0, "time without data before a segment is reported stale on /diagnostics",
                                 "s", low=0.1, high=60.0)
    diagnostics_period_s: float = param(1.0, "period of the /diagnostics status", "s", low=0.1, high=60.0)

    def __post_init__(self) -> None:
        require(len(set(self.segments)) == len(self.segments),
                f"parameter 'segments': {list(self.segments)} names a segment twice")

    def algorithm_of(self, segment: str) -> str:
        """The filter of ``segment``: its own override, else ``algorithm``."""
        return self.segment_algorithm.get(segment) or self.algorithm

    def tracker(self, segment: str) -> SegmentOrientationTracker:
        """The stream of one segment with these parameters."""
        return SegmentOrientationTracker(segment, rate_hz=self.rate_hz, algorithm=self.algorithm_of(segment),
                                         scheme=self.scheme, startup_s=self.startup_s,
                                         max_gap_s=self.max_gap_s, mag_max_age_s=self.mag_max_age_s,
                                         reorder_window_s=self.reorder_window_s,
                                         acc_range=self.acc_range, gyr_range=self.gyr_range,
                                         recover_s=self.recover_s)


@dataclass(frozen=True)
class OrientationSample:
    """One filtered sample: its stamp (int ns), q (w, x, y, z) sensor→world, bias-corrected gyro
    (rad/s), raw acc (m/s²)."""

    stamp_ns: int
    q: np.ndarray
    gyr: np.ndarray
    acc: np.ndarray
    recovering: bool = False  # in the window that re-acquired the attitude after a gap
    heading: bool = True  # False: no magnetometer sample, the filter ran 6D (heading from the gyro only)

    @property
    def t(self) -> float:
        """The stamp in seconds."""
        return self.stamp_ns / NS_PER_S


class SegmentOrientationTracker:
    """Streaming orientation of one segment's IMU (see module docstring)."""

    def __init__(self, segment: str, rate_hz: float = 100.0, algorithm: str | None = None,
                 params: dict[str, Any] | None = None, startup_s: float = 1.0, max_gap_s: float = 0.15,
                 mag_max_age_s: float = 0.05, mag_delay: float = 0.05, reorder_window_s: float = 0.03,
                 acc_range: float = 16 * 9.80665, gyr_range: float = 2000 * math.pi / 180,
                 recover_s: float = 2.0, scheme: str = "") -> None:
        self.segment = segment
        self.algorithm = algorithm or DEFAULT_ALGORITHM
        if self.algorithm not in ALGORITHMS:
            raise ValueError(f"{segment}: unknown orientation algorithm {self.algorithm!r}; "
                             f"choose one of {sorted(ALGORITHMS)}")
        if scheme and "scheme" not in ALGORITHMS[self.algorithm].DEFAULTS:
            raise ValueError(f"{segment}: orientation algorithm {self.algorithm!r} has no gain scheme; set "
                             "'scheme' to '' or choose madgwick, mahony, guo_fkf or roetenberg_ikf")
        # tuned for this body location (thesis §4.3), else for every sensor; then the scheme and overrides
        self.params = filter_params(self.algorithm, segment, {**({"scheme": scheme} if scheme else {}),
                                                              **(params or {})})
        self.rate_hz = float(rate_hz)
        self.startup_s = float(startup_s)
        self.max_gap_s = float(max_gap_s)
        self.mag_max_age_s = float(mag_max_age_s)
        self.mag_delay = float(mag_delay)
        self.filter = ALGORITHMS[self.algorithm](self.rate_hz, **self.params)
        self.recover_s = float(recover_s)
        self.acc_range = float(acc_range)
        self.gyr_range = float(gyr_range)
        self.sequencer = StreamSequencer(window=reorder_window_s)
        self.rate = RateCheck(rate_hz)
        self._rate_note: str | None = None
        self.counts = {"samples": 0, "published": 0, "nan_skipped": 0, "no_gyro": 0, "out_of_range": 0,
                       "duplicates": 0, "late": 0, "bad_stamps": 0, "time_resets": 0, "gaps": 0, "missing": 0,
                       "mag_samples": 0}
        self.startup_quiet: bool | None = None
        self.last_gap_s = 0.0
        self.gaps: deque[tuple[int, int]] = deque(maxlen=1000)
        """(stamp before, stamp after) of the latest gaps taken for a dropout, int ns."""
        self._reported: dict[str, int] = {}  # the counts at the last report()
        self.notices = Notices()
        self._mag: deque[tuple[float, tuple[float, float, float]]] = deque(maxlen=64)
        self._restart()

    def _restart(self) -> None:
        self._t_last: float | None = None
        self._startup: list[tuple[float, tuple, tuple, tuple | None, int]] | None = []
        self._recover: list[tuple[float, tuple, tuple, tuple | None, int]] | None = None
        self._last_q: np.ndarray | None = None
        self._last_ga: tuple[tuple, tuple] = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))

    def _say(self, level: str, text: str) -> None:
        self.notices.say(level, f"{self.segment}: {text}")

    def add_mag(self, stamp_ns: int, mag: Any) -> None:
        """A magnetometer sample (any unit, tesla on the wire) stamped ``stamp_ns``."""
        m = tuple(map(float, mag))
        if math.isfinite(sum(m)) or all(math.isfinite(v) for v in m):
            self._mag.append((stamp_ns / NS_PER_S, m))
            self.counts["mag_samples"] += 1

    def _mag_for(self, t: float) -> tuple | None:
        newest = t - self.mag_delay
        for t_mag, m in reversed(self._mag):
            if t_mag <= newest:
                return m if newest - t_mag <= self.mag_max_age_s else None
        return None

    def update(self, stamp_ns: int, gyr: Any, acc: Any) -> list[OrientationSample]:
        """One IMU sample (rad/s, m/s²) stamped ``stamp_ns`` → the samples ready now (usually one,
        ``reorder_window_s`` s after its stamp)."""
        self.counts["samples"] += 1
        g = tuple(map(float, gyr))
        a = tuple(map(float, acc))
        if not math.isfinite(sum(g) + sum(a)) and not all(math.isfinite(v) for v in g + a):
            no_gyro = all(math.isfinite(v) for v in a) and not any(math.isfinite(v) for v in g)
            self.counts["no_gyro" if no_gyro else "nan_skipped"] += 1
            return []
        acc_peak, gyr_peak = max(map(abs, a)), max(map(abs, g))
        if acc_peak > RANGE_MARGIN * self.acc_range or gyr_peak > RANGE_MARGIN * self.gyr_range:
            self.counts["out_of_range"] += 1
            if self.counts["out_of_range"] == UNITS_SUSPECT and self.counts["samples"] < 2 * UNITS_SUSPECT:
                first = self.counts["samples"]
                self._say("error", f"{UNITS_SUSPECT} of the first {first} samples are beyond the sensor's "
                                   "range: the data are probably in other units than the wire's (a gyro in "
                                   "deg/s sent as rad/s, an accelerometer in counts or g sent as m/s²); a "
                                   "recording: import it again with the right --units")
            if self.counts["out_of_range"] == 1:
                self._say("warn", f"sample beyond the sensor's range (acc {acc_peak:.4g} m/s², gyro "
                                  f"{gyr_peak:.4g} rad/s; ranges {self.acc_range:.4g}, "
                                  f"{self.gyr_range:.4g}, +{RANGE_MARGIN - 1:.0%}): rejected as a glitch; "
                                  "further ones are counted")
            return []
        return self._run(self.sequencer.push(stamp_ns, (g, a)))

    def flush(self, end: bool = False) -> list[OrientationSample]:
        """The samples the reorder window still holds (a stream that went silent); with ``end`` (the end
        of a recording), a start-up or re-acquisition window in progress too (live, a silence is not its
        end: the window goes on when the data come back)."""
        out = self._run(self.sequencer.flush())
        if end and self._recover:
            out += self._finish_recovery()
        elif end and self._startup:
            out += self._finish_startup()
        return out

    def _run(self, released: list) -> list[OrientationSample]:
        """The sequencer's released samples through the filter; its drops counted and said."""
        if self.sequencer.sync_drops(self.counts):
            dropped = self.sequencer.dropped
            if dropped <= 3 or dropped % 100 == 0:
                more = "" if dropped < 3 else f" ({dropped} so far; counted on /diagnostics)"
                self._say("warn", f"dropped {self.sequencer.last_dropped}{more}")
        out: list[OrientationSample] = []
        for r in released:
            out += self._process(r.stamp_ns, *r.payload, restart_s=r.restart_s)
        return out

    def _process(self, stamp_ns: int, g: tuple, a: tuple, restart_s: float = 0.0) -> list[OrientationSample]:
        t = stamp_ns / NS_PER_S
        if restart_s:
            self.counts["time_resets"] += 1
            if self._last_q is None:  # still in its start-up: that starts again
                self._say("warn", f"time went back {restart_s:.3f} s and went on from there (a recording "
                                  "replayed again, or the driver or sensor restarted): orientation filter "
                                  "reset, start-up step repeated")
                self.filter.reset()
                self._restart()
            else:  # the sensor kept its attitude: re-acquired as after a gap (a start-up while moving is
                # an attitude from one sample: a knee 100° off for seconds), its samples marked
                self._say("warn", f"time went back {restart_s:.3f} s and went on from there (a recording "
                                  "replayed again, or the driver or sensor restarted): attitude re-acquired "
                                  f"from the next {self.recover_s:g} s (those samples are marked as "
                                  "recovering)")
                self._t_last = None
                self._recover = []
        released: list[OrientationSample] = []
        if self._t_last is not None:
            dt = t - self._t_last
            gap_s = max(self.max_gap_s, 3.0 / self.rate_hz,
                        STARTUP_GAP_S if self._startup is not None else 0.0)
            if dt > gap_s:
                # a gap inside the start-up or re-acquisition window ends it with what it holds
                if self._startup is not None:
                    released = self._finish_startup()
                elif self._recover is not None:
                    released = self._finish_recovery()
                self.counts["gaps"] += 1
                self.last_gap_s = dt
                self.gaps.append((round(self._t_last * NS_PER_S), stamp_ns))
                self._say("warn", f"{dt:.2f} s without data: attitude re-acquired from the next "
                                  f"{self.recover_s:g} s (those samples are marked as recovering)")
                self._recover = []
            elif self._startup is None and (missing := missing_samples(dt * self.rate_hz)):
                # the rate is known after start-up
                self.counts["missing"] += missing
                if self._recover is None:
                    self._bridge(missing, dt, g, a)
        self._rate_note = self.rate.update(stamp_ns) or self._rate_note
        m = self._mag_for(t)
        for held, duration, finish in ((self._recover, self.recover_s, self._finish_recovery),
                                       (self._startup, self.startup_s, self._finish_startup)
                                       ) if self._recover is not None or self._startup is not None else ():
            if held is not None:  # the re-acquisition or start-up window: held, then released together
                held.append((t, g, a, m, stamp_ns))
                self._t_last = t
                return released + (finish() if t - held[0][0] + 1.0 / self.rate_hz >= duration else [])
        dt = t - self._t_last if self._t_last is not None else None
        self._t_last = t
        return [*released, self._step(g, a, m, dt, stamp_ns)]

    def _bridge(self, missing: int, dt: float, g: tuple, a: tuple) -> None:
        """A hole of ``missing`` samples (at most ``max_gap_s``): the filter is stepped through the
        missing instants with the gyro and accelerometer interpolated linearly between the samples on
        either side (nothing is published for them). One step of the whole hole would integrate only
        the sample after it: on the demo walk a 0.1 s hole left a shank 13° off (1 s after), bridged
        it stays within 3°."""
        step = dt / (missing + 1)
        g0, a0 = self._last_ga
        for j in range(1, missing + 1):
            f = j / (missing + 1)
            self.filter.update(tuple(p + f * (q - p) for p, q in zip(g0, g, strict=True)),
                               tuple(p + f * (q - p) for p, q in zip(a0, a, strict=True)), None, step)
        self._t_last += missing * step

    def _finish_startup(self) -> list[OrientationSample]:
        samples, self._startup = self._startup, None
        note, self._rate_note = self._rate_note or self.rate.decide(), None
        if note:
            self.notices.say("warn", f"{self.segment} (orientation filter): {note}")
            self.rate_hz = self.rate.rate_hz
            self.filter = ALGORITHMS[self.algorithm](self.rate_hz, **self.params)
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
        for t, g, a, m, stamp_ns in samples:
            out.append(self._step(g, a, m, None if previous is None else t - previous, stamp_ns))
            previous = t
        return out

    def _finish_recovery(self) -> list[OrientationSample]:
        samples, self._recover = self._recover, None
        bias = self.filter.gyro_bias()
        mag = np.array([s[3] if s[3] is not None else (np.nan,) * 3 for s in samples])
        q0 = attitude_after_gap([s[0] for s in samples], np.array([s[1] for s in samples]),
                                np.array([s[2] for s in samples]), mag, bias, self._last_q)
        self.filter.reset(q0)
        t0, g0, a0, m0, stamp0 = samples[0]
        self.counts["published"] += 1
        self._last_q = q0
        out = [OrientationSample(stamp0, q0, np.array(g0) - bias, np.array(a0), True, m0 is not None)]
        previous = t0
        for t, g, a, m, stamp_ns in samples[1:]:
            out.append(self._step(g, a, m, t - previous, stamp_ns, recovering=True))
            previous = t
        return out

    def _step(self, g: tuple, a: tuple, m: tuple | None, dt: float | None,
              stamp_ns: int, recovering: bool = False) -> OrientationSample:
        q = self.filter.update(g, a, m, dt)
        self._last_ga = (g, a)
        self._last_q = q
        bias = self.filter.gyro_bias()
        self.counts["published"] += 1
        return OrientationSample(stamp_ns, q, np.array(g) - bias, np.array(a), recovering, m is not None)

    @property
    def recovering(self) -> bool:
        """The attitude is being re-acquired after a gap (its samples are held, then marked)."""
        return self._recover is not None

    def conditions(self, before: dict[str, int]) -> list[str]:
        """What is wrong now, or happened since the counts ``before`` (a copy of :attr:`counts` taken
        at the last report): the warnings /diagnostics names."""
        new = {k: v - before.get(k, 0) for k, v in self.counts.items()}
        out = []
        if self.recovering:
            out.append(f"sensor dropout: re-acquiring the attitude ({self.recover_s:g} s, those samples are "
                       "marked, no feedback from them)")
        elif new["gaps"]:
            out.append(f"sensor dropout: {self.last_gap_s:.2f} s without data (attitude re-acquired)")
        if new["time_resets"]:
            out.append("time went back: filter reset (recording replayed again, or driver restart)")
        if new["out_of_range"]:
            out.append(f"{new['out_of_range']} sample(s) out of range rejected (glitch)")
        dropped = [f"{new[k]} {k.replace('_', ' ')}" for k in DROPPED if new[k]]
        if dropped:
            out.append("dropped " + ", ".join(dropped))
        if new["nan_skipped"]:
            out.append(f"{new['nan_skipped']} sample(s) with NaN skipped")
        if new["no_gyro"]:
            out.append("no gyro (angular rate not given): no orientation from this sensor (an accelerometer "
                       "alone: the activity monitor uses it)")
        # the holes a rejected or dropped sample leaves are named above, not counted again
        lost = new["missing"] - sum(new[k] for k in ("nan_skipped", "no_gyro", "out_of_range", "late",
                                                     "bad_stamps"))
        expected = new["samples"] + lost
        if lost > MISSING_WARN * expected:
            share = (f"{100 * lost / expected:.1f} %" if expected >= MISSING_SHARE_MIN
                     else f"{lost} of {expected}")
            out.append(f"losing samples: {share} missing from the stamps (the link, or a node falling "
                       "behind)")
        if self.rate.mismatch:
            out.append(f"rate {self.rate.measured_hz:.1f} Hz measured, {self.rate.configured_hz:g} "
                       "configured: using the measured rate")
        if self.startup_quiet is not None and not self.counts["mag_samples"]:
            out.append(SIX_D)
        return out

    def report(self) -> list[str]:
        """:meth:`conditions` since the last report (a /diagnostics status)."""
        texts = self.conditions(self._reported)
        self._reported = dict(self.counts)
        return texts

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
            "recovering": self.recovering,
            "rate_hz": self.rate_hz,
            "measured_rate_hz": None if self.rate.measured_hz is None else round(self.rate.measured_hz, 2),
            "magnetometer": bool(self.counts["mag_samples"]),
        }


def track_orientation(series: ImuSeries, **options: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Offline: the same tracker over a whole recording → (t (M,), q (M, 4), gyr (M, 3)).

    The series' times become stamps on the 1 ns grid (as in a recording) and the returned ``t`` is
    those stamps in seconds. Magnetometer samples are taken to share the IMU stamps (as the
    project's recordings do).
    ``options`` are the tracker's keyword arguments; ``rate_hz`` defaults to the series' median rate
    rounded to 1 µHz (so a 100 Hz recording gives exactly the 100.0 the live node is configured with:
    the filters use 1/rate_hz as the dt of a first sample).
    """
    options.setdefault("rate_hz", round(series.rate_hz, 6))
    tracker = SegmentOrientationTracker(series.segment, **options)
    out: list[OrientationSample] = []
    mag = series.mag
    for k, stamp_ns in enumerate(seconds_to_ns(series.t).tolist()):
        if mag is not None:
            tracker.add_mag(stamp_ns, mag[k])
        out.extend(tracker.update(stamp_ns, series.gyr[k], series.acc[k]))
    out.extend(tracker.flush(end=True))
    if not out:
        return np.zeros(0), np.zeros((0, 4)), np.zeros((0, 3))
    return (ns_to_seconds(np.array([s.stamp_ns for s in out])), np.array([s.q for s in out]),
            np.array([s.gyr for s in out]))
