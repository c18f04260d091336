"""Real-time initial/terminal contact (IC/TC) detection from the foot pitch (thesis ch. 6, Algorithm 1).

Signal (thesis Eq 52, gait.md §2.3): ``s = -sin(beta)`` = element (3,1) of the foot orientation, i.e.
the world-vertical (ENU z) component of the foot's anterior unit axis. In the project's ISB foot frame
(x anterior, y superior, z right) the anterior axis is the segment x-axis, so with the calibrated foot
orientation ``q_segment = q_sensor ⊗ r``: ``s = e_up · R(q_sensor) R(r) e_x``. READING: the thesis'
ch. 6 frame (x forward, z up) maps onto ours by its x-axis alone; no sign flip is needed: s > 0 with
the toes up (IC region), s < 0 toes down (TC region), s = 0 in quiet standing after the vertical
calibration (thesis "correction 1" is then automatic; "correction 2" is a no-op for element (3,1)).

Algorithm 1 (gait.md §2.4–2.6), one detector per foot, state ``flag`` (0 = waiting for TC):
- TC at the confirming sample k: ``k - k_TC > N_refr``, ``s_k < -0.2``, ``s_{k-1}`` is a local minimum;
- IC: a TC since the last IC (the flag), ``k - k_IC > N_refr``, ``s_k > -0.2``, ``s_{k-1}`` local maximum.
Local minimum of ``c = k-1`` (gait.md §2.5): ``s_c < s_{c-i}`` for i = 1..W and ``s_c < s_{c+1}``, and at
least 80 % of the W differences ``s_{c-i} - s_{c-i-1}`` (i = 1..W) are negative; maximum mirrored.

READINGs / choices (documented and tested):
- Rates other than 100 Hz: the sample counts scale with time, ``W = round(0.150 s · rate)`` (15 at
  100 Hz, 30 at 200 Hz, 31 at 204.8 Hz) and ``N_refr = round(0.150 s · rate)`` with the strict ``>`` of
  Algorithm 1 (so exactly Algorithm 1 at 100 Hz: ≥ 160 ms between events of one type); the 80 % rule
  needs ``ceil(0.8 · W)`` decreasing (increasing) differences. The look-ahead stays one sample.
- Start-up: no previous TC/IC counts as −∞ (gait.md §6.2 #18); the first test waits for ``W + 3``
  samples (the 80 % rule of candidate k−1 reaches back to ``s_{k-W-2}``).
- Threshold on the confirming sample ``s_k``, extremum at ``s_{k-1}`` (verbatim Algorithm 1).
- Event time: the extremum sample ``k-1`` (the message stamp); it is emitted when sample k arrives, so
  the detection latency is one sample period (thesis Table 15 compares the detection sample k; the
  benchmark reports both).
- EXT (issue 15): a heel strike whose toe-off was not detected still counts. In Algorithm 1 an IC needs
  a TC since the last IC, so a toe-off shallower than the −0.2 threshold (the first step from standing:
  −0.04…−0.29 on ipol_gait, while its heel strike reaches +0.23…+0.63) lost that step's IC too. While
  waiting for a TC, a local maximum (same trend rule) above ``IC_WITHOUT_TC`` more than
  ``IC_WITHOUT_TC_AFTER_S`` after the last IC is an IC with the flag :data:`MISSED_TC_FLAG`; the
  stride it closes has no TC and is not plausible (no cue from it), the next stride is unaffected.
- EXT: such a heel strike first looks back (``LATE_TC_LOOKBACK_S``, from the last IC's refractory to
  the refractory before this one) for the deepest ``s``; below ``LATE_TC_THRESHOLD`` (toes down, or level
  within the calibration's uncertainty) and not the window's first sample (a foot that only rose since
  then, e.g. from standing, shows no toe-off) it is the toe-off,
  emitted then with :data:`LATE_TC_FLAG` (its stamp is its own sample; detected at the heel strike)
  and the heel strike follows one sample later, unflagged: the stride is whole. On ipol_gait 31 of the
  66 missed toe-offs were the first from standing.

- Lost samples (a radio drops packets: up to 18 % of an ipol_gait trial). Algorithm 1 counts samples,
  so a hole would stretch its windows and refractory periods in time. A stamp gap of 2 to
  ``MAX_FILL_S`` / period sample periods is filled first: the missing samples' ``s`` linearly between
  its two neighbours, at the missing stamps (an event may then carry such a stamp). Longer gaps are
  left as they are (the stream flags a stride with a gap over 0.1 s). On ipol_gait IC Se
  97.9 → 98.0 %, Pr 98.6 → 98.7 % (benchmarks/gait_events.py).

Event times (issue 47; READING of "IC/TC ↔ local maximum/minimum" [T §6.2.2, Fig 23(c)], with the
extremum kept as Algorithm 1's detection and a documented definitional placement of the stamp):
Algorithm 1 finds each event at an extremum of ``s``; the extremum is not the contact itself. The
stamp is placed by the foot pitch's distance from that extremum, ``EVENT_MARGIN`` (m = 0.05, 2.9°):
- TC: the first sample of the run before the minimum that stays within m of it (``s <= s_min + m``), at
  most ``TOE_OFF_SHIFT_MAX_S`` (60 ms) before it: where the toe-down rotation of push-off enters its
  plateau. The stamp lies before the detection (published at the minimum's confirming sample, as
  Algorithm 1; a negative shift of the stamp, causal).
- IC: the first sample after the maximum that is more than m below it (``s <= s_max - m``): where the
  foot, having struck with the heel, starts lowering its forefoot; at most ``HEEL_STRIKE_SHIFT_MAX_S``
  (60 ms) after the maximum (else the last sample within it). It is published when that sample arrives
  (0 to 60 ms after the maximum's confirmation; the stamp is never after the publication).
Two references disagree on the heel strike: ipol_gait's (Voisard et al. 2023: two validated IMU
algorithms, checked by hand; 9 subjects) lies 30-40 ms after the pitch maximum in every subject, motion
capture's (gaitmap_example, one subject) on it (+0 ms); their toe-offs agree. m and both caps were
chosen on ipol_gait subjects 1-5 and confirmed on 6-9 (medians IC 0 / 0, TC 0 / 0 ms; stance within 2
points in 48 of 52 trials; benchmarks/gait_events.py ``--halves``): against motion capture the heel
strike is then +29 ms and stance 2.4 points low (a heel-strike cap of 20 ms keeps both references
within 20 ms, but puts ipol's stance 1-2 points high and its healthy walkers' double support above the
normative band: ``docs/benchmarks/gait_events.md``). ``event_margin = 0`` gives Algorithm 1's extremum stamps.
A pending IC is dropped by :meth:`GaitEventDetector.reset` and given out by :meth:`~GaitEventDetector.flush`.

Samples and events are identified by their stamps (int ns, ``docs/conventions.md``); Algorithm 1 itself
counts samples and never looks at time.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.stamps import NS_PER_S, lost_between, sample_stamps

INITIAL_CONTACT = "ic"
TERMINAL_CONTACT = "tc"
THRESHOLD = -0.2  # -sin(beta) threshold, thesis §6.2.2 (≈ 11.5° toes-down)
REFRACTORY_S = 0.150  # per event type, thesis §6.2.2 / Algorithm 1 ("> 15" samples at 100 Hz)
EXTREMUM_WINDOW_S = 0.150  # 15 previous samples at 100 Hz, thesis §6.2.2
TREND_FRACTION = 0.8  # ≥ 80 % monotone differences, thesis §6.2.2
IC_WITHOUT_TC = 0.15  # -sin(beta), 8.6° toes up: a heel strike that counts without a toe-off before it (EXT)
IC_WITHOUT_TC_AFTER_S = 0.5  # s since the last IC, for such a heel strike
MISSED_TC_FLAG = "no toe-off detected before this heel strike"
LATE_TC_THRESHOLD = 0.03  # -sin(beta): a toe-off taken late may be level within ±1.7° (the vertical
# calibration's uncertainty; a step lifted flat from standing). ipol subjects 1-5, TC Se / Pr: -0.03
# 97.24 / 99.27 %, 0.0 97.45 / 99.17, +0.03 and +0.06 97.65 / 99.17; confirmed on 6-9: 98.49 / 98.86 →
# 98.61 / 98.86 (EXT)
LATE_TC_LOOKBACK_S = 1.5  # how far back from such a heel strike its toe-off is looked for
LATE_TC_FLAG = "toe-off shallower than the threshold, found at the next heel strike"
MAX_FILL_S = 0.1  # s: the longest stamp gap whose missing samples are filled (module docstring)
EVENT_MARGIN = 0.05  # -sin(beta), 2.9°: how far from its extremum the foot pitch places the event (module
# docstring "Event times"); chosen on ipol_gait subjects 1-5 with TOE_OFF_SHIFT_MAX_S
# (benchmarks/gait_events.py --halves, both caps 0.06 s): margin 0.03 / 0.04 / 0.05 / 0.06 → median IC
# -10 / 0 / 0 / 0 ms, TC +10 / 0 / 0 / 0 ms, trials with stance within 2 points 22 / 27 / 27 / 24 of 28,
# double support 12 / 14 / 22 / 19 of 28
TOE_OFF_SHIFT_MAX_S = 0.06  # s: the most a TC is moved before its minimum (0.06 / 0.08 / 0.10 s: 27 / 25 /
# 24 of 28 trials' stance within 2 points at margin 0.05)
HEEL_STRIKE_SHIFT_MAX_S = 0.06  # s: the most an IC is moved after its maximum (and published later). 0 /
# 0.02 / 0.03 / 0.06 s → median IC error ipol 1-5 -40 / -20 / -10 / 0 ms (gaitmap +0 / +19.5 / +29.3 / +29.3);
# ipol 1-5 trials with stance within 2 points 6 / 14 / 22 / 27 of 28


@dataclass(frozen=True)
class GaitEvent:
    """One detected event of one foot. ``stamp_ns``: stamp of the event's sample;
    ``detected_ns``: stamp of the sample that gave it out (module docstring "Event times"); ``signal``:
    the detector's signal at the extremum that gave the event (-sin(beta) for Algorithm 1); ``index``:
    running count of events of this side and type; ``flag``: why the event is doubtful (set by the
    stream), empty otherwise."""

    side: str
    kind: str
    stamp_ns: int
    detected_ns: int
    signal: float
    index: int
    flag: str = ""

    @property
    def t(self) -> float:
        """The event's stamp in seconds."""
        return self.stamp_ns / NS_PER_S

    @property
    def latency(self) -> float:
        """Detection latency, s (thesis: one sample)."""
        return (self.detected_ns - self.stamp_ns) / NS_PER_S


def samples_for(duration_s: float, rate_hz: float) -> int:
    """A duration of thesis Algorithm 1 (stated at 100 Hz) as a sample count at ``rate_hz`` (≥ 1)."""
    return max(1, round(duration_s * rate_hz))


def anterior_axis_in_sensor(mounting: np.ndarray | None) -> tuple[float, float, float]:
    """The foot's anterior (segment x) axis in the sensor frame, ``R(r) e_x``, for the calibration
    rotation ``r`` (segment → sensor, ``q_segment = q_sensor ⊗ r``); identity if ``None``."""
    r = quat.IDENTITY if mounting is None else np.asarray(mounting, dtype=float)
    f = quat.rotate(quat.normalize(r), np.array([1.0, 0.0, 0.0]))
    return float(f[0]), float(f[1]), float(f[2])


def foot_pitch_sine(foot_quat: np.ndarray, mounting: np.ndarray | None = None) -> np.ndarray:
    """``-sin(beta)`` (thesis Eq 52) of sensor orientations (..., 4) with the calibration ``r``: the
    world-vertical component of the foot's anterior axis (see module docstring)."""
    fx, fy, fz = anterior_axis_in_sensor(mounting)
    q = quat.normalize(np.asarray(foot_quat, dtype=float))
    w, x, y, z = np.moveaxis(q, -1, 0)
    # third row of R(q): (2(xz - wy), 2(yz + wx), 1 - 2(x² + y²))
    return 2.0 * (x * z - w * y) * fx + 2.0 * (y * z + w * x) * fy + (1.0 - 2.0 * (x * x + y * y)) * fz


class GaitEventDetector:
    """Streaming thesis Algorithm 1 for one foot (see module docstring); pure-Python floats.

    ``update(stamp_ns, foot_quat)`` takes the foot IMU's orientation (sensor → world, (w, x, y, z)) and
    uses the calibration ``mounting`` r; ``update_signal(stamp_ns, s)`` takes ``-sin(beta)`` directly.
    Both return a :class:`GaitEvent` (for the previous sample) or ``None``.
    """

    def __init__(self, side: str = "left", rate_hz: float = 100.0, mounting: np.ndarray | None = None,
                 threshold: float = THRESHOLD, refractory_s: float = REFRACTORY_S,
                 window_s: float = EXTREMUM_WINDOW_S, trend_fraction: float = TREND_FRACTION,
                 event_margin: float = EVENT_MARGIN, toe_off_shift_max_s: float = TOE_OFF_SHIFT_MAX_S,
                 heel_strike_shift_max_s: float = HEEL_STRIKE_SHIFT_MAX_S) -> None:
        if not rate_hz > 0:
            raise ValueError(f"rate_hz must be > 0, got {rate_hz}")
        self.side = side
        self.threshold = float(threshold)
        self.event_margin = float(event_margin)
        self.toe_off_shift_max_ns = round(float(toe_off_shift_max_s) * NS_PER_S)
        self.heel_strike_shift_max_ns = round(float(heel_strike_shift_max_s) * NS_PER_S)
        self._durations = (float(window_s), float(refractory_s), float(trend_fraction))
        self.set_rate(rate_hz)
        self.set_mounting(mounting)
        self.counts = {INITIAL_CONTACT: 0, TERMINAL_CONTACT: 0}
        self._queued: deque[GaitEvent] = deque()  # events not returned yet: one per update, in order
        self.reset()

    def set_rate(self, rate_hz: float) -> None:
        """Count the windows (stated in seconds) at ``rate_hz``; call :meth:`reset` after a change."""
        window_s, refractory_s, trend_fraction = self._durations
        self.rate_hz = float(rate_hz)
        self.window = samples_for(window_s, rate_hz)
        self.refractory = samples_for(refractory_s, rate_hz)
        self.min_trend = math.ceil(trend_fraction * self.window - 1e-9)
        self._ic_alone = samples_for(IC_WITHOUT_TC_AFTER_S, rate_hz)

    def set_mounting(self, mounting: np.ndarray | None) -> None:
        """Use a new calibration rotation r (segment → sensor)."""
        self._f = anterior_axis_in_sensor(mounting)

    def reset(self) -> None:
        """Forget the signal history and the state (e.g. after a stream gap); counters are kept."""
        self._s: deque[float] = deque(maxlen=self.window + 3)
        self._stamps: deque[int] = deque(maxlen=2)
        self._k = -1
        self._k_tc = -math.inf
        self._k_ic = -math.inf
        self.waiting_for_ic = False  # Algorithm 1 "flag"
        lookback = samples_for(LATE_TC_LOOKBACK_S, self.rate_hz)
        self._recent: deque[tuple[int, int, float]] = deque(maxlen=lookback)  # (k, stamp, s)
        # a heel strike found at its maximum, waiting for its stamp: (maximum's stamp, level, s_max, flag)
        self._pending_ic: tuple[int, float, float, str] | None = None
        # (a queued event is kept: the next update returns it)

    def signal(self, foot_quat: Any) -> float:
        """``-sin(beta)`` of one sensor orientation (w, x, y, z) with the current calibration."""
        w, x, y, z = (float(v) for v in foot_quat)
        n2 = w * w + x * x + y * y + z * z
        fx, fy, fz = self._f
        up_x, up_y, up_z = 2.0 * (x * z - w * y), 2.0 * (y * z + w * x), n2 - 2.0 * (x * x + y * y)
        return (up_x * fx + up_y * fy + up_z * fz) / n2

    def update(self, stamp_ns: int, foot_quat: Any) -> GaitEvent | None:
        """One orientation sample stamped ``stamp_ns`` → the event of the previous sample, if any."""
        return self.update_signal(stamp_ns, self.signal(foot_quat))

    def update_signal(self, stamp_ns: int, s: float) -> GaitEvent | None:
        """One ``-sin(beta)`` sample stamped ``stamp_ns`` → the event of the previous sample, if any (a
        heel strike whose toe-off was found late comes one sample after that toe-off; so does the
        second event of a filled hole)."""
        if self._stamps and stamp_ns - self._stamps[-1] <= MAX_FILL_S * NS_PER_S:
            last_s = self._s[-1]
            for lost_ns, f in lost_between(self._stamps[-1], stamp_ns, self.rate_hz):
                self._step(lost_ns, last_s + f * (s - last_s))
        self._step(stamp_ns, s)
        return self._queued.popleft() if self._queued else None

    def _step(self, stamp_ns: int, s: float) -> None:
        """Algorithm 1 on one sample; its events join the queue."""
        self._queued.extend(self._detect(stamp_ns, s))

    def _detect(self, stamp_ns: int, s: float) -> tuple[GaitEvent, ...]:
        buf = self._s
        last_ns = self._stamps[-1] if self._stamps else stamp_ns
        buf.append(s)
        self._stamps.append(stamp_ns)
        self._k += 1
        k = self._k
        self._recent.append((k, stamp_ns, s))
        settled = self._settle_heel_strike(stamp_ns, s, last_ns)
        if len(buf) < self.window + 3:
            return settled
        prev = buf[-2]
        if not self.waiting_for_ic:
            if k - self._k_tc > self.refractory and s < self.threshold and prev < s and self._is_minimum():
                self._k_tc = k
                self.waiting_for_ic = True
                tc_ns = self._toe_off_stamp(self._stamps[0], prev)
                return (*settled, self._event(TERMINAL_CONTACT, stamp_ns, prev, stamp_ns=tc_ns))
            if (k - self._k_ic > self._ic_alone and s > IC_WITHOUT_TC and prev > s
                    and self._is_maximum()):
                late = self._late_toe_off(k)
                self._k_ic = k
                if late is None:
                    return (*settled, *self._heel_strike(stamp_ns, s, prev, MISSED_TC_FLAG))
                k_tc, tc_ns, value = late
                self._k_tc = k_tc + 1  # as Algorithm 1 counts a TC: at its confirming sample
                toe_off = self._event(TERMINAL_CONTACT, stamp_ns, value, LATE_TC_FLAG,
                                      stamp_ns=self._toe_off_stamp(tc_ns, value))
                return (*settled, toe_off, *self._heel_strike(stamp_ns, s, prev))
        elif k - self._k_ic > self.refractory and s > self.threshold and prev > s and self._is_maximum():
            self._k_ic = k
            self.waiting_for_ic = False
            return (*settled, *self._heel_strike(stamp_ns, s, prev))
        return settled

    def _toe_off_stamp(self, minimum_ns: int, s_min: float) -> int:
        """The stamp of a toe-off whose minimum ``s_min`` is at ``minimum_ns``: the first sample of the run
        before it within ``event_margin`` of it, at most ``toe_off_shift_max_s`` earlier (module
        docstring)."""
        level = s_min + self.event_margin
        stamp = minimum_ns
        for _, sample_ns, sj in reversed(self._recent):
            if sample_ns >= minimum_ns:
                continue
            if sj > level or minimum_ns - sample_ns > self.toe_off_shift_max_ns:
                break
            stamp = sample_ns
        return stamp

    def _heel_strike(self, stamp_ns: int, s: float, s_max: float, flag: str = "") -> tuple[GaitEvent, ...]:
        """The heel strike whose maximum ``s_max`` is the previous sample, confirmed by the sample
        (``stamp_ns``, ``s``): out now if that sample already lies ``event_margin`` below the maximum
        (or the shift is capped at the maximum itself), else pending (:meth:`_settle_heel_strike`); with
        ``event_margin <= 0`` at the maximum."""
        maximum_ns = self._stamps[0]
        if self.event_margin <= 0.0:  # Algorithm 1's own stamp: the maximum
            return (self._event(INITIAL_CONTACT, stamp_ns, s_max, flag, stamp_ns=maximum_ns),)
        self._pending_ic = (maximum_ns, s_max - self.event_margin, s_max, flag)
        return self._settle_heel_strike(stamp_ns, s, maximum_ns)

    def _settle_heel_strike(self, stamp_ns: int, s: float, last_ns: int) -> tuple[GaitEvent, ...]:
        """The pending heel strike, given out at this sample (``stamp_ns``, ``s``) when it lies
        ``event_margin`` below the maximum, or at the last sample before it (``last_ns``) when this one is
        more than ``heel_strike_shift_max_s`` after the maximum; nothing otherwise (module docstring)."""
        if self._pending_ic is None:
            return ()
        maximum_ns, level, s_max, flag = self._pending_ic
        if stamp_ns - maximum_ns > self.heel_strike_shift_max_ns:
            at_ns = last_ns
        elif s <= level:
            at_ns = stamp_ns
        else:
            return ()
        self._pending_ic = None
        return (self._event(INITIAL_CONTACT, stamp_ns, s_max, flag, stamp_ns=at_ns),)

    def flush(self) -> GaitEvent | None:
        """The next event still queued (a heel strike behind its late toe-off, or one still waiting for
        its stamp at the end of the data: stamped at the last sample): call at the end of the data until
        it returns None."""
        if self._pending_ic is not None and self._stamps:
            _, _, s_max, flag = self._pending_ic
            self._pending_ic = None
            last_ns = self._stamps[-1]
            self._queued.append(self._event(INITIAL_CONTACT, last_ns, s_max, flag, stamp_ns=last_ns))
        return self._queued.popleft() if self._queued else None

    def _late_toe_off(self, k: int) -> tuple[int, int, float] | None:
        """(k, stamp, s) of the deepest sample between the last IC's refractory and the refractory
        before the heel strike confirmed at ``k``, if below LATE_TC_THRESHOLD (module docstring)."""
        best = first = None
        for kj, stamp_ns, sj in self._recent:
            if self._k_ic + self.refractory < kj < k - 1 - self.refractory:
                first = kj if first is None else first
                if best is None or sj < best[2]:
                    best = (kj, stamp_ns, sj)
        if best is None or best[0] == first or not best[2] < LATE_TC_THRESHOLD:
            return None  # no toe-off: a foot that only rose since the window began
        return best

    def _is_minimum(self) -> bool:
        buf = self._s
        n = len(buf)
        c = buf[n - 2]
        trend = 0
        for j in range(n - 3, 0, -1):  # s_{c-i}, i = 1..W (indices n-3 .. 1)
            v = buf[j]
            if not c < v:
                return False
            if v < buf[j - 1]:
                trend += 1
        return trend >= self.min_trend

    def _is_maximum(self) -> bool:
        buf = self._s
        n = len(buf)
        c = buf[n - 2]
        trend = 0
        for j in range(n - 3, 0, -1):
            v = buf[j]
            if not c > v:
                return False
            if v > buf[j - 1]:
                trend += 1
        return trend >= self.min_trend

    def _event(self, kind: str, detected_ns: int, value: float, flag: str = "",
               stamp_ns: int | None = None) -> GaitEvent:
        self.counts[kind] += 1
        stamp = self._stamps[0] if stamp_ns is None else stamp_ns
        return GaitEvent(self.side, kind, stamp, detected_ns, value, self.counts[kind], flag)


def events_from_signal(signal: np.ndarray, rate_hz: float, **options: Any) -> dict[str, np.ndarray]:
    """Algorithm 1 over a whole ``-sin(beta)`` series → event sample indices ``{"ic": (n,), "tc": (m,)}``
    (the extremum samples; the thesis' detection sample is one later). ``options`` go to
    :class:`GaitEventDetector`."""
    detector = GaitEventDetector(rate_hz=rate_hz, **options)
    values = np.asarray(signal, dtype=float)
    out: dict[str, list[int]] = {INITIAL_CONTACT: [], TERMINAL_CONTACT: []}
    stamps = sample_stamps(len(values), rate_hz).tolist()
    index_of = {stamp_ns: k for k, stamp_ns in enumerate(stamps)}
    for stamp_ns, sk in zip(stamps, values.tolist(), strict=True):
        event = detector.update_signal(stamp_ns, sk)
        if event is not None:
            out[event.kind].append(index_of[event.stamp_ns])
    while (event := detector.flush()) is not None:
        out[event.kind].append(index_of[event.stamp_ns])
    return {kind: np.array(v, dtype=int) for kind, v in out.items()}
