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

from gait_biofeedback.core.notices import Notice, Notices
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
from gait_biofeedback.core.rate import HOLE, MISSING_SHARE_MIN, MISSING_WARN, RateCheck, missing_samples
from gait_biofeedback.core.segments import SEGMENTS, ImuSeries
from gait_biofeedback.core.sequencer import DROPPED, StreamSequencer
from gait_biofeedback.core.stamps import NS_PER_S, ns_to_seconds, seconds_to_ns

_CHOICES = tuple(sorted(ALGORITHMS))
RANGE_MARGIN = 1.1
"""A sample is rejected beyond its range by this factor: a sensor that saturates (a heel strike on a
±16 g accelerometer reads up to 158 m/s² on gaitmap's example) is clipped, not glitching."""
UNITS_SUSPECT = 100
"""This many samples beyond the range among the first 2 × as many: the units are wrong, not a glitch."""
SIX_D = ("6D (no magnetometer): each sensor's own heading comes from its gyro and drifts; joint angles take "
         "their headings from the legs' movement, gait events and strides need none")
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


@dataclass
class OrientationBatch:
    """What :meth:`SegmentOrientationTracker.update_batch` released, in release order: ``call`` (M,) the
    index of the input sample whose update released each (as :meth:`~SegmentOrientationTracker.update`
    returns them), the :class:`OrientationSample` fields as arrays (``stamp_ns`` (M,) int, ``q`` (M, 4),
    ``gyr`` (M, 3), ``acc`` (M, 3), ``recovering``, ``heading`` (M,) bool), and ``notices``: (call
    index, the notices said while handling it), popped from the tracker."""

    call: np.ndarray
    stamp_ns: np.ndarray
    q: np.ndarray
    gyr: np.ndarray
    acc: np.ndarray
    recovering: np.ndarray
    heading: np.ndarray
    notices: list[tuple[int, list[Notice]]]

    @classmethod
    def of(cls, calls: list[int], samples: list[OrientationSample]) -> OrientationBatch:
        """Samples released one by one (``calls``: the input index of each) as a batch."""
        n = len(samples)
        return cls(np.array(calls, dtype=np.int64), np.array([s.stamp_ns for s in samples], dtype=np.int64),
                   np.array([s.q for s in samples]).reshape(n, 4),
                   np.array([s.gyr for s in samples]).reshape(n, 3),
                   np.array([s.acc for s in samples]).reshape(n, 3),
                   np.array([s.recovering for s in samples], dtype=bool),
                   np.array([s.heading for s in samples], dtype=bool), [])

    @classmethod
    def concat(cls, parts: list[OrientationBatch]) -> OrientationBatch:
        """The parts one after the other."""
        return cls(*(np.concatenate([getattr(p, name) for p in parts]) for name in
                     ("call", "stamp_ns", "q", "gyr", "acc", "recovering", "heading")),
                   [n for p in parts for n in p.notices])


MIN_RUN = 16
MAX_RUN = 8192
"""Ordinary samples in a row that :meth:`SegmentOrientationTracker.update_batch` runs as arrays; fewer go
through :meth:`SegmentOrientationTracker.update` (the arrays' set-up costs more than they save); a run
is cut every ``MAX_RUN`` samples."""


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

    def update_batch(self, stamp_ns: np.ndarray, gyr: np.ndarray, acc: np.ndarray,
                     mag_ns: np.ndarray | None = None, mag: np.ndarray | None = None,
                     mag_before: np.ndarray | None = None) -> OrientationBatch:
        """:meth:`update` of each row (stamps int ns (n,), gyro, acc (n, 3)) with the magnetometer
        samples (``mag_ns``, ``mag``) given to :meth:`add_mag` in between (``mag_before`` (n,): how many
        of them come before each row; the rest after the last), as the array function of the stream (as
        vqf's ``updateBatch``): the same outputs, notices and state, bit for bit. Runs of ordinary
        samples (the stream steady: in order, no hole, finite, in range, the magnetometer stamps in
        order, nothing held across a jump) are filtered as arrays (:meth:`_steady_run`); wherever the
        control logic acts, the samples go through :meth:`update` one by one."""
        n = len(stamp_ns)
        stamps = np.asarray(stamp_ns, dtype=np.int64)
        gyr, acc = np.asarray(gyr, dtype=float), np.asarray(acc, dtype=float)
        n_mag = 0 if mag_ns is None else len(mag_ns)
        mag_before = np.zeros(n, np.int64) if mag_before is None else np.asarray(mag_before, np.int64)
        mag_values = np.zeros((0, 3)) if mag is None else np.asarray(mag, dtype=float)
        mag_list = mag_values.tolist()
        mag_stamps = [] if mag_ns is None else np.asarray(mag_ns, np.int64).tolist()
        stamp_list, g_rows, a_rows = stamps.tolist(), gyr.tolist(), acc.tolist()
        ordinary = (np.isfinite(gyr).all(axis=1) & np.isfinite(acc).all(axis=1)
                    & ~(np.abs(acc).max(axis=1, initial=0.0) > RANGE_MARGIN * self.acc_range)
                    & ~(np.abs(gyr).max(axis=1, initial=0.0) > RANGE_MARGIN * self.gyr_range))
        step_ns = np.diff(stamps)
        ordinary[1:] &= (step_ns > 0) & (step_ns <= self.sequencer._max_jump_ns)
        breaks = np.flatnonzero(~ordinary)
        next_break = np.append(breaks, n)[np.searchsorted(breaks, np.arange(n))]  # the first at or after
        t = np.array([s / NS_PER_S for s in stamp_list])
        mag_t = [s / NS_PER_S for s in mag_stamps]
        mag_ok = (np.isfinite(mag_values).all(axis=1) if n_mag else np.zeros(0, bool)).tolist()
        parts: list[OrientationBatch] = []
        calls: list[int] = []
        samples: list[OrientationSample] = []
        notices: list[tuple[int, list[Notice]]] = []
        added = 0
        i = 0
        while i < n:
            run = self._steady_run(i, stamps, t, ordinary, next_break, gyr, acc, mag_before, mag_t, mag_list,
                                   mag_ok, added)
            if run is not None:
                if samples:
                    parts.append(OrientationBatch.of(calls, samples))
                    calls, samples = [], []
                batch, i, added = run
                parts.append(batch)
                continue
            for k in range(added, int(mag_before[i])):
                self.add_mag(mag_stamps[k], mag_list[k])
            added = max(added, int(mag_before[i]))
            out = self.update(stamp_list[i], g_rows[i], a_rows[i])
            calls += [i] * len(out)
            samples += out
            if self.notices:
                notices.append((i, self.notices.pop()))
            i += 1
        for k in range(added, n_mag):
            self.add_mag(mag_stamps[k], mag_list[k])
        parts.append(OrientationBatch.of(calls, samples))
        batch = OrientationBatch.concat(parts)
        batch.notices = notices
        return batch

    def _steady_run(self, i: int, stamps: np.ndarray, t: np.ndarray, ordinary: np.ndarray,
                    next_break: np.ndarray, gyr: np.ndarray, acc: np.ndarray, mag_before: np.ndarray,
                    mag_t: list[float], mag_list: list, mag_ok: list[bool],
                    added: int) -> tuple[OrientationBatch, int, int] | None:
        """The ordinary samples from ``i`` on through the filter as arrays, the stream's state brought to
        where :meth:`update` of each would leave it: (what they released, the next index, magnetometer
        samples given); None when the stream is not steady at ``i`` or the run is short (then
        :meth:`update` takes sample ``i``)."""
        seq = self.sequencer
        if (self._startup is not None or self._recover is not None or self._t_last is None
                or self._last_q is None or seq._jumped or seq._newest_ns is None
                or self.rate.measured_hz is None or not ordinary[i]
                or not 0 < int(stamps[i]) - seq._newest_ns <= seq._max_jump_ns
                or any(p[3] or p[4] for p in seq._pending)):
            return None
        end = min(int(next_break[i]), i + MAX_RUN)
        # the released stamps: what the window held, then the run's; each checked against the one before
        held = [p[0] for p in seq._pending]
        t_all = np.concatenate([[self._t_last], [h / NS_PER_S for h in held], t[i:end]])
        dt = np.diff(t_all)
        rate = self.rate_hz
        bad = ~(dt > 0.0) | (dt > max(self.max_gap_s, 3.0 / rate)) | (dt * rate > HOLE)
        first_bad = np.flatnonzero(bad)
        if len(first_bad):
            if first_bad[0] < len(held):
                return None
            end = i + int(first_bad[0]) - len(held)
        if end - i < MIN_RUN:
            return None
        run_ns = stamps[i:end]
        window = seq._window_ns
        all_ns = np.concatenate([np.array(held, dtype=np.int64), run_ns])
        call = np.searchsorted(run_ns, all_ns + window, side="left")  # the run's index that releases it
        released = int(np.searchsorted(call, end - i, side="left"))
        call = call[:released] + i
        # the magnetometer each released sample pairs with (:meth:`_mag_for` at its release)
        mag_end = int(mag_before[end - 1])
        prior = list(self._mag)
        new = [k for k in range(max(added, 0), mag_end) if mag_ok[k]]
        mag_times = np.array([p[0] for p in prior] + [mag_t[k] for k in new])
        if len(mag_times) > 1 and np.any(np.diff(mag_times) < 0):
            return None
        new_before = np.searchsorted(np.array(new, dtype=np.int64), mag_before[call], side="left")
        count = len(prior) + new_before  # the deque's length at each release, before its maxlen
        newest = t_all[1:released + 1] - self.mag_delay
        idx = np.minimum(np.searchsorted(mag_times, newest, side="right") - 1, count - 1)
        have = (idx >= np.maximum(count - self._mag.maxlen, 0)) & (idx >= 0)
        idx = np.where(have, idx, 0)
        if len(mag_times):
            have &= newest - mag_times[idx] <= self.mag_max_age_s
            mag_rows = np.array([p[1] for p in prior] + [mag_list[k] for k in new]).reshape(-1, 3)[idx]
        else:
            mag_rows = np.zeros((released, 3))
        mag_rows[~have] = 0.0
        # the filter over the released samples
        held_g = [p[2][0] for p in seq._pending]
        held_a = [p[2][1] for p in seq._pending]
        g = np.concatenate([np.array(held_g).reshape(-1, 3), gyr[i:end]])
        a = np.concatenate([np.array(held_a).reshape(-1, 3), acc[i:end]])
        q, bias = self.filter.update_batch(g[:released], a[:released], mag_rows, have, dt[:released])
        # the state as update() leaves it
        run_stamps = run_ns.tolist()
        g_rows, a_rows = gyr[i:end].tolist(), acc[i:end].tolist()
        self.counts["samples"] += end - i
        self.counts["published"] += released
        arrivals = seq._arrivals
        pending = seq._pending[released:] if released < len(held) else []
        pending += [(s, arrivals + 1 + k, (tuple(g_rows[k]), tuple(a_rows[k])), 0.0, 0.0)
                    for k, s in enumerate(run_stamps) if k + len(held) >= released]
        seq._pending = pending
        seq._arrivals = arrivals + end - i
        seq._newest_ns = run_stamps[-1]
        if released:
            out_ns = all_ns[:released].tolist()
            previous = seq._released_ns
            intervals = [s - p for s, p in zip(out_ns, [previous, *out_ns[:-1]], strict=True)]
            seq._intervals.extend(intervals if previous is not None else intervals[1:])
            seq._jump_threshold = None
            seq._released_ns = out_ns[-1]
            self._t_last = float(t_all[released])
            self._last_ga = (tuple(g[released - 1].tolist()), tuple(a[released - 1].tolist()))
            self._last_q = q[-1].copy()
            self.rate._last_ns = out_ns[-1]
        for k in new:
            self._mag.append((mag_t[k], tuple(mag_list[k])))
        self.counts["mag_samples"] += len(new)
        batch = OrientationBatch(call, all_ns[:released], q, g[:released] - bias, a[:released],
                                 np.zeros(released, bool), have, [])
        return batch, end, max(added, mag_end)

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
