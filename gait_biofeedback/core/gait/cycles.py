"""Per-stride temporal parameters from both feet's IC/TC events (issue 5; thesis Ch. 8 feedback list).

A stride of one foot runs from its IC to its next IC. At that closing IC, :class:`GaitCycleTracker`
returns a :class:`GaitCycle`: stride, stance (IC → TC) and swing (TC → next IC) time and fractions,
step time (last IC of the other foot → this IC), cadence (steps/s = 2 / stride time), double support
(IC → other foot's TC, plus other foot's IC → this foot's TC, inside the stride), and the step-time
symmetry index ``(left - right) / (0.5 (left + right))`` of the mean step times over the last
``symmetry_window`` steps of each side (a step "of the left side" ends with a left IC).
Plausibility: a stride outside [0.4, 3] s, one without exactly one TC of its own foot between the
two ICs, or, when the other foot is tracked (``tracking``: its detector runs), one without an IC of
the other foot (a leg lifted and set down while the other stands: hip flexion, a shuffle; or the
other's step missed) is returned with ``plausible=False`` and a ``flag`` saying why; implausible
strides do not enter the symmetry window.
Events may arrive slightly out of order between feet (two topics; the other foot's step lies half a
stride before the closing IC); each foot's own events must be in order.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from gait_biofeedback.core.gait.events import INITIAL_CONTACT, TERMINAL_CONTACT, GaitEvent
from gait_biofeedback.core.segments import SIDES
from gait_biofeedback.core.stamps import NS_PER_S, s_to_ns

MIN_STRIDE_S = 0.4
MAX_STRIDE_S = 3.0
NO_STEP = "no step of the {other} foot detected in this stride (not walking, or its step missed)"
TOE_OFFS = "{count} terminal contacts between the initial contacts (expected 1)"
STRIDE_TIME = "stride time {stride:.2f} s outside {low:g}-{high:g} s"
FLAG_KINDS = (("no step of the ", "no step of the other foot (not walking, or a step missed)"),
              ("stride time ", "stride time outside the plausible range (a pause, or not walking)"),
              ("terminal contacts between", "not one toe-off between the heel strikes"))
"""A flag's clauses by what they start with (the others: their text up to a colon), for counting
strides by why they were left out."""


def flag_kinds(flag: str) -> list[str]:
    """The kinds of the clauses of a stride's ``flag`` (:data:`FLAG_KINDS`), in order, each once."""
    kinds = []
    for clause in filter(None, flag.split("; ")):
        start = clause.lstrip("0123456789 ")
        kind = next((k for prefix, k in FLAG_KINDS if start.startswith(prefix)), clause.split(":")[0])
        if kind not in kinds:
            kinds.append(kind)
    return kinds
TURN_LIMIT = math.radians(20.0)
"""rad: a stride whose foot's heading changed more is a turn, left out of the summaries (EXT)."""


TURN_WINDOW_S = 0.25
"""s: a stride is looked at with its neighbours this far before and after it (:func:`turning_strides`)."""
WHOLE_TURN_LIMIT = math.radians(60.0)
"""rad: a foot whose heading changes more over a stride and its neighbours turns. With TURN_WINDOW_S,
chosen on ipol_gait subjects 1-5 (U-turn strides kept as straight 47 → 14 of 110, straight strides
kept 99.1 → 93.2 %) and confirmed on 6-9 (34 → 12 of 74, 94.7 %): benchmarks/turns.py."""


def turning_strides(strides: Sequence[tuple[str, float, float, float]], window_s: float = TURN_WINDOW_S,
                    limit: float = WHOLE_TURN_LIMIT) -> list[bool]:
    """Which strides ``(side, start s, end s, turning angle rad)`` are part of a turn (EXT): the stride's
    own heading change is over :data:`TURN_LIMIT`, or either foot's heading changes by more than
    ``limit`` summed over its strides that overlap the stride widened by ``window_s`` on each side. A
    U-turn is made of a few strides of both feet, and a stride inside one can keep its own heading (a
    foot pivoting while the other turns: ipol_gait 7-4's right stride at 12.62 s, 5° inside a U-turn);
    a stride without a turning angle (NaN) adds nothing."""
    feet = {}
    for side in {s[0] for s in strides}:
        mine = sorted((a, b, angle) for s, a, b, angle in strides if s == side)
        starts, ends = np.array([m[0] for m in mine]), np.array([m[1] for m in mine])
        angles = np.nan_to_num(np.array([m[2] for m in mine], dtype=float))
        feet[side] = (starts, ends, np.concatenate([[0.0], np.cumsum(angles)]))
    out = []
    for _, a, b, angle in strides:
        turn = abs(angle) > TURN_LIMIT
        for starts, ends, total in feet.values():
            first = int(np.searchsorted(ends, a - window_s, side="right"))
            last = int(np.searchsorted(starts, b + window_s, side="left"))
            turn = turn or (last > first and abs(total[last] - total[first]) > limit)
        out.append(bool(turn))
    return out


def left_out_reasons(strides: Sequence[tuple[str, int, int, bool, float]],
                     walking: Sequence[bool] | None = None) -> list[str]:
    """Why each stride ``(side, start_ns, end_ns, plausible, turning angle rad)`` is left out of the
    summaries (EXT), "" when it is used: ``implausible``; ``outside_walking`` where ``walking`` (per
    stride, None: not looked at) is False; ``turning`` (:func:`turning_strides`); ``walk_start_or_end``
    (:func:`steady_strides`). The one rule of analyze's summary, the report and the tables."""
    steady = steady_strides([s[:4] for s in strides])
    turns = turning_strides([(side, a / NS_PER_S, b / NS_PER_S, angle) for side, a, b, _, angle in strides])
    reasons = []
    for k, ((*_, plausible, _), keep, turn) in enumerate(zip(strides, steady, turns, strict=True)):
        if not plausible:
            reasons.append("implausible")
        elif walking is not None and not walking[k]:
            reasons.append("outside_walking")
        elif turn:
            reasons.append("turning")
        elif not keep:
            reasons.append("walk_start_or_end")
        else:
            reasons.append("")
    return reasons


def steady_strides(strides: Sequence[tuple[str, int, int, bool]]) -> list[bool]:
    """Which strides ``(side, start_ns, end_ns, plausible)`` are steady walking, for the summaries (EXT):
    plausible, and neither the first nor the last of their foot's bout. A bout is a run of the foot's
    plausible strides each starting at the previous one's end (an implausible stride, e.g. the 4.3 s
    "stride" from a stop to the next walk, ends one). The first after a standing is the gait
    initiation, the last the stop (a foot brought alongside the other: half a stride or less;
    ipol_gait 1-1's last right stride of 0.28 m made its right stride length 1.21 ± 0.26 against the
    left's 1.29 ± 0.12 m). A bout of one or two strides keeps none."""
    out = [False] * len(strides)
    for side in {s[0] for s in strides}:
        mine = sorted((start, end, k) for k, (s, start, end, ok) in enumerate(strides) if s == side and ok)
        for i, (start, end, k) in enumerate(mine):
            after = i > 0 and mine[i - 1][1] == start
            before = i + 1 < len(mine) and mine[i + 1][0] == end
            out[k] = after and before
    return out


@dataclass(frozen=True)
class StrideSpace:
    """The spatial values of one IC→IC stride (SI, NaN when unknown) and why they are doubtful."""

    stride_length: float = math.nan
    gait_speed: float = math.nan
    max_foot_height: float = math.nan
    min_toe_clearance: float = math.nan
    foot_angle_ic: float = math.nan
    foot_angle_tc: float = math.nan
    turning_angle: float = math.nan
    lateral_excursion: float = math.nan
    flag: str = ""
    provisional: bool = False  # before the next stance: every value provisional (.spatial)


@dataclass(frozen=True)
class GaitCycle:
    """One stride of ``side``: the stamps (int ns) of its opening IC, closing IC and its TC (None when
    it has not exactly one), durations in s, fractions of the stride time, NaN where unknown;
    ``space``: its spatial values (:mod:`.spatial`), all NaN until they are paired; ``revision``: this
    is not a new stride but the smoothed ``space`` of one that went out with provisional values."""

    side: str
    index: int
    start_ns: int
    end_ns: int
    terminal_contact_ns: int | None
    stride_time: float
    stance_time: float
    swing_time: float
    stance_fraction: float
    swing_fraction: float
    step_time: float
    cadence: float
    double_support_time: float
    double_support_fraction: float
    step_time_symmetry_index: float
    plausible: bool
    flag: str = ""
    space: StrideSpace = field(default_factory=StrideSpace)
    revision: bool = False

    @property
    def start(self) -> float:
        """Opening IC, s."""
        return self.start_ns / NS_PER_S

    @property
    def end(self) -> float:
        """Closing IC, s."""
        return self.end_ns / NS_PER_S

    @property
    def terminal_contact(self) -> float:
        """The stride's TC, s (NaN when unknown)."""
        return math.nan if self.terminal_contact_ns is None else self.terminal_contact_ns / NS_PER_S


class GaitCycleTracker:
    """Streaming stride parameters of both feet: feed every :class:`GaitEvent` to :meth:`add`."""

    def __init__(self, symmetry_window: int = 10, min_stride_s: float = MIN_STRIDE_S,
                 max_stride_s: float = MAX_STRIDE_S, history: int = 8) -> None:
        self.min_stride_s = float(min_stride_s)
        self.max_stride_s = float(max_stride_s)
        self._ics: dict[str, deque[GaitEvent]] = {s: deque(maxlen=history) for s in SIDES}
        self._tcs: dict[str, deque[GaitEvent]] = {s: deque(maxlen=history) for s in SIDES}
        self._steps = {s: deque(maxlen=max(1, int(symmetry_window))) for s in SIDES}
        self.counts = {s: 0 for s in SIDES}
        self.implausible = {s: 0 for s in SIDES}
        self.tracking: set[str] = set()  # the feet whose events come in: a stride needs the other's step

    def reset(self, side: str) -> None:
        """Forget one foot's events (its stream stopped): its next IC opens a new stride."""
        self._ics[side].clear()
        self._tcs[side].clear()
        self.tracking.discard(side)

    def add(self, event: GaitEvent, doubt: tuple[int, str] | None = None) -> GaitCycle | None:
        """One event; the stride it closes (an IC after an earlier IC of the same foot), else None.
        ``doubt``: (stamp ns, why) of the foot's latest doubtful sample; a stride containing it is
        not plausible, with that flag."""
        side = event.side
        if event.kind == TERMINAL_CONTACT:
            self._tcs[side].append(event)
            return None
        if event.kind != INITIAL_CONTACT:
            raise ValueError(f"unknown event kind {event.kind!r}")
        ics = self._ics[side]
        previous = ics[-1] if ics else None
        ics.append(event)
        if previous is None:
            return None
        return self._cycle(side, previous, event, doubt)

    def _cycle(self, side: str, opening: GaitEvent, closing: GaitEvent,
               doubt: tuple[int, str] | None) -> GaitCycle:
        start, end = opening.t, closing.t
        other = SIDES[1 - SIDES.index(side)]
        stride = end - start
        own_tcs = [e for e in self._tcs[side] if start < e.t < end]
        flags = [doubt[1]] if doubt is not None and doubt[0] >= opening.stamp_ns else []
        if not self.min_stride_s <= stride <= self.max_stride_s:
            flags.append(STRIDE_TIME.format(stride=stride, low=self.min_stride_s, high=self.max_stride_s))
        if len(own_tcs) != 1:
            flags.append(TOE_OFFS.format(count=len(own_tcs)))
        tc = own_tcs[0].t if own_tcs else math.nan
        other_ics = [e.t for e in self._ics[other] if start < e.t < end]
        if not other_ics and (other in self.tracking or self._ics[other] or self._tcs[other]):
            flags.append(NO_STEP.format(other=other))
        step = end - other_ics[-1] if other_ics else math.nan
        other_tc_after_start = [e.t for e in self._tcs[other] if start < e.t < tc]
        other_ic_before_tc = [t for t in other_ics if t < tc]
        if other_tc_after_start and other_ic_before_tc:
            double = (other_tc_after_start[0] - start) + (tc - other_ic_before_tc[-1])
        else:
            double = math.nan
        plausible = not flags
        if plausible and math.isfinite(step):
            self._steps[side].append(step)
        if not plausible:
            self.implausible[side] += 1
        self.counts[side] += 1
        stance = tc - start
        swing = end - tc
        return GaitCycle(
            side=side, index=self.counts[side], start_ns=opening.stamp_ns, end_ns=closing.stamp_ns,
            terminal_contact_ns=own_tcs[0].stamp_ns if own_tcs else None,
            stride_time=stride, stance_time=stance, swing_time=swing, stance_fraction=stance / stride,
            swing_fraction=swing / stride, step_time=step, cadence=2.0 / stride,
            double_support_time=double, double_support_fraction=double / stride,
            step_time_symmetry_index=self.symmetry_index(), plausible=plausible, flag="; ".join(flags))

    def symmetry_index(self) -> float:
        """Symmetry index of the mean step times in the window (:func:`symmetry_index`)."""
        return symmetry_index(self._steps["left"], self._steps["right"])


def symmetry_index(left: Sequence[float], right: Sequence[float]) -> float:
    """``(L - R) / (0.5 (L + R))`` of the means of ``left`` and ``right``; NaN until both have one."""
    if not left or not right:
        return math.nan
    mean_left = sum(left) / len(left)
    mean_right = sum(right) / len(right)
    return (mean_left - mean_right) / (0.5 * (mean_left + mean_right))


def cycles_from_events(events: list[GaitEvent], **options: float) -> list[GaitCycle]:
    """Batch: all strides of a list of both feet's events (sorted here by detection time)."""
    tracker = GaitCycleTracker(**options)
    tracker.tracking = {e.side for e in events}
    out = []
    for event in sorted(events, key=lambda e: (e.detected_ns, e.stamp_ns)):
        cycle = tracker.add(event)
        if cycle is not None:
            out.append(cycle)
    return out


def cycles_from_event_times(events: Mapping[str, Mapping[str, Sequence[float]]], rate_hz: float,
                            **options: float) -> list[GaitCycle]:
    """Batch: the strides of both feet's event times, ``{side: {"ic": [s], "tc": [s]}}`` as
    :func:`~gait_biofeedback.core.gait.detect.detect_gait_events` gives them (each event confirmed one
    sample later, as live)."""
    detected = []
    for side, per_kind in events.items():
        for kind in (INITIAL_CONTACT, TERMINAL_CONTACT):
            for index, t in enumerate(per_kind.get(kind, ())):
                stamp_ns = s_to_ns(float(t))
                confirmed_ns = stamp_ns + s_to_ns(1.0 / rate_hz)
                detected.append(GaitEvent(side, kind, stamp_ns, confirmed_ns, 0.0, index))
    return cycles_from_events(detected, **options)
