"""``joint_states`` (sensor_msgs/JointState, names from JOINT_NAMES, rad) and the ``skeleton``
stick figure (visualization_msgs/MarkerArray) ↔ the core's joint-angle stream.

JointState has no quality field and joint states have no frame, so the header's ``frame_id`` carries
the project's one mark: empty normally, ``"recovering: <segments>"`` when the orientation of those
segments was being re-acquired after a sensor dropout. Such angles are shown (marked) and recorded,
but no biofeedback is computed from them (:func:`recovering_of`).
"""

from __future__ import annotations

import struct
from collections.abc import Mapping, Sequence

from geometry_msgs.msg import Point
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from visualization_msgs.msg import Marker, MarkerArray

from gait_biofeedback.core.body import BodyDimensions
from gait_biofeedback.core.joints.angles import segment_orientations
from gait_biofeedback.core.joints.skeleton import stick_figure
from gait_biofeedback.core.joints.stream import SyncedAngles
from gait_biofeedback.core.segments import WORLD_FRAME
from gait_biofeedback.core.stamps import NS_PER_S
from gait_biofeedback.wire.cdr import header_stamp_ns
from gait_biofeedback.wire.padding import CDR_LE
from gait_biofeedback.wire.stamps import ns_to_stamp, stamp_to_ns

RECOVERING = "recovering: "


JOINT_STATE_TYPE = "sensor_msgs/msg/JointState"
_U32 = struct.Struct("<I")
_STAMP = struct.Struct("<iI")
_NO_VELOCITY_NO_EFFORT = bytes(8)  # two empty sequences; the offset is 4-aligned after the positions
_layouts: dict[tuple[str, tuple[str, ...]], tuple[bytes, struct.Struct]] = {}


def joint_state_bytes(angles: Mapping[str, float], stamp_ns: int, recovering: Sequence[str] = ()) -> bytes:
    """``joint_states`` of one instant (names from JOINT_NAMES, without NUL; rad; stamp = the samples'
    stamp), marked when segments were ``recovering`` (module docstring): the message's one definition,
    as XCDR1 little-endian bytes, padding 0, exact size (header, ``name``, ``position``, empty
    ``velocity`` and ``effort``). What :func:`~gait_biofeedback.wire.cdr.serialize` gives for the same
    rclpy message (test/test_cdr.py compares them); the node publishes these bytes, ``analyze`` writes
    them, :func:`joint_state_msg` decodes them."""
    frame_id = RECOVERING + ",".join(recovering) if recovering else ""
    key = (frame_id, tuple(angles))
    found = _layouts.get(key)
    if found is None:
        found = _layout(*key)
        if len(_layouts) < 1024:
            _layouts[key] = found
    middle, positions = found
    sec, nanosec = divmod(int(stamp_ns), NS_PER_S)
    return b"".join((CDR_LE, _STAMP.pack(sec, nanosec), middle, positions.pack(*angles.values()),
                     _NO_VELOCITY_NO_EFFORT))


def joint_state_msg(angles: Mapping[str, float], stamp_ns: int,
                    recovering: Sequence[str] = ()) -> JointState:
    """:func:`joint_state_bytes` as an rclpy message (simulated ground truth, tests)."""
    return deserialize_message(joint_state_bytes(angles, stamp_ns, recovering), JointState)


def _layout(frame_id: str, names: tuple[str, ...]) -> tuple[bytes, struct.Struct]:
    """(the bytes of a JointState from ``frame_id`` to the padding before the positions, the positions'
    Struct) for these names: all but the stamp and the values, the same for every instant."""
    parts = []
    part, pos = _string_bytes(frame_id.encode("utf-8"), 8)
    parts.append(part)
    part, pos = _u32(len(names), pos)
    parts.append(part)
    for name in names:
        part, pos = _string_bytes(name.encode("utf-8"), pos)
        parts.append(part)
    part, pos = _u32(len(names), pos)  # the positions' count
    parts.append(part)
    if names:
        parts.append(bytes(-pos % 8))
    return b"".join(parts), struct.Struct(f"<{len(names)}d")


def _u32(n: int, pos: int) -> tuple[bytes, int]:
    """A CDR uint32 at offset ``pos`` (after the encapsulation), padded to 4; and the offset after it."""
    pad = -pos % 4
    return bytes(pad) + _U32.pack(n), pos + pad + 4


def _string_bytes(text: bytes, pos: int) -> tuple[bytes, int]:
    """A CDR string at offset ``pos``: its length with the NUL, the bytes, the NUL; and the offset after."""
    head, pos = _u32(len(text) + 1, pos)
    return head + text + b"\0", pos + len(text) + 1


def joint_state_of(data: bytes) -> tuple[int, dict[str, float], tuple[str, ...]] | None:
    """(:func:`angles_of`, :func:`recovering_of`) read straight from a ``joint_states`` message's CDR
    bytes (XCDR1 little endian, as the project writes them); None for other bytes (another encoding, a
    velocity or effort, a truncated message, a string rclpy reads its own way): decode those with rclpy."""
    try:
        if data[:2] != CDR_LE[:2] or (stamp_ns := header_stamp_ns(data)) is None:
            return None
        frame, pos = _read_string(data, 8)
        pos += -pos % 4
        n = _U32.unpack_from(data, 4 + pos)[0]
        pos += 4
        names = []
        for _ in range(n):
            name, pos = _read_string(data, pos)
            names.append(name)
        pos += -pos % 4
        if _U32.unpack_from(data, 4 + pos)[0] != n:
            return None
        pos += 4
        if n:
            pos += -pos % 8
        values = struct.unpack_from(f"<{n}d", data, 4 + pos)
        pos += 8 * n
        pos += -pos % 4
        if _U32.unpack_from(data, 4 + pos)[0] or _U32.unpack_from(data, 8 + pos)[0]:
            return None  # a velocity or an effort: not the project's form
    except (struct.error, ValueError):  # UnicodeDecodeError is one
        return None
    return stamp_ns, dict(zip(names, values, strict=True)), _recovering(frame)


def _read_string(data: bytes, pos: int) -> tuple[str, int]:
    """The CDR string at offset ``pos`` (after the encapsulation; padded to 4) and the offset after it;
    ValueError when its bytes do not end in their one NUL (rclpy reads those its own way)."""
    pos += -pos % 4
    size = _U32.unpack_from(data, 4 + pos)[0]
    text = data[8 + pos:8 + pos + size]
    if not size or len(text) != size or text.find(0) != size - 1:
        raise ValueError("not one NUL, at the end")
    return str(text[:-1], "utf-8"), pos + 4 + size


def recovering_of(msg: JointState) -> tuple[str, ...]:
    """The segments a ``joint_states`` message is marked as recovering (empty: not marked)."""
    return _recovering(msg.header.frame_id)


def _recovering(frame_id: str) -> tuple[str, ...]:
    return tuple(frame_id[len(RECOVERING):].split(",")) if frame_id.startswith(RECOVERING) else ()


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
