"""The chest activity monitor on a live stream: the input rules around :class:`ActivityMonitor`.

Shared by the ``activity_monitor`` node and the offline ``analyze`` path, so both see the same
states. NaN/inf samples are skipped and counted. Samples pass a
:class:`~gait_biofeedback.core.sequencer.StreamSequencer` (``reorder_window_s`` s of re-sequencing;
duplicates, late samples and single bad stamps dropped and counted); a confirmed jump back or a gap
longer than ``max_gap_s`` s restarts the monitor (its upright reference is found again after a jump
back, kept after a gap; each reference taken is said in the notices), keeping the step count, the
posture and the wearer's history, so a dropout does not set the count back to 0 (issue 13). A state
is "changed" when posture, locomotion or the last transition differ from the last changed one. A
trunk forward axis (from the chest's sensor-to-segment calibration) is handed to the monitor at the
first sample at or after its "in force" stamp, or at once if that has passed, as the calibration is
for the other consumers (the monitor applies it to the states it emits from then on, see
``ActivityMonitor.set_forward_axis``). A restart keeps the forward axis and the wearer's walking-
displacement history. The last ``reorder_window_s`` s of a stream stay held: the monitor labels a sample 3 s
after it anyway. Warnings go to :attr:`ActivityStream.notices`.

Samples are identified by their stamps (int ns); the stage's parameters are :class:`ActivityParams`.
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.activity.monitor import (
    INITIAL_POSTURES,
    PLACEMENTS,
    REFERENCES,
    ActivityMonitor,
    ActivityState,
    check_forward_axis,
)
from gait_biofeedback.core.activity.thigh import ThighInputs
from gait_biofeedback.core.body import BodyDimensions
from gait_biofeedback.core.calibration.sensor_to_segment import SegmentEntry
from gait_biofeedback.core.in_force import InForceQueue
from gait_biofeedback.core.notices import Notices
from gait_biofeedback.core.params import param, require, same_as
from gait_biofeedback.core.rate import RateCheck
from gait_biofeedback.core.segments import SEGMENTS
from gait_biofeedback.core.sequencer import StreamSequencer
from gait_biofeedback.core.stamps import NS_PER_S

UNITS = ("m/s2", "g")
MIN_RATE_HZ, MAX_RATE_HZ = 20.0, 200.0  # the monitor's filters are designed for these rates


@dataclass(frozen=True)
class ActivityParams:
    """Parameters of the activity stage (node ``activity_monitor``, and ``analyze``)."""

    segment: str = param("chest", "segment whose raw accelerometer is monitored", choices=SEGMENTS)
    rate_hz: float = param(100.0, "nominal sample rate of that IMU (the filters are designed for it; the "
                           "rate measured from the stamps is used when it differs by over 10 %)", "Hz",
                           low=20.0, high=200.0)
    units: str = param("m/s2", "unit of the accelerometer readings", choices=UNITS)
    placement: str = param("chest", "where the monitored sensor sits on the trunk (chest: thesis ch. 7; "
                           "pelvis: also lower back or waist, posture from the pelvis tilt)",
                           choices=PLACEMENTS)
    reference: str = param("auto", "how the trunk's upright is found: auto = the first quiet period, "
                           "checked and if need be replaced by the first walking bout; start = the first "
                           "reference_s s",
                           choices=REFERENCES)
    reference_s: float = param(2.0, "length of the quiet (auto) or initial (start) period taken as upright",
                               "s", low=0.1, high=60.0)
    thighs: tuple[str, ...] = param(("left_thigh", "right_thigh"), "segments whose raw accelerometers tell "
                                    "sitting from standing while they send (their inclination; empty: the "
                                    "trunk alone)", choices=SEGMENTS)
    thigh_length_m: float = same_as(BodyDimensions, "thigh_length_m")
    initial_posture: str = param("auto", "posture until a transition says otherwise (auto: sitting at the "
                                 "chest, which cannot tell a still stand from sitting until the wearer "
                                 "walks; standing at the pelvis, whose tilt tells them)",
                                 choices=INITIAL_POSTURES)
    forward_axis: tuple[float, ...] = param(
        (1.0, 0.0, 0.0), "trunk forward in chest-sensor axes until a calibration gives it (decides upstairs "
        "vs downstairs only, until 10 s of the wearer's level walking are known)", "1", length=3)
    max_gap_s: float = param(0.5, "longest stamp gap before the monitor restarts", "s", low=0.01, high=60.0)
    reorder_window_s: float = param(0.03, "samples out of order by less than this are re-sequenced (added "
                                    "latency)", "s", low=0.0, high=1.0)
    publish_period_s: float = param(1.0, "the state is also published this often (besides every change)", "s",
                                    low=0.05, high=60.0)

    def __post_init__(self) -> None:
        require(not (self.segment == "pelvis" and self.placement == "chest"),
                "parameter 'segment' is pelvis but 'placement' is chest: the chest's posture rules read a "
                "pelvis sensor wrong; set placement: pelvis (also for a lower-back or waist sensor)")


class ActivityStream:
    """One chest accelerometer stream (see module docstring)."""

    def __init__(self, params: ActivityParams | None = None) -> None:
        p = params or ActivityParams()
        self.params = p
        self.rate_hz = p.rate_hz
        self.max_gap_s = p.max_gap_s
        self.options = {"units": p.units, "reference_s": p.reference_s, "reference": p.reference,
                        "thigh_length_m": p.thigh_length_m, "initial_posture": p.initial_posture,
                        "forward_axis": list(p.forward_axis), "placement": p.placement}
        self._references_said = 0
        self.monitor = ActivityMonitor(self.rate_hz, **self.options)
        self.sequencer = StreamSequencer(window=p.reorder_window_s)
        self.rate = RateCheck(p.rate_hz)
        self._every = 1  # keep every this many samples (a sensor faster than MAX_RATE_HZ)
        self._held: list[tuple[int, tuple]] = []  # the first samples, until the rate is known
        self._skip = 0
        self.counts = {"samples": 0, "nan_skipped": 0, "duplicates": 0, "late": 0, "bad_stamps": 0,
                       "restarts": 0}
        self._steps_before = 0  # steps counted by the monitors a restart replaced
        self._assumption_said = False
        self.notices = Notices()
        self.latest: ActivityState | None = None
        self._last_ns: int | None = None
        self._key: tuple | None = None
        self._waiting_forward: InForceQueue[list[float]] = InForceQueue()
        self.thighs = ThighInputs([seg for seg in p.thighs if seg != p.segment], p.rate_hz, p.reference_s)
        self._waiting: deque[tuple[int, tuple]] = deque()  # trunk samples waiting for the thighs

    def set_forward_axis(self, forward_axis: Sequence[float], from_ns: int = 0) -> None:
        """Trunk forward in sensor axes, in force from stamp ``from_ns`` (see module docstring).

        Raises ValueError when it is not a usable direction (zero, NaN, or vertical for the mounting).
        """
        forward = check_forward_axis(forward_axis).tolist()
        if from_ns > 0 and (self._last_ns is None or from_ns > self._last_ns):
            self._waiting_forward.put(int(from_ns), forward)
            return
        problem = self._apply_forward(forward)
        if problem:
            raise ValueError(problem)

    def apply_calibration(self, entries: Mapping[str, SegmentEntry], from_ns: int = 0) -> None:
        """The trunk forward axis from this segment's entry of a calibration (in force from
        ``from_ns``), and the thighs' uprights from theirs (:meth:`ThighInputs.calibrate`); what happened
        is said in :attr:`notices`.

        The entry's rotation maps segment axes into sensor axes, so the segment's x (anterior) in
        sensor axes is rotate(r, x)."""
        thighs = [seg for seg in self.thighs.segments if seg in entries and entries[seg].valid]
        for seg in thighs:
            self.thighs.calibrate(seg, quat.rotate(entries[seg].rotation, np.array([0.0, 1.0, 0.0])), from_ns)
        if thighs:
            self.notices.say("info", f"{', '.join(thighs)}: upright from the calibration (sitting vs "
                                     "standing from the thighs' inclination)")
        segment = self.params.segment
        entry = entries.get(segment)
        if entry is None or not entry.valid:
            self.notices.say("info", f"calibration has no valid {segment} entry: the current forward axis "
                                     "is kept")
            return
        forward = quat.rotate(entry.rotation, np.array([1.0, 0.0, 0.0]))
        try:
            self.set_forward_axis(forward, from_ns)
        except ValueError as exc:
            self.notices.say("warn", f"{segment} calibration not used for the forward axis: {exc}")
            return
        self.notices.say("info", f"{segment} forward axis from the calibration: "
                                 f"{np.round(forward, 3).tolist()} (sensor)")

    def _apply_forward(self, forward: list[float]) -> str:
        """Hand the axis to the monitor; the reason it was refused, or ""."""
        try:
            self.monitor.set_forward_axis(forward)
        except ValueError as exc:
            return f"{exc}: the previous forward axis is kept"
        self.options["forward_axis"] = forward  # kept across restarts
        return ""

    def update(self, stamp_ns: int, acc: Sequence[float], gyro: Sequence[float] | None = None
               ) -> tuple[ActivityState | None, bool]:
        """One sample (acceleration, and the same sensor's angular velocity if it has a gyro) → (the
        newest state released or None, whether any state released changed). A sample whose acceleration
        is not finite is skipped; a gyro reading that is not is left out."""
        self.counts["samples"] += 1
        if not all(math.isfinite(v) for v in acc):
            self.counts["nan_skipped"] += 1
            return None, False
        rate = tuple(gyro) if gyro is not None and all(math.isfinite(v) for v in gyro) else None
        return self._released(self.sequencer.push(stamp_ns, (tuple(acc), rate)))

    def update_thigh(self, segment: str, stamp_ns: int, acc: Sequence[float]) -> tuple[ActivityState | None,
                                                                                        bool]:
        """One sample of a thigh in ``thighs`` → the trunk states it released (as :meth:`update`)."""
        self.thighs.add(segment, stamp_ns, acc)
        return self._collect(self._release())

    def finish(self) -> list[ActivityState]:
        """The end of the data (``analyze``, the end of a replay): the samples the reorder window, the
        thighs' wait and the monitor's delay line still hold, decided; the states among them that
        changed (a posture, a transition or the walking of the last seconds), and the last one."""
        states = [out for r in self.sequencer.flush()
                  for out in self._sample(r.stamp_ns, r.payload, r.restart_s)]
        states += self._release(force=True)
        states += [self._state(state) for state in self.monitor.flush()]
        out = [state for state, changed in states if changed]
        if states and not states[-1][1]:
            out.append(states[-1][0])
        return out

    @staticmethod
    def _collect(states: list[tuple[ActivityState, bool]]) -> tuple[ActivityState | None, bool]:
        latest, changed = None, False
        for state, change in states:
            latest, changed = state, changed or change
        return latest, changed

    def _released(self, released: list) -> tuple[ActivityState | None, bool]:
        new = self.sequencer.sync_drops(self.counts)
        if new and self.sequencer.dropped - new < 3:
            self.notices.say("warn", f"{self.params.segment}: dropped {self.sequencer.last_dropped}")
        return self._collect([out for r in released
                              for out in self._sample(r.stamp_ns, r.payload, r.restart_s)])

    def _sample(self, stamp_ns: int, sample: tuple, restart_s: float) -> list[tuple[ActivityState, bool]]:
        """One sample (``(acc, gyro or None)``) in stamp order, after the sequencer."""
        segment = self.params.segment
        out: list[tuple[ActivityState, bool]] = []
        dt = None if self._last_ns is None else (stamp_ns - self._last_ns) / NS_PER_S
        if restart_s or (dt is not None and dt > self.max_gap_s):
            self.counts["restarts"] += 1
            cause = (f"time went back {restart_s:.3f} s and went on from there" if restart_s
                     else f"{dt:.2f} s without data")
            kept = "the upright reference taken again" if restart_s else "the upright reference kept"
            self.notices.say("warn", f"{segment}: {cause}: activity monitor restarted (steps, posture and "
                                     f"history kept; {kept})")
            previous = self.monitor
            out = self._release(force=True)
            if restart_s:
                self.thighs.clear()
            out += [self._state(st) for st in previous.flush()]  # its last DELAY_S s, steps included
            self._steps_before += previous.emitted_steps
            options = {**self.options, "initial_posture": previous.posture}
            self.monitor = ActivityMonitor(self.rate_hz, **options)
            self._references_said = 0
            self.monitor.keep_wearer_history(previous)
            if not restart_s:
                self.monitor.keep_mounting(previous)
        self._last_ns = stamp_ns
        if self.rate.measured_hz is None:  # the first samples wait until the rate is known
            self._held.append((stamp_ns, sample))
            rate_note = self.rate.update(stamp_ns)
            if self.rate.measured_hz is None:
                return out
            if rate_note:
                self._set_rate(rate_note)
            held, self._held = self._held, []
            for held_ns, held_sample in held:
                out += self._feed(held_ns, held_sample)
            return out
        return out + self._feed(stamp_ns, sample)

    def _feed(self, stamp_ns: int, sample: tuple) -> list[tuple[ActivityState, bool]]:
        """One sample towards the monitor (thinned above MAX_RATE_HZ), through the thighs' wait."""
        if self._every > 1:
            self._skip = (self._skip + 1) % self._every
            if self._skip:
                return []
        self._waiting.append((stamp_ns, sample))
        return self._release()

    def _release(self, *, force: bool = False) -> list[tuple[ActivityState, bool]]:
        """The waiting trunk samples the thighs are ready for (all if ``force``) into the monitor."""
        segment = self.params.segment
        out: list[tuple[ActivityState, bool]] = []
        newest = self._last_ns or 0
        while self._waiting and (force or self.thighs.ready(self._waiting[0][0], newest)):
            stamp_ns, (acc, gyro) = self._waiting.popleft()
            for forward in self._waiting_forward.due(stamp_ns):
                problem = self._apply_forward(forward)
                if problem:
                    self.notices.say("warn", f"{segment}: {problem}")
            self.monitor.thigh_inclination = self.thighs.inclination_at(stamp_ns, newest)
            state = self.monitor.update(stamp_ns, acc, gyro)
            if len(self.monitor.reference_log) > self._references_said:
                self._say_reference()
            if state is not None and not self._assumption_said and self.monitor.posture_assumed:
                self._assumption_said = True
                self.notices.say("info", f"{segment}: posture {state.posture} assumed until a walk, a "
                                         "transition or a level (pelvis tilt, thighs) tells it "
                                         "(initial_posture: auto)")
            if state is not None:
                out.append(self._state(state))
        return out

    def _say_reference(self) -> None:
        """A notice for each upright reference the monitor took (see core.activity.reference)."""
        segment = self.params.segment
        for t, source, angle in self.monitor.reference_log[self._references_said:]:
            off = f", {math.degrees(angle):.0f}° from the quiet one" if math.isfinite(angle) else ""
            text = {"quiet": "the first quiet period", "walking": f"a walking bout{off}",
                    "start": "the first seconds", "given": "the given reference",
                    "walking confirms quiet": f"a walking bout confirms it{off}"}.get(source, source)
            level = "warn" if source == "walking" and math.isfinite(angle) else "info"
            self.notices.say(level, f"{segment}: trunk upright reference at {t:.1f} s from {text}")
        self._references_said = len(self.monitor.reference_log)

    def _set_rate(self, note: str) -> None:
        """The stream's rate is not the configured one: a new monitor designed for it (before any sample
        reached the old one); above MAX_RATE_HZ every k-th sample."""
        measured = self.rate.rate_hz
        self._every = max(1, math.ceil(measured / MAX_RATE_HZ - 1e-9))
        self.rate_hz = measured / self._every
        if self.rate_hz < MIN_RATE_HZ:
            self.notices.say("error", f"{self.params.segment}: {note}; below {MIN_RATE_HZ:g} Hz the monitor "
                                      "cannot count steps: it keeps the configured rate")
            self.rate_hz, self._every = self.params.rate_hz, 1
            return
        thinned = f", every {self._every}th sample kept" if self._every > 1 else ""
        self.notices.say("warn", f"{self.params.segment} (activity monitor): {note}{thinned}")
        self.monitor = ActivityMonitor(self.rate_hz, **self.options)
        self._references_said = 0
        self.thighs.rate_hz = self.rate_hz  # thigh streams not yet heard from get filters for this rate

    def _state(self, state: ActivityState) -> tuple[ActivityState, bool]:
        """A state of the current monitor, counted on from the monitors a restart replaced."""
        if self._steps_before:
            state = dataclasses.replace(state, step_count=state.step_count + self._steps_before)
        self.latest = state
        key = (state.posture, state.locomotion, state.last_transition, state.last_transition_ns)
        changed = key != self._key
        self._key = key
        return state, changed
