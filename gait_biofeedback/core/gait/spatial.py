"""Each IC→IC stride with the spatial values of the same stride of the foot's trajectory (issue 16).

The foot trajectory (:class:`~gait_biofeedback.core.spatial.stream.FootTrajectoryStream`) cuts the
walk from stance to stance (zero velocity), the gait events from IC to IC. The trajectory stride
whose foot-off lies in the IC→IC stride, and whose next stance (foot flat) begins after the closing
IC (less ``EARLY_FOOT_FLAT_S``, the events' own timing error), is the same stride; the stride's
message waits for it at most ``wait_s`` (the ``gait_events`` parameter ``spatial_wait_s``) after the
closing IC. The next stance is needed to close the trajectory stride: the detector finds foot flat
0.1-0.3 s after IC (about 0.28 s on gaitmap_example's real gait), and the trajectory closes it
``close_after_s`` + 25 ms later.

Never silently wrong: without exactly one such trajectory stride the stride gets NaN spatial values
and a ``spatial_flag``:

- none by the deadline: no stance was found after the closing IC (a missed stance, a shuffle);
- the trajectory stride carries a problem flag (no stance for longer than ``max_swing_s``);
- its foot-off is before the opening IC: it spans more than one IC→IC stride (a missed stance).

A flag that only informs (``started from standing``, ``no direction of travel``, ``lost samples
interpolated``) keeps the values.
``gait_speed`` is the stride length over the IC→IC stride time.

Provisional values (``provisional_after_s``): waiting for the next stance delays the stride's message,
temporal values included, by 0.28-0.46 s, longer than a cue may lag. So at the last sample at or
before ``provisional_after_s`` past the closing IC, the foot trajectory is asked for a provisional
stride (:mod:`gait_biofeedback.core.spatial.provisional`) of the swing that left its stance inside the
IC→IC stride. With one, the stride goes out then with all its spatial values provisional
(``stride_length`` and ``gait_speed``; ``max_foot_height``, ``min_toe_clearance``, ``foot_angle_ic``,
``foot_angle_tc``, ``turning_angle`` and ``lateral_excursion`` each NaN while the foot's estimates of it
disagree with the smoothed values), and its smoothed values follow as a *revision* once its trajectory
stride is in, by the rules above (NaN and the flag when there is none by the deadline). Without one
(the foot's first strides, lost samples, a swing that left before the opening IC, estimates that
disagreed with their smoothed values: ``provisional_tolerance_m``), the stride waits for the smoothed
values as before.

The default 15 ms puts the message 45-50 ms after the IC's raw sample entered the graph: the
orientation filter's ``reorder_window_s`` (30 ms) comes before this stage. The foot trajectory, 25 ms
behind its newest sample, is then at IC - 10 ms. Through ``analyze`` on gaitmap_example
(``benchmarks/spatial.py --cli-only``): provisional stride length +0.2 ± 3.7 cm (mean abs 2.4 cm)
on 51 of 61 strides, published 49 ms after the IC; the smoothed values of record −0.2 ± 2.9 cm at
278-459 ms (``docs/benchmarks/spatial.md``, Latency, for other ``provisional_after_s``).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable

from gait_biofeedback.core.gait.cycles import GaitCycle, StrideSpace
from gait_biofeedback.core.spatial.provisional import ProvisionalStride
from gait_biofeedback.core.spatial.strides import LOST_FLAG, SpatialStride
from gait_biofeedback.core.stamps import NS_PER_S

EARLY_FOOT_FLAT_S = 0.05  # s: foot flat found before the IC the events found, still the same stride
INFORMATIONAL = ("started from standing", "no direction of travel", LOST_FLAG)


def stride_space(cycle: GaitCycle, stride: SpatialStride) -> StrideSpace:
    """The spatial values of ``cycle`` from its trajectory stride (NaN with a flag if it has a problem)."""
    problems = [f for f in stride.flags if f not in INFORMATIONAL]
    if problems:
        return StrideSpace(flag="; ".join(problems))
    length = stride.stride_length
    return StrideSpace(stride_length=length, gait_speed=length / cycle.stride_time,
                       max_foot_height=stride.max_sensor_height, min_toe_clearance=stride.min_toe_clearance,
                       foot_angle_ic=stride.foot_angle_ic, foot_angle_tc=stride.foot_angle_tc,
                       turning_angle=stride.turning_angle, lateral_excursion=stride.lateral_excursion)


Provisional = Callable[[], "ProvisionalStride | None"]
Decided = tuple[GaitCycle, StrideSpace, bool]  # (stride, its spatial values, a revision)


class SpatialPairing:
    """One foot: holds its IC→IC strides until their trajectory stride is in, or until a provisional
    value is asked for (module docstring). ``provisional_after_s`` None: no provisional values."""

    def __init__(self, wait_s: float, provisional_after_s: float | None = None,
                 period_s: float = 0.01) -> None:
        self.wait_ns = round(wait_s * NS_PER_S)
        self._early_ns = round(EARLY_FOOT_FLAT_S * NS_PER_S)
        self._after_ns = None if provisional_after_s is None else round(provisional_after_s * NS_PER_S)
        self._period_ns = round(period_s * NS_PER_S)
        self._held: deque[GaitCycle] = deque()
        self._asked: int | None = None  # closing IC of the held stride that had no provisional value
        self._revise: deque[GaitCycle] = deque()  # out with provisional values
        self._strides: deque[SpatialStride] = deque(maxlen=8)

    @property
    def waiting(self) -> bool:
        """A stride or a revision is held: :meth:`due` looks at the trajectory strides and may ask for a
        provisional value."""
        return bool(self._held or self._revise)

    def add_cycle(self, cycle: GaitCycle) -> None:
        self._held.append(cycle)

    def add_stride(self, stride: SpatialStride) -> None:
        self._strides.append(stride)

    def due(self, now_ns: int, provisional: Provisional | None = None) -> list[Decided]:
        """The strides and revisions decided at stamp ``now_ns``, oldest first; ``provisional``: the
        foot trajectory's :meth:`~gait_biofeedback.core.spatial.stream.FootTrajectoryStream.provisional`."""
        out: list[Decided] = []
        while self._revise and (space := self._decide(self._revise[0], now_ns)) is not None:
            out.append((self._revise.popleft(), space, True))
        while self._held:
            cycle = self._held[0]
            space = self._decide(cycle, now_ns)
            if space is None and provisional is not None:
                space = self._provisional(cycle, now_ns, provisional)
                if space is not None:
                    self._revise.append(cycle)
            if space is None:
                break
            out.append((self._held.popleft(), space, False))
        return out

    def _provisional(self, cycle: GaitCycle, now_ns: int, provisional: Provisional) -> StrideSpace | None:
        """Asked once, at the last sample at or before ``provisional_after_s`` past the closing IC."""
        if (self._after_ns is None or self._asked == cycle.end_ns
                or now_ns + self._period_ns <= cycle.end_ns + self._after_ns):
            return None
        self._asked = cycle.end_ns
        value = provisional()
        if value is None or not cycle.start_ns <= value.foot_off_ns < cycle.end_ns:
            return None
        length = value.stride_length
        return StrideSpace(stride_length=length, gait_speed=length / cycle.stride_time,
                           max_foot_height=value.max_sensor_height, min_toe_clearance=value.min_toe_clearance,
                           foot_angle_ic=value.foot_angle_ic, foot_angle_tc=value.foot_angle_tc,
                           turning_angle=value.turning_angle, lateral_excursion=value.lateral_excursion,
                           provisional=True)

    def release(self, why: str) -> list[Decided]:
        """Every held stride and pending revision at once, without spatial values (``why``: the foot
        was reset)."""
        out = [(cycle, StrideSpace(flag=why), False) for cycle in self._held]
        out += [(cycle, StrideSpace(flag=why), True) for cycle in self._revise]
        self._held.clear()
        self._revise.clear()
        self._strides.clear()
        return out

    def _decide(self, cycle: GaitCycle, now_ns: int) -> StrideSpace | None:
        for stride in self._strides:
            if stride.foot_flat_ns < cycle.end_ns - self._early_ns:
                continue
            if stride.foot_off_ns < cycle.start_ns:
                return StrideSpace(flag="a stance was missed: the foot trajectory's stride began before "
                                   "this stride's initial contact")
            if stride.foot_off_ns < cycle.end_ns:
                return stride_space(cycle, stride)
        if now_ns >= cycle.end_ns + self.wait_ns:
            return StrideSpace(flag=f"no stance of the foot within {self.wait_ns / NS_PER_S:g} s after the "
                               "initial contact (foot not still)")
        return None

