"""Each IC→IC stride with the spatial values of the same stride of the foot's trajectory (issue 16).

The foot trajectory (:class:`~gait_biofeedback.core.spatial.stream.FootTrajectoryStream`) cuts the
walk from stance to stance (zero velocity), the gait events from IC to IC. The trajectory stride
whose foot-off lies in the IC→IC stride, and whose next stance (foot flat) begins after the closing
IC (less ``EARLY_FOOT_FLAT_S``, the events' own timing error), is the same stride; the stride's
message waits for it at most ``wait_s`` (the ``gait_events`` parameter ``spatial_wait``) after the
closing IC. The next stance is needed to close the trajectory stride: the detector finds foot flat
0.1-0.3 s after IC (about 0.28 s on gaitmap_example's real gait), and the trajectory closes it
``close_after`` + 25 ms later.

Never silently wrong: without exactly one such trajectory stride the stride gets NaN spatial values
and a ``spatial_flag``:

- none by the deadline: no stance was found after the closing IC (a missed stance, a shuffle);
- the trajectory stride carries a problem flag (no stance for longer than ``max_swing``);
- its foot-off is before the opening IC: it spans more than one IC→IC stride (a missed stance).

A flag that only informs (``started from standing``, ``no direction of travel``, ``lost samples
interpolated``) keeps the values.
``gait_speed`` is the stride length over the IC→IC stride time.
"""

from __future__ import annotations

from collections import deque

from gait_biofeedback.core.gait.cycles import GaitCycle, StrideSpace
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


class SpatialPairing:
    """One foot: holds its IC→IC strides until their trajectory stride is in (module docstring)."""

    def __init__(self, wait_s: float) -> None:
        self.wait_ns = round(wait_s * NS_PER_S)
        self._early_ns = round(EARLY_FOOT_FLAT_S * NS_PER_S)
        self._held: deque[GaitCycle] = deque()
        self._strides: deque[SpatialStride] = deque(maxlen=8)

    def add_cycle(self, cycle: GaitCycle) -> None:
        self._held.append(cycle)

    def add_stride(self, stride: SpatialStride) -> None:
        self._strides.append(stride)

    def due(self, now_ns: int) -> list[tuple[GaitCycle, StrideSpace]]:
        """The held strides that are decided at stamp ``now_ns``, oldest first."""
        out = []
        while self._held:
            cycle = self._held[0]
            space = self._decide(cycle, now_ns)
            if space is None:
                break
            out.append((self._held.popleft(), space))
        return out

    def release(self, why: str) -> list[tuple[GaitCycle, StrideSpace]]:
        """Every held stride at once, without spatial values (``why``: the foot was reset)."""
        out = [(cycle, StrideSpace(flag=why)) for cycle in self._held]
        self._held.clear()
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

