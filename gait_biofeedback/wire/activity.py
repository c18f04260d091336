"""``activity/state`` (ActivityState) ↔ the core's activity state; the message's enum tables, both ways."""

from __future__ import annotations

from gait_biofeedback.core.activity.monitor import ActivityState as CoreActivityState
from gait_biofeedback.wire.stamps import ns_to_stamp, stamp_to_ns
from gait_biofeedback_msgs.msg import ActivityState

POSTURE_CODES = {"standing": ActivityState.POSTURE_STANDING, "sitting": ActivityState.POSTURE_SITTING,
                 "lying": ActivityState.POSTURE_LYING}
LOCOMOTION_CODES = {"none": ActivityState.LOCOMOTION_NONE, "level": ActivityState.LOCOMOTION_LEVEL,
                    "upstairs": ActivityState.LOCOMOTION_UPSTAIRS,
                    "downstairs": ActivityState.LOCOMOTION_DOWNSTAIRS}
TRANSITION_CODES = {None: ActivityState.TRANSITION_NONE,
                    "sit_to_stand": ActivityState.TRANSITION_SIT_TO_STAND,
                    "stand_to_sit": ActivityState.TRANSITION_STAND_TO_SIT,
                    "sit_to_lie": ActivityState.TRANSITION_SIT_TO_LIE,
                    "lie_to_sit": ActivityState.TRANSITION_LIE_TO_SIT,
                    "stand_to_lie": ActivityState.TRANSITION_STAND_TO_LIE,
                    "lie_to_stand": ActivityState.TRANSITION_LIE_TO_STAND}
POSTURE_NAMES = {ActivityState.POSTURE_UNKNOWN: "unknown"} | {c: name for name, c in POSTURE_CODES.items()}
LOCOMOTION_NAMES = {code: name for name, code in LOCOMOTION_CODES.items()}
TRANSITION_NAMES = {code: name for name, code in TRANSITION_CODES.items()}


def activity_msg(state: CoreActivityState, newest_ns: int, frame_id: str) -> ActivityState:
    """The message of a core state (stamp = the sample it describes; ``delay`` = to the newest input)."""
    msg = ActivityState(posture=POSTURE_CODES[state.posture], locomotion=LOCOMOTION_CODES[state.locomotion],
                        last_transition=TRANSITION_CODES[state.last_transition],
                        step_count=int(state.step_count), trunk_inclination=float(state.trunk_inclination),
                        delay=(newest_ns - state.stamp_ns) / 1e9)
    msg.header.stamp = ns_to_stamp(state.stamp_ns)
    msg.header.frame_id = frame_id
    if state.last_transition_ns is not None:
        msg.last_transition_stamp = ns_to_stamp(state.last_transition_ns)
    return msg


def state_of(msg: ActivityState) -> dict[str, object]:
    """Plain fields of a message (names, not codes; stamps in ns; None for no transition)."""
    return {"posture": POSTURE_NAMES.get(msg.posture, "unknown"),
            "locomotion": LOCOMOTION_NAMES.get(msg.locomotion, "none"),
            "last_transition": TRANSITION_NAMES.get(msg.last_transition),
            "last_transition_ns": stamp_to_ns(msg.last_transition_stamp), "step_count": int(msg.step_count),
            "trunk_inclination": float(msg.trunk_inclination), "stamp_ns": stamp_to_ns(msg.header.stamp)}


def add_transition(transitions: list[tuple[int, int]], msg: ActivityState) -> None:
    """Append ``msg``'s last transition (stamp ns, TRANSITION_* code) to ``transitions`` when it is new.
    One with the stamp of the last one replaces it: the monitor merges stand→sit then sit→lie into
    one stand→lie (lie→sit then sit→stand into lie→stand) at the first one's stamp, after that one
    may have been published (core/activity/monitor.py ``_add_transition``)."""
    if not msg.last_transition:
        return
    mark = (stamp_to_ns(msg.last_transition_stamp), int(msg.last_transition))
    if transitions and transitions[-1][0] == mark[0]:
        transitions[-1] = mark
    else:
        transitions.append(mark)
