"""One foot's trajectory and spatial strides, live (:class:`FootTrajectoryStream`) and offline
(:func:`estimate_foot_trajectory`): zero-velocity detection (Suh Eq 4), the error-state Kalman filter
(Suh §3), and a smoother (Suh §4 or RTS).

Live, per stride: the filter runs ``h`` samples (half the window: 25 ms) behind the sensor, the
look-ahead of the zero-velocity detector. A stride closes once the next stance has lasted
``close_after_s`` s. Its window, from the first stance's start to that sample, is then smoothed by
RTS (:func:`.smoother.rts_smooth`) and its parameters computed (:mod:`.strides`). The latency is
``h`` + ``close_after_s`` after foot flat: 75 ms by default. A stance found by the valley rule (running:
:class:`~.zero_velocity.StanceDetector`) is decided ``valley_gap_s`` (0.45 s) after its sample instead.

Start: the filter starts at the first stance. Its vertical is the mean acceleration of that stance's
first ``bias_rest_s`` s, or of the whole stance when it is shorter. When the stance lasts that long, the
mean gyro over it is the gyro bias prior (Suh §4.4: "b_g,init from the sensor at rest"). Samples before
the first stance have no position (NaN offline).

Memory: the window holds one stride; a standing stance keeps its last ``KEEP_STANDING_S`` s (3 s), so
a live stride after standing reports that as its ``stance_start`` (offline: the whole standing).

Bad input: a non-finite sample is skipped and counted; a stamp going back, or a gap over ``max_gap_s``
s, restarts the foot at its next stance (counted in :attr:`FootTrajectoryStream.counts`, said in
:attr:`FootTrajectoryStream.notices`). A shorter
gap (lost samples: a radio, a loaded DDS queue) is filled by linear interpolation of gyro and
acceleration at the sample rate, so that the filter and the detector windows keep their step, and
counted (``interpolated``). Interpolation only halves the error: on the simulator's walk at 100 Hz one
lost sample moves the stride length by up to 4.2 cm interpolated (8.2 cm held), two by 12 cm, worst
at heel strike and push-off; a 80 ms gap in a stance leaves an attitude error that costs the next
stride up to 8 cm. Hence, per stride (``_judge_lost``):

- more than ``max_swing_lost_s`` s lost in its swing (from the last zero-velocity sample of the first
  stance to the first of the next, widened by the detector's look-ahead): NaN values and a flag;
- a gap longer than ``max_stance_gap_s`` s in its window or in the previous stride's: NaN and a flag;
- fewer lost samples: the values, with the informational flag ``lost samples interpolated``.

With 1 % of the samples lost at random (100 Hz), 27 % of the strides get no values and the others
are within 4.1 cm of the lossless ones (0.8 cm p95); at 200 Hz 28 % and 0.7 cm
(``benchmarks/spatial.py --lost-samples``).

A swing longer than ``max_swing_s`` s (no stance seen: running, a sensor off the foot, a shuffle) gives a
stride with NaN values and a flag, never a number integrated over seconds.

Kernels and array function (issue 46): the detector's and the filter's per-sample arithmetic are
compiled kernels (:mod:`._zero_velocity_kernel`, :mod:`._kalman_kernel`) that
:meth:`FootTrajectoryStream.update` calls once per sample, and :meth:`FootTrajectoryStream.update_batch`
runs over whole arrays wherever the stream's control logic does not act, with the same outputs bit for
bit (``test/test_foot_kernel.py``).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace

import numpy as np

from gait_biofeedback.core.calibration.windows import runs
from gait_biofeedback.core.notices import Notices
from gait_biofeedback.core.params import as_mapping, from_mapping, param, require
from gait_biofeedback.core.spatial.kalman import FootKalman, KalmanNoise
from gait_biofeedback.core.spatial.kalman import kernels as kalman_kernels
from gait_biofeedback.core.spatial.provisional import (
    SWING_TOLERANCES,
    ProvisionalStride,
    RestOfSwing,
    SwingAgreement,
)
from gait_biofeedback.core.spatial.smoother import apply, rts_smooth, suh_smooth
from gait_biofeedback.core.spatial.strides import (
    LOST_FLAG,
    MAX_STANCE_S,
    SpatialStride,
    stride_parameters,
    swing_so_far,
    unknown,
)
from gait_biofeedback.core.spatial.zero_velocity import (
    ADAPTIVE_SCALE,
    ADAPTIVE_SHOE_WINDOW_S,
    ADAPTIVE_WINDOW_S,
    DETECTORS,
    SHOE_ACC,
    SHOE_GYRO,
    VALLEY_GAP_S,
    VALLEY_MAX,
    VALLEY_SWING,
    StanceDetector,
    window_half,
)
from gait_biofeedback.core.stamps import NS_PER_S, lost_between

SMOOTHERS = ("suh", "rts", "none")
KEEP_STANDING_S = 2 * MAX_STANCE_S  # s of a standing stance kept live (still "standing" for the next stride)
MIN_RUN = 16  # rows: a shorter run of ordinary samples goes through update() (the arrays' overhead)
MAX_RUN = 2048  # rows per compiled run: the filter's steps of a run are views of one block of arrays


@dataclass(frozen=True)
class FootTrajectoryParams:
    """Parameters of the foot-trajectory stage (Suh 2014 Table 1 where it gives them)."""

    detector: str = param("suh", "zero-velocity detector: suh (Suh Eq 4) or shoe (Skog 2010)",
                          choices=DETECTORS)
    gyro_limit: float = param(0.4, "suh: largest gyro norm in the window (Suh B_g: 0.2)", "rad/s",
                              low=0.01, high=5.0)
    jerk_limit: float = param(150.0, "suh: largest change of acceleration per second (Suh B_a: 0.4 m/s² per "
                              "10 ms = 40 m/s³)", "m/s^3", low=1.0, high=1000.0)
    window_s: float = param(0.05, "zero velocity: centred window (Suh: 10 samples at 100 Hz = 0.1 s); half "
                            "of it is the look-ahead", "s", low=0.01, high=0.5)
    shoe_acc: float = param(SHOE_ACC, "shoe: scale of |a - g| in the statistic", "m/s^2", low=0.01, high=20.0)
    shoe_gyro: float = param(SHOE_GYRO, "shoe: scale of |ω| in the statistic", "rad/s", low=0.01, high=10.0)
    valley: bool = param(True, "one stance per gait cycle where the thresholds find none: the foot's "
                         "stillest moment after a swing (running; zero_velocity.py)")
    valley_max: float = param(VALLEY_MAX, "valley: largest statistic (|ω| with |a - g| / 6 per rad/s) taken "
                              "as a stance", "rad/s", low=0.1, high=5.0)
    valley_swing: float = param(VALLEY_SWING, "valley: the statistic in the 0.3 s before it (a swing)",
                                "rad/s", low=0.5, high=20.0)
    valley_gap_s: float = param(VALLEY_GAP_S, "valley: no stance of the thresholds this close; an accepted "
                                "valley is decided this late", "s", low=0.1, high=1.0)
    adaptive_scale: float = param(ADAPTIVE_SCALE, "gait-scaled stance test (zero_velocity.py): SHOE's gyro "
                                  "scale per m/s² of the past adaptive_window_s's 90th percentile of "
                                  "| |a| - g |; a stance must pass it too; 0: off (chosen by "
                                  "cross-validation over pyshoe_vicon's sessions)", "rad/s per m/s^2",
                                  low=0.0, high=1.0)
    adaptive_window_s: float = param(ADAPTIVE_WINDOW_S, "gait-scaled stance test: the past its acceleration "
                                     "percentile is taken over (causal, live and offline)", "s", low=1.0,
                                     high=120.0)
    flat_floor: bool = param(True, "every stance at height 0 (Suh Eq 14): level ground only, turn off on "
                             "stairs and ramps")
    gyro_noise: float = param(1e-5, "gyro white-noise density R_g (Suh Table 1: 1e-3, far above a MEMS "
                              "gyro's; docs/benchmarks/spatial.md)", "rad^2/s", low=1e-9, high=1.0)
    acc_noise: float = param(1e-2, "accelerometer white-noise density R_a (Suh Table 1)", "m^2/s^3",
                             low=1e-9, high=10.0)
    acc_shock: float = param(30.0, "a specific force this far off gravity is a shock (heel strike): the "
                             "accelerometer's noise density grows with the excess (kalman.py)", "m/s^2",
                             low=1.0, high=1000.0)
    shock_stance_s: float = param(0.05, "EXT: the shock noise only in a swing after a stance at least this "
                                  "long (not in running; kalman.py)", "s", low=0.0, high=10.0)
    bias_rest_s: float = param(1.0, "a first stance at least this long gives the gyro bias prior", "s",
                               low=0.1, high=120.0)
    close_after_s: float = param(0.05, "a stride closes once the next stance has lasted this long", "s",
                                 low=0.02, high=1.0)
    min_swing_s: float = param(0.2, "zero velocity resumed sooner than this is the same stance (a stance "
                               "that flickers is not two strides)", "s", low=0.0, high=1.0)
    max_swing_s: float = param(2.5, "a longer time without stance gives no spatial values", "s",
                               low=0.5, high=10.0)
    max_gap_s: float = param(0.2, "a longer stamp gap restarts the foot at its next stance", "s",
                             low=0.01, high=10.0)
    max_swing_lost_s: float = param(0.01, "more lost (interpolated) time in a swing gives no spatial values",
                                    "s", low=0.0, high=0.2)
    max_stance_gap_s: float = param(0.035, "a longer stamp gap gives no spatial values to the stride it is "
                                    "in and to the next", "s", low=0.0, high=0.2)
    toe_lever_arm_m: tuple[float, ...] = param((), "toe position in the sensor frame, for the toe clearance "
                                               "(empty: unknown)", "m")
    provisional_tolerance_m: float = param(0.05, "EXT: provisional stride lengths are published only while "
                                           "they differed from the smoothed ones by at most this (RMS of the "
                                           "foot's last 5, at least 3; core/spatial/provisional.py)", "m",
                                           low=0.0, high=1.0)
    smoother: str = param("suh", "offline smoother over the whole recording (live strides use rts)",
                          choices=SMOOTHERS)

    def __post_init__(self) -> None:
        require(len(self.toe_lever_arm_m) in (0, 3), "toe_lever_arm_m: 3 numbers (x, y, z in m) or empty")

    @property
    def noise(self) -> KalmanNoise:
        return KalmanNoise(gyro=self.gyro_noise, acc=self.acc_noise, acc_shock=self.acc_shock,
                           shock_stance_s=self.shock_stance_s)


class FootTrajectoryStream:
    """One foot. ``update(stamp_ns, gyr, acc)`` returns the strides that closed (0 or 1)."""

    def __init__(self, rate_hz: float, params: FootTrajectoryParams | None = None,
                 keep_all: bool = False) -> None:
        self.rate_hz = float(rate_hz)
        self.params = params or FootTrajectoryParams()
        self.keep_all = keep_all
        kalman_kernels()  # compiled now, not in the middle of a live session at the first stance
        self.counts = {"samples": 0, "skipped": 0, "restarts": 0, "interpolated": 0, "strides": 0}
        self.notices = Notices()
        self.index: list[int] = []  # input sample number of each filter step, -1 if filled (keep_all)
        self.kept: list = []  # every filter step (keep_all)
        self._min_swing_ns = self.params.min_swing_s * NS_PER_S
        self._keep = round(KEEP_STANDING_S * self.rate_hz)
        self._margin = window_half(self.rate_hz, self.params.window_s)  # the detector's look-ahead
        if self.params.adaptive_scale:
            self._margin = max(self._margin, window_half(self.rate_hz, ADAPTIVE_SHOE_WINDOW_S))
        self.rest_of_swing = RestOfSwing(self.params.provisional_tolerance_m)
        self.swing_agreement = SwingAgreement()
        self._restart()

    def _restart(self) -> None:
        p = self.params
        self._zv = StanceDetector(self.rate_hz, p.gyro_limit, p.jerk_limit, p.window_s, p.detector,
                                  p.shoe_acc, p.shoe_gyro, p.valley, p.valley_max, p.valley_swing,
                                  p.valley_gap_s, p.adaptive_scale, p.adaptive_window_s)
        self._pending: list[tuple[int, int, np.ndarray, np.ndarray]] = []  # waiting for their decision
        self._rest: list[tuple[int, int, np.ndarray, np.ndarray]] = []  # the first stance, before start
        self._kf: FootKalman | None = None
        self._steps: list = []
        self._stamps: list[int] = []
        self._numbers: list[int] = []
        self._filled: list[bool] = []  # per step: interpolated over lost samples
        self._long_gaps: list[tuple[int, int]] = []  # (last sample before, first after) of gaps, ns
        self._window_ns: int | None = None  # where the last closed stride's window began
        self._in_stance = False
        self._stance_start = 0  # position in the window
        self._previous: tuple[int, int] | None = None  # last completed stance, positions in the window
        self._ended: int | None = None  # last zero-velocity sample of a stance that may resume
        self._closed = False
        self._last_ns: int | None = None
        self._last: tuple[np.ndarray, np.ndarray] | None = None
        self.rest_of_swing.forget_request()
        self.swing_agreement.forget()

    def update(self, stamp_ns: int, gyr: np.ndarray, acc: np.ndarray) -> list[SpatialStride]:
        number = self.counts["samples"]
        self.counts["samples"] += 1
        gyr, acc = np.asarray(gyr, float), np.asarray(acc, float)
        if not math.isfinite(sum(gyr.ravel().tolist()) + sum(acc.ravel().tolist())) and not (
                np.all(np.isfinite(gyr)) and np.all(np.isfinite(acc))):
            self.counts["skipped"] += 1
            return []
        if self._last_ns is not None and not 0 < stamp_ns - self._last_ns <= self.params.max_gap_s * NS_PER_S:
            gap = (stamp_ns - self._last_ns) / NS_PER_S
            self.counts["restarts"] += 1
            why = "went back" if gap <= 0 else f"gap {gap:.2f} s"
            self.notices.say("warn", f"foot trajectory restarted at its next stance: stamp {why}")
            self._restart()
        out = self._fill(number - 1, stamp_ns, gyr, acc) if self._last_ns is not None else []
        self._last_ns, self._last = stamp_ns, (gyr, acc)
        return out + self._feed((number, stamp_ns, gyr, acc, False))

    def update_batch(self, stamps_ns: np.ndarray, gyr: np.ndarray,
                     acc: np.ndarray) -> list[tuple[int, SpatialStride]]:
        """:meth:`update` of each row (stamps int ns (n,), gyro, acc (n, 3)), as the stream's array
        function (vqf's ``updateBatch``): the strides that closed, each with the index of the row whose
        :meth:`update` returned it, the counts, notices and state equal to :meth:`update`'s. Runs of
        ordinary rows (finite, each stamp 0 < step <= ``max_gap_s`` after the one before, no sample lost
        between) go through the compiled kernels as arrays (:meth:`_steady_run`): the detector's, then
        the filter's over the samples it decided; the stance and stride bookkeeping per decided sample
        and the closing of strides stay Python. The other rows go through :meth:`update`."""
        stamps = np.asarray(stamps_ns, np.int64)
        gyr, acc = np.asarray(gyr, float), np.asarray(acc, float)
        n = len(stamps)
        require(gyr.shape == acc.shape == (n, 3), "update_batch: stamps (n,), gyr and acc (n, 3)")
        finite = np.isfinite(gyr).all(axis=1) & np.isfinite(acc).all(axis=1)
        steady = np.zeros(n, bool)  # row k follows row k - 1 as an ordinary sample
        if n > 1:
            gap = np.diff(stamps)
            steady[1:] = (finite[1:] & finite[:-1] & (gap > 0) & (gap <= self.params.max_gap_s * NS_PER_S)
                          & (np.round(gap * self.rate_hz / NS_PER_S) <= 1))
        breaks = np.append(np.flatnonzero(~steady), n)
        out: list[tuple[int, SpatialStride]] = []
        i = 0
        while i < n:
            end = min(int(breaks[np.searchsorted(breaks, i, side="right")]), i + MAX_RUN)
            if end - i >= MIN_RUN and finite[i] and self._ordinary(int(stamps[i])):
                out += self._steady_run(i, stamps[i:end].tolist(), gyr[i:end], acc[i:end])
                i = end
                continue
            out += [(i, stride) for stride in self.update(int(stamps[i]), gyr[i], acc[i])]
            i += 1
        return out

    def _ordinary(self, stamp_ns: int) -> bool:
        """A finite sample at ``stamp_ns`` would be an ordinary one: no restart, no lost sample."""
        if self._last_ns is None:
            return False
        gap = stamp_ns - self._last_ns
        return 0 < gap <= self.params.max_gap_s * NS_PER_S and not lost_between(self._last_ns, stamp_ns,
                                                                                   self.rate_hz)

    def _steady_run(self, first: int, stamps: list[int], gyr: np.ndarray,
                    acc: np.ndarray) -> list[tuple[int, SpatialStride]]:
        """Rows ``first`` on, ordinary samples (:meth:`update_batch`), through the compiled kernels."""
        m = len(stamps)
        number0 = self.counts["samples"]
        self.counts["samples"] += m
        decisions, released = self._zv.update_batch(gyr, acc)
        release_at = np.repeat(np.arange(first, first + m), released).tolist()
        self._last_ns, self._last = stamps[-1], (gyr[-1].copy(), acc[-1].copy())
        held = self._pending
        decided = len(decisions)
        run = [(number0 + k, stamps[k], gyr[k], acc[k], False) for k in range(max(0, decided - len(held)))]
        samples = held[:decided] + run
        self._pending = held[decided:] + [(number0 + k, stamps[k], gyr[k], acc[k], False)
                                          for k in range(len(run), m)]
        zv = decisions.tolist()
        out: list[tuple[int, SpatialStride]] = []
        j = 0
        while j < decided and self._kf is None:
            out += [(release_at[j], stride) for stride in self._decided(samples[j], zv[j])]
            j += 1
        if j == decided:
            return out
        rest = samples[j:]
        previous = [self._stamps[-1]] + [sample[1] for sample in rest[:-1]]
        dt = [(sample[1] - before) / NS_PER_S for sample, before in zip(rest, previous, strict=True)]
        steps = self._kf.update_batch(np.array([sample[2] for sample in rest]),
                                      np.array([sample[3] for sample in rest]), np.array(dt), decisions[j:])
        for sample, step, zero_velocity, at in zip(rest, steps, zv[j:], release_at[j:], strict=True):
            self._record(sample[0], sample[1], sample[4], step)
            out += [(at, stride) for stride in self._advance(zero_velocity)]
        return out

    def _fill(self, number: int, stamp_ns: int, gyr: np.ndarray, acc: np.ndarray) -> list[SpatialStride]:
        """Linearly interpolated samples for the ones lost after the sample ``number`` (reported as
        theirs) and before this one."""
        lost = lost_between(self._last_ns, stamp_ns, self.rate_hz)
        out: list[SpatialStride] = []
        if not lost:
            return out
        self.counts["interpolated"] += len(lost)
        if (len(lost) + 1) / self.rate_hz > self.params.max_stance_gap_s + 1e-9:
            self._long_gaps.append((self._last_ns, stamp_ns))
        gyr0, acc0 = self._last
        for lost_ns, f in lost:
            out += self._feed((number, lost_ns, gyr0 + f * (gyr - gyr0), acc0 + f * (acc - acc0), True))
        return out

    def _feed(self, sample: tuple) -> list[SpatialStride]:
        self._pending.append(sample)
        out: list[SpatialStride] = []
        for decision in self._zv.update(sample[2], sample[3]):
            out += self._decided(self._pending.pop(0), decision)
        return out

    def flush(self) -> list[SpatialStride]:
        """The last samples' decisions at the end of the data."""
        out: list[SpatialStride] = []
        for decision in self._zv.flush():
            out += self._decided(self._pending.pop(0), decision)
        if self._kf is None and self._rest:
            out += self._start()
        return out

    def _decided(self, sample, zero_velocity: bool) -> list[SpatialStride]:
        if self._kf is None:
            if zero_velocity:
                self._rest.append(sample)
                if len(self._rest) * 1.0 / self.rate_hz >= self.params.bias_rest_s:
                    return self._start()
            elif self._rest:
                return self._start(then=(sample, False))
            return []
        return self._step(sample, zero_velocity)

    def _start(self, then=None) -> list[SpatialStride]:
        rest = self._rest
        self._rest = []
        acc = np.mean([s[3] for s in rest], axis=0)
        long_enough = len(rest) / self.rate_hz >= self.params.bias_rest_s
        bias = np.concatenate([np.mean([s[2] for s in rest], axis=0), np.zeros(3)]) if long_enough else None
        self._kf = FootKalman(self.params.noise, self.params.flat_floor, keep=False)
        number, ns, gyr, acc0, filled = rest[0]
        self._record(number, ns, filled, self._kf.start(acc, gyr, acc0, True, bias))
        self._in_stance, self._stance_start, self._closed = True, 0, False
        out: list[SpatialStride] = []
        for sample in rest[1:]:
            out += self._step(sample, True)
        if then is not None:
            out += self._step(*then)
        return out

    def _record(self, number: int, ns: int, filled: bool, step) -> None:
        self._steps.append(step)
        self._stamps.append(ns)
        self._numbers.append(number)
        self._filled.append(filled)
        if self.keep_all:
            self.kept.append(step)
            self.index.append(-1 if filled else number)

    def _step(self, sample, zero_velocity: bool) -> list[SpatialStride]:
        number, ns, gyr, acc, filled = sample
        dt = (ns - self._stamps[-1]) / NS_PER_S
        self._record(number, ns, filled, self._kf.update(gyr, acc, dt, zero_velocity))
        return self._advance(zero_velocity)

    def _advance(self, zero_velocity: bool) -> list[SpatialStride]:
        """The stance and stride bookkeeping of the step just recorded: the strides it closed."""
        k = len(self._steps) - 1
        out: list[SpatialStride] = []
        if zero_velocity:
            if not self._in_stance and self._ended is None:
                self._stance_start, self._closed = k, False
            self._in_stance, self._ended = True, None
            if (not self._closed and self._previous is not None
                    and (k - self._stance_start + 1) / self.rate_hz >= self.params.close_after_s):
                out.append(self._close(k))
            if (self._closed or self._previous is None) and k - self._stance_start + 1 > self._keep:
                self._cut(k + 1 - self._keep)  # standing: its older samples are no longer needed
            return out
        if self._in_stance:
            self._in_stance, self._ended = False, k - 1
        if self._ended is not None and self._stamps[k] - self._stamps[self._ended] >= self._min_swing_ns:
            if not self._closed and self._previous is not None:
                out.append(self._close(self._ended))
            self._previous, self._ended = (self._stance_start, self._ended), None
            self._trim()
        return out

    def provisional(self) -> ProvisionalStride | None:
        """The stride in progress before it closes (:mod:`.provisional`): its stride length, in its
        swing the forward filter's travel plus the foot's usual rest of the swing, in its next stance
        the travel to that stance; its swing values (foot height, toe clearance, foot and turning
        angles, lateral excursion) from the forward filter (:func:`~.strides.swing_so_far`). None
        before the filter started, between stances less than ``min_swing_s`` apart, once the stride has
        closed (its smoothed values are out), after lost samples in the stride, while the foot's rests
        are not learnt, or while its length estimates are not trusted
        (:class:`.provisional.RestOfSwing`, ``provisional_tolerance_m``)."""
        if self._kf is None or self._previous is None or self._ended is not None:
            return None
        stopped = self._in_stance
        if stopped and self._closed:
            return None
        (a0, a1), since = self._previous, self._stamps[self._previous[0]]
        if any(self._filled[a0:]) or any(b > since for _, b in self._long_gaps):
            return None
        start = np.mean([step.r for step in self._steps[a0:a1 + 1]], axis=0)
        if stopped:
            now = np.mean([step.r for step in self._steps[self._stance_start:]], axis=0)
            length = float(np.hypot(*(now - start)[:2]))
        else:
            length = self.rest_of_swing.estimate(self._stamps[a1], start, self._steps[-1].r)
        if length is None or (length := self.rest_of_swing.offer(self._stamps[a1], length)) is None:
            return None
        end = self._stance_start + 1 if stopped else len(self._steps)
        swing = swing_so_far(np.array([step.q for step in self._steps[a0:end]]),
                             np.array([step.r for step in self._steps[a0:end]]), (0, a1 - a0),
                             self.params.toe_lever_arm_m or None)
        return self.swing_agreement.offer(ProvisionalStride(self._stamps[a1], length, **swing))

    def _close(self, last: int) -> SpatialStride:
        self._closed = True
        a0 = self._previous[0]
        stance = self._steps[self._stance_start:last + 1]
        self.rest_of_swing.learn(self._stamps[self._previous[1]], np.mean([s.r for s in stance], axis=0))
        window = self._steps[a0:last + 1]
        smooth = rts_smooth(window)
        t = np.array(self._stamps[a0:last + 1], dtype=float) / NS_PER_S
        first = (0, self._previous[1] - a0)
        second = (self._stance_start - a0, last - a0)
        stride = stride_parameters(t, smooth["orientation"], smooth["position"], first, second,
                                   self._numbers[a0:last + 1], self.params.toe_lever_arm_m or None,
                                   self.params.max_swing_s)
        stride = self._judge_lost(stride, a0, last)
        self.rest_of_swing.check(self._stamps[self._previous[1]], stride.stride_length)
        self.swing_agreement.check(self._stamps[self._previous[1]],
                                   {name: getattr(stride, name) for name in SWING_TOLERANCES})
        self.counts["strides"] += 1
        return replace(stride, foot_off_ns=self._stamps[self._previous[1]],
                       foot_flat_ns=self._stamps[self._stance_start])

    def _judge_lost(self, stride: SpatialStride, a0: int, last: int) -> SpatialStride:
        """NaN values when samples were lost in the swing, or a long gap came in this stride or the one
        before (its attitude error outlasts the stance's zero-velocity update; module docstring)."""
        start_ns, end_ns = self._stamps[a0], self._stamps[last]
        since = start_ns if self._window_ns is None else self._window_ns
        self._window_ns = start_ns
        hit = [(a, b) for a, b in self._long_gaps if a < end_ns and b > since]
        self._long_gaps = [(a, b) for a, b in self._long_gaps if b > start_ns]
        if hit:
            gap_s = max(b - a for a, b in hit) / NS_PER_S
            return unknown(stride, f"a {gap_s * 1e3:.0f} ms gap in the data: spatial values unknown")
        if not any(self._filled[a0:last + 1]):
            return stride
        swing = self._filled[max(0, self._previous[1] - self._margin):self._stance_start + self._margin + 1]
        lost_s = sum(swing) / self.rate_hz
        if lost_s > self.params.max_swing_lost_s + 1e-9:
            return unknown(stride, f"{lost_s * 1e3:.0f} ms of lost samples in the swing: "
                           "spatial values unknown")
        return replace(stride, flags=(*stride.flags, LOST_FLAG))

    def _trim(self) -> None:
        """Drop the steps before the last completed stance (the next stride's start)."""
        self._cut(self._previous[0])
        self._previous = (0, self._previous[1] - self._previous[0])

    def _cut(self, cut: int) -> None:
        if cut > 0:
            del self._steps[:cut], self._stamps[:cut], self._numbers[:cut], self._filled[:cut]
            self._stance_start = max(0, self._stance_start - cut)  # a standing stance starts at the cut


def estimate_foot_trajectory(gyr: np.ndarray, acc: np.ndarray, rate_hz: float,
                             params: FootTrajectoryParams | None = None, **options) -> dict:
    """Trajectory of one foot IMU over a whole recording (gait.md §4).

    ``gyr`` rad/s and ``acc`` m/s² (N, 3), sensor frame, at ``rate_hz``. ``options`` override
    :class:`FootTrajectoryParams` fields (e.g. ``smoother="rts"``, ``flat_floor=False``).

    Returns a dict:

    - ``position`` (N, 3) m and ``velocity`` (N, 3) m/s, in the world frame: z up, heading that of
      the first stance, origin at the first tracked sample. Samples before the first stance are NaN.
    - ``orientation`` (N, 4) and ``zero_velocity`` (N,) bool.
    - ``strides``: the :class:`.strides.SpatialStride` of each stride, as dicts. They are computed
      from the whole-recording smoother (``smoother``), so they can differ slightly from the live
      per-stride values.
    - ``live_strides``: what :class:`FootTrajectoryStream` emitted, stride by stride.
    """
    p = params or FootTrajectoryParams()
    if options:  # checked as a params file is: a typo or a value out of range is refused by name
        p = from_mapping(FootTrajectoryParams, {**as_mapping(p), **options}, "estimate_foot_trajectory")
    gyr, acc = np.asarray(gyr, float), np.asarray(acc, float)
    require(gyr.shape == acc.shape and gyr.ndim == 2 and gyr.shape[1] == 3, "gyr and acc: (N, 3) each")
    stream = FootTrajectoryStream(rate_hz, p, keep_all=True)
    period_ns = NS_PER_S / rate_hz
    stamps = np.array([round(k * period_ns) for k in range(len(gyr))], np.int64)
    live = [stride for _, stride in stream.update_batch(stamps, gyr, acc)]
    live += stream.flush()
    n = len(gyr)
    out = {name: np.full((n, width), np.nan) for name, width in (("position", 3), ("velocity", 3),
                                                                 ("orientation", 4))}
    zv = np.zeros(n, bool)
    strides: list[SpatialStride] = []
    if stream.kept:
        steps, index = stream.kept, np.array(stream.index)
        real = index >= 0  # (the stamps here are regular: nothing is filled)
        if p.smoother == "none" or stream.counts["restarts"]:
            states = apply(steps, np.zeros((len(steps), 9)))
        elif p.smoother == "rts":
            states = rts_smooth(steps)
        else:
            states = suh_smooth(steps, p.noise, p.flat_floor, bias_prior=steps[0].b)
        states["position"] = states["position"] - states["position"][0]
        states = {name: value[real] for name, value in states.items()}
        index, steps = index[real], [s for s, keep in zip(steps, real, strict=True) if keep]
        for name in ("position", "velocity", "orientation"):
            out[name][index] = states[name]
        zv[index] = [s.zero_velocity for s in steps]
        strides = _strides(index, states, zv[index], rate_hz, p)
    return {**out, "zero_velocity": zv, "strides": [vars(s) for s in strides],
            "live_strides": [vars(s) for s in live]}


def _strides(index: np.ndarray, states: dict, zv: np.ndarray, rate_hz: float,
             p: FootTrajectoryParams) -> list[SpatialStride]:
    t = index / rate_hz
    stances: list[list[int]] = []
    for first, stop in runs(zv):
        # the stream ends a stance at the first moving sample min_swing_s after it: the one before first
        if stances and t[first - 1] - t[stances[-1][1]] < p.min_swing_s - 1e-9:
            stances[-1][1] = stop - 1
        else:
            stances.append([first, stop - 1])
    numbers = index.tolist()
    close = max(1, math.ceil(p.close_after_s * rate_hz - 1e-9))
    return [stride_parameters(t, states["orientation"], states["position"], (a0, a1),
                              (b0, min(b1, b0 + close - 1)), numbers, p.toe_lever_arm_m or None,
                              p.max_swing_s)
            for (a0, a1), (b0, b1) in itertools.pairwise(stances)]
