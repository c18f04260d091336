"""``gait/events`` (GaitEvent), ``gait/cycles`` (GaitCycle) and ``gait/stride_space`` (StrideSpace) ↔
the core's events and strides.

The enum tables of the messages live here and only here: side (SIDE_LEFT/SIDE_RIGHT) and event type
(INITIAL_CONTACT/TERMINAL_CONTACT), both ways.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from builtin_interfaces.msg import Time

from gait_biofeedback.core.biofeedback.evaluator import Stride
from gait_biofeedback.core.gait.cycles import GaitCycle
from gait_biofeedback.core.gait.events import INITIAL_CONTACT, TERMINAL_CONTACT, GaitEvent
from gait_biofeedback.wire import topics
from gait_biofeedback.wire.stamps import ns_to_stamp, stamp_to_ns
from gait_biofeedback_msgs.msg import GaitCycle as GaitCycleMsg
from gait_biofeedback_msgs.msg import GaitEvent as GaitEventMsg
from gait_biofeedback_msgs.msg import StrideSpace as StrideSpaceMsg

SIDE_CODES = {"left": GaitEventMsg.SIDE_LEFT, "right": GaitEventMsg.SIDE_RIGHT}
SIDE_NAMES = {code: side for side, code in SIDE_CODES.items()}
KIND_CODES = {INITIAL_CONTACT: GaitEventMsg.INITIAL_CONTACT, TERMINAL_CONTACT: GaitEventMsg.TERMINAL_CONTACT}
KIND_NAMES = {code: kind for kind, code in KIND_CODES.items()}
_CYCLE_FIELDS = ("stride_time", "stance_time", "swing_time", "stance_fraction", "swing_fraction", "step_time",
                 "cadence", "double_support_time", "double_support_fraction", "step_time_symmetry_index")
_SPACE_FIELDS = ("stride_length", "gait_speed", "max_foot_height", "min_toe_clearance", "foot_angle_ic",
                 "foot_angle_tc", "turning_angle", "lateral_excursion")


def foot_frame(side: str) -> str:
    """header.frame_id of a foot's events and strides."""
    return f"{side}_foot"


def event_msg(event: GaitEvent) -> GaitEventMsg:
    """``gait/events`` message of a core event (stamp = the event sample's stamp)."""
    out = GaitEventMsg(side=SIDE_CODES[event.side], type=KIND_CODES[event.kind],
                       detection_latency=float(event.latency), signal_value=float(event.signal),
                       event_index=int(event.index), flag=event.flag)
    out.header.stamp = ns_to_stamp(event.stamp_ns)
    out.header.frame_id = foot_frame(event.side)
    return out


def truth_event_msg(side: str, kind: str, stamp_ns: int, index: int) -> GaitEventMsg:
    """A ground-truth event (a simulator's exact IC/TC)."""
    out = GaitEventMsg(side=SIDE_CODES[side], type=KIND_CODES[kind], event_index=index)
    out.header.stamp = ns_to_stamp(stamp_ns)
    out.header.frame_id = foot_frame(side)
    return out


def event_of(msg: GaitEventMsg) -> tuple[str, str, int, int]:
    """(side, kind "ic"/"tc", stamp ns, index) of a ``gait/events`` message."""
    return SIDE_NAMES[msg.side], KIND_NAMES[msg.type], stamp_to_ns(msg.header.stamp), int(msg.event_index)


def _stamp(ns: int | None) -> Time:
    return Time() if ns is None else ns_to_stamp(ns)


def cycle_msg(c: GaitCycle) -> GaitCycleMsg:
    """``gait/cycles`` message of a core stride (header.stamp = its closing IC; an empty
    terminal_contact when the stride has no single TC)."""
    out = GaitCycleMsg(side=SIDE_CODES[c.side], stride_index=c.index, plausible=bool(c.plausible),
                       flag=c.flag)
    out.header.stamp = ns_to_stamp(c.end_ns)
    out.header.frame_id = foot_frame(c.side)
    out.start = ns_to_stamp(c.start_ns)
    out.terminal_contact = _stamp(c.terminal_contact_ns)
    for name in _CYCLE_FIELDS:
        setattr(out, name, float(getattr(c, name)))
    _set_space(out, c)
    out.spatial_provisional = bool(c.space.provisional)
    return out


def _set_space(out: GaitCycleMsg | StrideSpaceMsg, c: GaitCycle) -> None:
    for name in _SPACE_FIELDS:
        setattr(out, name, float(getattr(c.space, name)))
    out.spatial_flag = c.space.flag


def stride_space_msg(c: GaitCycle) -> StrideSpaceMsg:
    """``gait/stride_space`` message of a stride's revision: its smoothed spatial values (header.stamp =
    its closing IC, as its ``gait/cycles`` message)."""
    out = StrideSpaceMsg(side=SIDE_CODES[c.side], stride_index=c.index)
    out.header.stamp = ns_to_stamp(c.end_ns)
    out.header.frame_id = foot_frame(c.side)
    _set_space(out, c)
    return out


def stride_output(c: GaitCycle) -> tuple[topics.Topic, GaitCycleMsg | StrideSpaceMsg]:
    """Where a stride from :class:`~gait_biofeedback.core.gait.stream.GaitEventStream` goes: a new
    stride on ``gait/cycles``, a revision on ``gait/stride_space``."""
    return (topics.STRIDE_SPACE, stride_space_msg(c)) if c.revision else (topics.GAIT_CYCLES, cycle_msg(c))


def revised_cycles(messages: Iterable[tuple[str, Any]]) -> list[GaitCycleMsg]:
    """The ``gait/cycles`` messages among ``(topic, message)`` pairs in log order, each with the
    smoothed spatial values of its ``gait/stride_space`` revision (``spatial_provisional`` then
    False): the values of record. A provisional value whose revision never came stays flagged."""
    cycles, by_stride = [], {}
    for topic, msg in messages:
        if topic == topics.GAIT_CYCLES.absolute():
            cycles.append(msg)
            by_stride[(msg.side, msg.stride_index)] = msg
        elif topic == topics.STRIDE_SPACE.absolute() and (msg.side, msg.stride_index) in by_stride:
            cycle = by_stride[(msg.side, msg.stride_index)]
            for name in (*_SPACE_FIELDS, "spatial_flag"):
                setattr(cycle, name, getattr(msg, name))
            cycle.spatial_provisional = False
    return cycles


def stride_of(msg: GaitCycleMsg) -> Stride:
    """The biofeedback evaluator's view of a ``gait/cycles`` message."""
    tc = msg.terminal_contact
    return Stride(side=SIDE_NAMES[msg.side], index=int(msg.stride_index), start_ns=stamp_to_ns(msg.start),
                  tc_ns=None if (tc.sec, tc.nanosec) == (0, 0) else stamp_to_ns(tc),
                  end_ns=stamp_to_ns(msg.header.stamp), stance_fraction=float(msg.stance_fraction),
                  cadence=float(msg.cadence), step_time_symmetry=float(msg.step_time_symmetry_index),
                  plausible=bool(msg.plausible), step_time=float(msg.step_time),
                  stride_length=float(msg.stride_length),
                  gait_speed=float(msg.gait_speed), spatial_flag=msg.spatial_flag,
                  max_foot_height=float(msg.max_foot_height), foot_angle_ic=float(msg.foot_angle_ic),
                  turning_angle=float(msg.turning_angle))
