"""``joint_states`` (sensor_msgs/JointState, names from JOINT_NAMES, rad) and the ``skeleton``
stick figure (visualization_msgs/MarkerArray) ↔ the core's joint-angle stream.

JointState has no quality field and joint states have no frame, so the header's ``frame_id`` carries
the project's one mark: empty normally, ``"recovering: <segments>"`` when the orientation of those
segments was being re-acquired after a sensor dropout. Such angles are shown (marked) and recorded,
but no biofeedback is computed from them (:func:`recovering_of`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from geometry_msgs.msg import Point
from sensor_msgs.msg import JointState
from visualization_msgs.msg import Marker, MarkerArray

from gait_biofeedback.core.body import BodyDimensions
from gait_biofeedback.core.joints.angles import segment_orientations
from gait_biofeedback.core.joints.skeleton import stick_figure
from gait_biofeedback.core.joints.stream import SyncedAngles
from gait_biofeedback.core.segments import WORLD_FRAME
from gait_biofeedback.wire.stamps import ns_to_stamp, stamp_to_ns

RECOVERING = "recovering: "


def joint_state_msg(angles: Mapping[str, float], stamp_ns: int,
                    recovering: Sequence[str] = ()) -> JointState:
    """``joint_states`` of one instant (names from JOINT_NAMES, rad, stamp = the samples' stamp),
    marked when segments were ``recovering`` (module docstring)."""
    msg = JointState(name=list(angles), position=[float(v) for v in angles.values()])
    msg.header.stamp = ns_to_stamp(stamp_ns)
    if recovering:
        msg.header.frame_id = RECOVERING + ",".join(recovering)
    return msg


def recovering_of(msg: JointState) -> tuple[str, ...]:
    """The segments a ``joint_states`` message is marked as recovering (empty: not marked)."""
    frame = msg.header.frame_id
    return tuple(frame[len(RECOVERING):].split(",")) if frame.startswith(RECOVERING) else ()


def angles_of(msg: JointState) -> tuple[int, dict[str, float]]:
    """(stamp ns, name → angle rad) of a ``joint_states`` message."""
    return stamp_to_ns(msg.header.stamp), dict(zip(msg.name, msg.position, strict=False))


def skeleton_msg(synced: SyncedAngles, body: BodyDimensions) -> MarkerArray:
    """``skeleton`` stick figure (one LINE_LIST in "world", pelvis at the origin) of one instant."""
    m = Marker(ns="skeleton", id=0, type=Marker.LINE_LIST, action=Marker.ADD)
    m.header.stamp = ns_to_stamp(synced.ns)
    m.header.frame_id = WORLD_FRAME
    m.pose.orientation.w = 1.0
    m.scale.x = 0.02
    m.color.r, m.color.g, m.color.b, m.color.a = 0.1, 0.6, 1.0, 1.0
    orientations = segment_orientations(synced.sensor_quats, synced.rotations)
    for _seg, a, b in stick_figure(orientations, body):
        m.points.append(Point(x=float(a[0]), y=float(a[1]), z=float(a[2])))
        m.points.append(Point(x=float(b[0]), y=float(b[1]), z=float(b[2])))
    return MarkerArray(markers=[m])
