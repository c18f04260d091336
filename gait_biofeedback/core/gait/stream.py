"""Both feet's live gait events and strides: the stream rules around the detector and the tracker.

:class:`GaitEventStream` is what the ``gait_events`` node and the offline analysis
(:mod:`gait_biofeedback.analyze`) both drive: per foot a
:class:`~gait_biofeedback.core.gait.events.GaitEventDetector` (thesis Algorithm 1) and one shared
:class:`~gait_biofeedback.core.gait.cycles.GaitCycleTracker`, plus what a real stream needs:

- Calibration: a foot's samples are not used (counted as ``uncalibrated``) until its calibration is
  in force, unless ``use_standing_reference`` (the mounting is then taken from the first orientation,
  :func:`standing_reference`). :meth:`GaitEventStream.set_calibration` with ``from_ns`` > 0 takes
  effect at the first sample stamped ``>= from_ns`` (so a live node and the offline path switch at
  the same sample); ``from_ns = 0``, or a stamp the foot has already passed, takes effect at once. A
  new calibration resets the foot's detector and strides.
- Bad input: a non-finite or zero quaternion is skipped; a stamp going backwards or a gap
  > ``max_gap_s`` s resets that foot (detector and strides), counted and said
  (:attr:`GaitEventStream.notices`). A stream that stopped (the node's wall-clock check) is reported
  with :meth:`GaitEventStream.stream_stopped`.
- Rate: each foot's rate is measured from its first stamps
  (:class:`~gait_biofeedback.core.rate.RateCheck`); more than 10 % off ``rate_hz``, the detector
  counts its windows at the measured rate, and says so.
- Sensor dropouts (issue 13): an event detected on a sample whose orientation was being re-acquired
  after a dropout (``recovering``) carries the flag "sensor dropout: orientation recovering"; a
  stride that contains such a sample, or a stamp gap > ``dropout_gap_s`` s, is not plausible (flag
  "sensor dropout: ..."), so no cue is given from it.

- Spatial values (issue 16): with ``spatial``, each foot's angular velocity and specific force also
  feed a :class:`~gait_biofeedback.core.spatial.stream.FootTrajectoryStream`, and a stride closed
  by an IC is held until the trajectory's stride of the same swing is in
  (:class:`~gait_biofeedback.core.gait.spatial.SpatialPairing`, at most ``spatial_wait_s`` s); its
  values, or NaN and the reason, go with it. With ``spatial_provisional`` it goes out
  ``provisional_after_s`` s after the IC with a provisional length, speed and swing values when
  the trajectory has one, and a *revision* (a GaitCycle with ``revision``, the smoothed values)
  follows. A reset of the foot for its stamps (a gap, time going back, a stream that stopped)
  releases the held strides and pending revisions without spatial values; a new calibration does not
  (the trajectory does not use it).

Samples are identified by their stamps (int ns); the stage's parameters are :class:`GaitEventsParams`.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.calibration.sensor_to_segment import SegmentEntry
from gait_biofeedback.core.gait.cycles import MAX_STRIDE_S, MIN_STRIDE_S, GaitCycle, GaitCycleTracker
from gait_biofeedback.core.gait.events import (
    EVENT_MARGIN,
    EXTREMUM_WINDOW_S,
    HEEL_STRIKE_SHIFT_MAX_S,
    REFRACTORY_S,
    THRESHOLD,
    TOE_OFF_SHIFT_MAX_S,
    TREND_FRACTION,
    GaitEvent,
    GaitEventDetector,
)
from gait_biofeedback.core.gait.spatial import SpatialPairing
from gait_biofeedback.core.in_force import InForceQueue
from gait_biofeedback.core.notices import Notices
from gait_biofeedback.core.params import param, require, same_as
from gait_biofeedback.core.rate import RateCheck
from gait_biofeedback.core.segments import SIDES
from gait_biofeedback.core.spatial.stream import MIN_RUN, FootTrajectoryParams, FootTrajectoryStream
from gait_biofeedback.core.spatial.strides import SpatialStride, heading_change
from gait_biofeedback.core.stamps import NS_PER_S

FOOT_SIDES = SIDES
RECOVERING_FLAG = "sensor dropout: orientation recovering"
ENDED_FLAG = "the data ended before the foot's next stance: spatial values unknown"


@dataclass(frozen=True)
class GaitEventsParams:
    """Parameters of the gait-event stage (node ``gait_events``, and ``analyze``)."""

    sides: tuple[str, ...] = param(FOOT_SIDES, "feet whose events are detected", choices=FOOT_SIDES)
    rate_hz: float = param(100.0, "nominal sample rate: Algorithm 1 counts samples (windows of 15 at 100 "
                           "Hz); the rate measured from the stamps is used when it differs by over 10 %",
                           "Hz", low=20.0, high=1000.0)
    threshold: float = param(THRESHOLD, "-sin(foot pitch) threshold of Algorithm 1 (thesis §6.2.2)", "1",
                             low=-1.0, high=1.0)
    refractory_s: float = param(REFRACTORY_S, "least time between two events of one type", "s",
                                low=0.0, high=2.0)
    window_s: float = param(EXTREMUM_WINDOW_S, "look-back of the local-extremum rule", "s",
                            low=0.01, high=1.0)
    trend_fraction: float = param(TREND_FRACTION, "share of monotone differences the extremum rule needs",
                                  "1", low=0.0, high=1.0)
    event_margin: float = param(EVENT_MARGIN, "an event is stamped where the -sin(foot pitch) is this far "
                                "from its extremum: TC where it enters it before the minimum, IC where it "
                                "leaves it after the maximum; 0 = at the extremum (core/gait/events.py, "
                                "chosen on ipol_gait subjects 1-5)", "1", low=0.0, high=0.5)
    toe_off_shift_max_s: float = param(TOE_OFF_SHIFT_MAX_S, "the most a TC's stamp is moved before its "
                                       "minimum by event_margin", "s", low=0.0, high=0.5)
    heel_strike_shift_max_s: float = param(HEEL_STRIKE_SHIFT_MAX_S, "the most an IC's stamp is moved after "
                                           "its maximum by event_margin (it is published at most this much "
                                           "later)", "s", low=0.0, high=0.5)
    max_gap_s: float = param(0.5, "longest stamp gap before a foot's state is reset", "s",
                             low=0.01, high=60.0)
    dropout_gap_s: float = param(0.1, "a stamp gap longer than this inside a stride makes it implausible "
                                 "(sensor dropout)", "s", low=0.01, high=60.0)
    use_standing_reference: bool = param(False, "before a calibration, take the foot's anterior axis from "
                                         "its first orientation (IMU x made horizontal, thesis §6.2.2)")
    symmetry_window: int = param(10, "steps per side in the step-time symmetry index", "steps",
                                 low=1, high=1000)
    min_stride_s: float = param(MIN_STRIDE_S, "shorter strides are flagged implausible", "s",
                                low=0.1, high=10.0)
    max_stride_s: float = param(MAX_STRIDE_S, "longer strides are flagged implausible", "s",
                                low=0.2, high=30.0)
    stale_after_s: float = param(1.0, "time without a foot's data before its state is reset and reported",
                                 "s", low=0.1, high=60.0)
    diagnostics_period_s: float = param(1.0, "period of the /diagnostics status", "s", low=0.1, high=60.0)
    spatial: bool = param(True, "estimate each foot's trajectory (Suh 2014) for the strides' spatial values")
    spatial_wait_s: float = param(0.7, "longest wait after a stride's closing IC for the next stance that "
                                  "closes its trajectory; then it is published without spatial values", "s",
                                  low=0.05, high=2.0)
    spatial_provisional: bool = param(True, "publish a stride provisional_after_s after its closing IC "
                                      "with a provisional stride length, speed and swing values; the "
                                      "smoothed values follow on "
                                      "gait/stride_space (core/gait/spatial.py)")
    provisional_after_s: float = param(0.015, "how long after the closing IC (its stamp) the provisional "
                                       "values are taken; the orientation filter's reorder_window_s comes on "
                                       "top (core/gait/spatial.py)", "s", low=0.0, high=0.5)
    detector: str = same_as(FootTrajectoryParams, "detector")
    gyro_limit: float = same_as(FootTrajectoryParams, "gyro_limit")
    jerk_limit: float = same_as(FootTrajectoryParams, "jerk_limit")
    valley: bool = same_as(FootTrajectoryParams, "valley")
    flat_floor: bool = same_as(FootTrajectoryParams, "flat_floor")
    bias_rest_s: float = same_as(FootTrajectoryParams, "bias_rest_s")
    close_after_s: float = same_as(FootTrajectoryParams, "close_after_s")
    min_swing_s: float = same_as(FootTrajectoryParams, "min_swing_s")
    max_swing_s: float = same_as(FootTrajectoryParams, "max_swing_s")
    toe_lever_arm_m: tuple[float, ...] = same_as(FootTrajectoryParams, "toe_lever_arm_m")
    provisional_tolerance_m: float = same_as(FootTrajectoryParams, "provisional_tolerance_m")
    adaptive_scale: float = same_as(FootTrajectoryParams, "adaptive_scale")
    adaptive_window_s: float = same_as(FootTrajectoryParams, "adaptive_window_s")

    @property
    def foot_trajectory(self) -> FootTrajectoryParams:
        """The foot-trajectory stage's parameters (the rest at their defaults)."""
        return FootTrajectoryParams(**{f: getattr(self, f) for f in (
            "detector", "gyro_limit", "jerk_limit", "valley", "flat_floor", "bias_rest_s", "close_after_s",
            "min_swing_s", "max_swing_s", "toe_lever_arm_m", "provisional_tolerance_m", "adaptive_scale",
            "adaptive_window_s")})

    def __post_init__(self) -> None:
        require(bool(self.sides) and len(set(self.sides)) == len(self.sides),
                f"parameter 'sides': {list(self.sides)} must name 'left' and/or 'right' once each")
        self.foot_trajectory  # noqa: B018 (checked by the foot-trajectory stage's own rules)
        require(self.min_stride_s < self.max_stride_s,
                f"parameter 'min_stride_s' ({self.min_stride_s:g}) must be below 'max_stride_s' "
                f"({self.max_stride_s:g})")


def standing_reference(q: np.ndarray) -> np.ndarray:
    """Rotation r whose segment x axis is the horizontal projection of the IMU x axis at orientation q
    (y up): ``q_segment = q ⊗ r`` keeps the heading and removes the standing roll/pitch."""
    forward = quat.rotate(q, np.array([1.0, 0.0, 0.0]))
    forward[2] = 0.0
    forward /= np.linalg.norm(forward)
    up = np.array([0.0, 0.0, 1.0])
    segment_in_world = np.column_stack([forward, up, np.cross(forward, up)])
    return quat.from_matrix(quat.as_matrix(quat.conjugate(q)) @ segment_in_world)


_HELD = ()  # update_batch's gyro and acceleration of a row: in its _FootRows
Released = tuple[int, GaitCycle]  # a stride released and the row of update_batch it came out at


class _FootRows:
    """:meth:`GaitEventStream.update_batch`'s foot rows: rows ``start`` to ``end`` are not yet given to the
    foot trajectory."""

    def __init__(self, side: str, stamps: np.ndarray, gyr: np.ndarray, acc: np.ndarray) -> None:
        self.side, self.stamps, self.gyr, self.acc = side, stamps, gyr, acc
        self.start = self.end = 0


class GaitEventStream:
    """Gait events and strides of the feet in ``params.sides`` (see module docstring)."""

    def __init__(self, params: GaitEventsParams | None = None) -> None:
        p = params or GaitEventsParams()
        self.params = p
        self.sides = list(p.sides)
        self.max_gap_s = p.max_gap_s
        self.use_standing_reference = p.use_standing_reference
        self.tracker = GaitCycleTracker(symmetry_window=p.symmetry_window, min_stride_s=p.min_stride_s,
                                        max_stride_s=p.max_stride_s)
        self.detectors = {s: GaitEventDetector(s, p.rate_hz, threshold=p.threshold,
                                               refractory_s=p.refractory_s, window_s=p.window_s,
                                               trend_fraction=p.trend_fraction, event_margin=p.event_margin,
                                               toe_off_shift_max_s=p.toe_off_shift_max_s,
                                               heel_strike_shift_max_s=p.heel_strike_shift_max_s)
                          for s in self.sides}
        self.calibrated = {s: False for s in self.sides}
        self.counts = {s: {"samples": 0, "uncalibrated": 0, "resets": 0, "stream_stops": 0, "ic": 0, "tc": 0,
                           "strides": 0, "implausible_strides": 0, "spatial_strides": 0,
                           "spatial_unknown": 0, "spatial_provisional": 0} for s in self.sides}
        self.notes: dict[str, str] = {s: "" for s in self.sides}
        self.notices = Notices()
        self._last_ns: dict[str, int | None] = {s: None for s in self.sides}
        self._doubtful: dict[str, tuple[int, str] | None] = {s: None for s in self.sides}
        self.rates = {s: RateCheck(p.rate_hz) for s in self.sides}
        self._waiting: dict[str, InForceQueue[np.ndarray]] = {s: InForceQueue() for s in self.sides}
        self.feet = {s: self._foot(p.rate_hz) for s in self.sides} if p.spatial else {}
        after = p.provisional_after_s if p.spatial_provisional else None
        self.pairing = {s: SpatialPairing(p.spatial_wait_s, after, 1.0 / p.rate_hz) for s in self.sides}
        self._released: dict[str, list[GaitCycle]] = {s: [] for s in self.sides}
        # each foot's recent orientations, for the heading change of a stride without spatial values
        self._orientations: dict[str, deque[tuple[int, tuple[float, ...]]]] = {s: deque() for s in self.sides}
        self._history_ns = round((p.max_stride_s + p.spatial_wait_s + 1.0) * NS_PER_S)
        self._batch: _FootRows | None = None  # update_batch's foot rows not yet given to the foot

    def _foot(self, rate_hz: float) -> FootTrajectoryStream:
        return FootTrajectoryStream(rate_hz, self.params.foot_trajectory)

    def set_calibration(self, side: str, rotation: np.ndarray | None, valid: bool = True, message: str = "",
                        from_ns: int = 0) -> None:
        """The foot calibration r (segment → sensor) of ``side``, in force from stamp ``from_ns``."""
        if side not in self.detectors:
            return
        if not valid or rotation is None:
            self.notes[side] = f"calibration invalid: {message}"
            return
        last = self._last_ns[side]
        if from_ns > 0 and (last is None or from_ns > last):
            self._waiting[side].put(int(from_ns), np.asarray(rotation, dtype=float))
            return
        self._apply(side, np.asarray(rotation, dtype=float))

    def apply_calibration(self, entries: Mapping[str, SegmentEntry], from_ns: int = 0) -> None:
        """The feet's entries (``<side>_foot``) of a calibration in force from stamp ``from_ns``."""
        for side in self.sides:
            entry = entries.get(f"{side}_foot")
            if entry is not None:
                self.set_calibration(side, entry.rotation, entry.valid, entry.message, from_ns)

    def _apply(self, side: str, rotation: np.ndarray) -> None:
        self.detectors[side].set_mounting(rotation)
        self.reset(side, "new calibration", release=False)  # the foot trajectory does not use it
        self.calibrated[side] = True
        self.notes[side] = ""

    def reset(self, side: str, why: str, release: bool = True) -> None:
        """Forget ``side``'s detector state and open strides (counted; noted for /diagnostics);
        ``release``: the strides waiting for their spatial values go out without them."""
        self._sync(side)
        self.detectors[side].reset()
        self.tracker.reset(side)
        if release:
            self._release(side, self.pairing[side].release(f"state reset ({why}): spatial values unknown"))
        self._last_ns[side] = None
        self._doubtful[side] = None
        self._orientations[side].clear()
        self.counts[side]["resets"] += 1
        self.notes[side] = f"state reset: {why}"

    def stream_stopped(self, side: str, seconds: float) -> None:
        """``side``'s samples stopped ``seconds`` ago (wall clock): reset its state."""
        self.counts[side]["stream_stops"] += 1
        self.reset(side, "stream stopped")
        self.notices.say("warn", f"{side} foot: no data for {seconds:.1f} s, state reset")

    def finish(self) -> list[GaitCycle]:
        """The end of the data (``analyze``, the end of a replay): each foot's trajectory decides its
        last samples, the strides held for their spatial values go out with those that closed, the
        others without values (flagged), and pending revisions likewise; nothing held is dropped."""
        for side, foot in self.feet.items():
            for stride in foot.flush():
                self.pairing[side].add_stride(stride)
        out = []
        for side in self.sides:
            last_ns = self._last_ns[side]
            if last_ns is not None:
                self._release(side, self.pairing[side].due(last_ns))
            self._release(side, self.pairing[side].release(ENDED_FLAG))
            out += self.take_released(side)
        return out

    def take_released(self, side: str) -> list[GaitCycle]:
        """``side``'s strides released outside :meth:`update` (a reset), to be published now."""
        out, self._released[side] = self._released[side], []
        return out

    def _release(self, side: str, decided: list) -> None:
        for cycle, space, revision in decided:
            final = "spatial_unknown" if space.flag else "spatial_strides"
            self.counts[side]["spatial_provisional" if space.provisional else final] += 1
            if not space.provisional and not math.isfinite(space.turning_angle):
                space = replace(space, turning_angle=self._turn(side, cycle.start_ns, cycle.end_ns))
            self._released[side].append(replace(cycle, space=space, revision=revision))

    def _turn(self, side: str, start_ns: int, end_ns: int) -> float:
        """The foot's heading change (rad) from its orientation at ``start_ns`` to the one at ``end_ns``
        (each the last sample at or before it): a stride without spatial values still says whether it
        turned (EXT; a U-turn's strides often have none: benchmarks/turns.py). NaN when either is gone."""
        history = self._orientations[side]
        stamps = [t for t, _ in history]
        a, b = bisect_right(stamps, start_ns) - 1, bisect_right(stamps, end_ns) - 1
        if a < 0 or b < 0:
            return math.nan
        return heading_change(np.array(history[a][1]), np.array(history[b][1]))

    def update(self, side: str, stamp_ns: int, q: tuple[float, float, float, float],
               recovering: bool = False, gyr: tuple[float, float, float] | None = None,
               acc: tuple[float, float, float] | None = None) -> tuple[list[GaitEvent], list[GaitCycle]]:
        """One orientation sample (sensor→world w, x, y, z) of ``side``'s foot stamped ``stamp_ns``
        (``recovering``: its orientation is being re-acquired after a dropout), with its angular
        velocity (rad/s) and specific force (m/s²) for the foot trajectory → (the events it
        confirmed, the strides now complete). With ``spatial`` a stride closed by an IC comes out
        once its trajectory stride is in (:mod:`.spatial`), at most ``spatial_wait_s`` s later."""
        events = self._events(side, stamp_ns, q, recovering, gyr, acc)
        return events, self.take_released(side)

    def _events(self, side: str, stamp_ns: int, q: tuple[float, float, float, float], recovering: bool,
                gyr: tuple[float, float, float] | None, acc: tuple[float, float, float] | None
                ) -> list[GaitEvent]:
        counts = self.counts[side]
        counts["samples"] += 1
        foot = self.feet.get(side)
        if foot is not None and gyr is not None and acc is not None:
            if self._batch is not None:
                self._batch.end += 1  # given to the foot when something needs it (_sync)
            else:
                self._foot_strides(side, foot.update(stamp_ns, gyr, acc))
        if not all(math.isfinite(v) for v in q) or tuple(q) == (0.0, 0.0, 0.0, 0.0):
            return []
        rate_note = self.rates[side].update(stamp_ns)
        if rate_note:
            self._sync(side)
            self.detectors[side].set_rate(self.rates[side].rate_hz)
            self.detectors[side].reset()
            if foot is not None:
                self.feet[side] = self._foot(self.rates[side].rate_hz)
            self.notices.say("warn", f"{side} foot (gait events): {rate_note}")
        for rotation in self._waiting[side].due(stamp_ns):
            self._apply(side, rotation)
        if not self.calibrated[side]:
            if not self.use_standing_reference:
                counts["uncalibrated"] += 1
                return []
            self.detectors[side].set_mounting(standing_reference(np.array(q)))
            self.calibrated[side] = True
        last_ns = self._last_ns[side]
        if last_ns is not None:
            t, last = stamp_ns / NS_PER_S, last_ns / NS_PER_S
            if t <= last or t - last > self.max_gap_s:
                why = "time went backwards" if t <= last else f"{t - last:.2f} s gap in the stamps"
                self.reset(side, why)
                self.notices.say("warn", f"{side} foot: {self.notes[side]}")
            elif t - last > self.params.dropout_gap_s:
                self._doubtful[side] = (stamp_ns, f"sensor dropout: {t - last:.2f} s without data")
        if recovering:
            self._doubtful[side] = (stamp_ns, RECOVERING_FLAG)
        self._last_ns[side] = stamp_ns
        history = self._orientations[side]
        history.append((stamp_ns, tuple(q)))
        while history[0][0] < stamp_ns - self._history_ns:
            history.popleft()
        self.tracker.tracking.add(side)
        event = self.detectors[side].update(stamp_ns, q)
        events = [] if event is None else [self._event(side, event, recovering)]
        pairing = self.pairing[side]
        if pairing.waiting:
            self._sync(side)
        self._release(side, pairing.due(stamp_ns, self.feet[side].provisional) if self.feet
                      else pairing.release("spatial values off"))
        return events

    def _foot_strides(self, side: str, strides: list[SpatialStride]) -> None:
        """The strides the foot trajectory closed, and its notices."""
        for stride in strides:
            self.pairing[side].add_stride(stride)
        for notice in self.feet[side].notices.pop():
            self.notices.say(notice.level, f"{side} foot trajectory: {notice.text}")

    def _sync(self, side: str) -> None:
        """:meth:`update_batch`: the foot rows held back given to the foot now (its array function), as
        :meth:`update` would have given them one by one: called before anything that depends on the
        foot's state or strides (a due stride, a reset, a new rate, a notice)."""
        rows = self._batch
        if rows is None or rows.side != side or rows.end == rows.start:
            return
        a, b = rows.start, rows.end
        rows.start = b
        foot = self.feet[side]
        if b - a < MIN_RUN:  # a row or a few (a stride held: the foot row by row): no arrays' overhead
            self._foot_strides(side, [stride for k in range(a, b) for stride in
                                      foot.update(int(rows.stamps[k]), rows.gyr[k], rows.acc[k])])
            return
        strides = foot.update_batch(rows.stamps[a:b], rows.gyr[a:b], rows.acc[a:b])
        self._foot_strides(side, [stride for _, stride in strides])

    def update_batch(self, side: str, stamps_ns: np.ndarray, q: np.ndarray,
                     recovering: np.ndarray | None = None, gyr: np.ndarray | None = None,
                     acc: np.ndarray | None = None) -> tuple[list[tuple[int, GaitEvent]], list[Released]]:
        """:meth:`update` of each row of ``side``'s foot (stamps int ns (n,), q (n, 4), recovering (n,),
        gyr and acc (n, 3)), as the stage's array function: (each event confirmed, each stride released,
        with its row), the state, counts and notices equal to :meth:`update`'s row by row. The foot
        trajectory's rows go through its array function in runs, given to it whenever the events' logic
        needs its state (a held stride due, a reset, a new rate, a notice); the events' logic runs per
        row."""
        n = len(stamps_ns)
        stamps = np.asarray(stamps_ns, np.int64)
        quaternions = np.asarray(q, float).tolist()
        flags = [False] * n if recovering is None else np.asarray(recovering, bool).tolist()
        events: list[tuple[int, GaitEvent]] = []
        cycles: list[Released] = []
        held = None if gyr is None or acc is None else _HELD
        if gyr is None or acc is None:
            rows = None
        else:
            rows = _FootRows(side, stamps, np.asarray(gyr, float), np.asarray(acc, float))
            self._batch = rows
        try:
            for k, stamp_ns in enumerate(stamps.tolist()):
                row_events, released = self.update(side, stamp_ns, tuple(quaternions[k]), flags[k], held,
                                                   held)
                events += [(k, event) for event in row_events]
                cycles += [(k, cycle) for cycle in released]
            self._sync(side)
            cycles += [(n - 1, cycle) for cycle in self.take_released(side)]
        finally:
            self._batch = None
        return events, cycles

    def _event(self, side: str, event: GaitEvent, recovering: bool) -> GaitEvent:
        counts = self.counts[side]
        if recovering:
            event = replace(event, flag=RECOVERING_FLAG)
        counts[event.kind] += 1
        cycle = self.tracker.add(event, self._doubtful[side])
        if cycle is not None:
            self._sync(side)  # the foot's notices before this one
            counts["strides"] += 1
            if not cycle.plausible:
                counts["implausible_strides"] += 1
                # information: strides of a calibration's leg movements or across a pause are flagged as a
                # rule; the summaries count them by reason (report.session) and /diagnostics counts them
                self.notices.say("info", f"{cycle.side} stride {cycle.index} flagged: {cycle.flag}")
            self.pairing[side].add_cycle(cycle)
        return event
