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
from sensor_msgs.msg import JointState
from visualization_msgs.msg import Marker, MarkerArray

from gait_biofeedback.core.body import BodyDimensions
from gait_biofeedback.core.joints.angles import segment_orientations
from gait_biofeedback.core.joints.skeleton import stick_figure
from gait_biofeedback.core.joints.stream import SyncedAngles
from gait_biofeedback.core.segments import WORLD_FRAME
from gait_biofeedback.wire.cdr import header_stamp_ns
from gait_biofeedback.wire.padding import CDR_LE
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


JOINT_STATE_TYPE = "sensor_msgs/msg/JointState"
_U32 = struct.Struct("<I")
_STAMP = struct.Struct("<iI")


def _string_bytes(text: bytes, pos: int) -> tuple[bytes, int]:
    """A CDR string at offset ``pos`` (after the encapsulation): padding to 4, length with the NUL,
    the bytes, the NUL; and the offset after it."""
    pad = -pos % 4
    return bytes(pad) + _U32.pack(len(text) + 1) + text + b"\0", pos + pad + 5 + len(text)


def joint_state_bytes(angles: Mapping[str, float], stamp_ns: int, recovering: Sequence[str] = ()) -> bytes:
    """:func:`joint_state_msg` (names without NUL) as XCDR1 little-endian bytes, padding 0, exact size
    (header, ``name``, ``position``, empty ``velocity`` and ``effort``), written without an rclpy
    message: ``analyze`` writes one per instant. For one with angles, what
    :func:`~gait_biofeedback.wire.cdr.serialize` gives (test/test_cdr.py compares them with rclpy's)."""
    stamp = ns_to_stamp(stamp_ns)
    frame = (RECOVERING + ",".join(recovering)).encode("utf-8") if recovering else b""
    parts = [CDR_LE, _STAMP.pack(stamp.sec, stamp.nanosec)]
    part, pos = _string_bytes(frame, 8)
    parts.append(part)
    pad = -pos % 4
    parts.append(bytes(pad) + _U32.pack(len(angles)))
    pos += pad + 4
    for name in angles:
        part, pos = _string_bytes(name.encode("utf-8"), pos)
        parts.append(part)
    pad = -pos % 4
    parts.append(bytes(pad) + _U32.pack(len(angles)))
    pos += pad + 4
    if angles:
        pad = -pos % 8
        parts.append(bytes(pad) + struct.pack(f"<{len(angles)}d", *map(float, angles.values())))
        pos += pad + 8 * len(angles)
    for _ in ("velocity", "effort"):
        pad = -pos % 4
        parts.append(bytes(pad) + _U32.pack(0))
        pos += pad + 4
    return b"".join(parts)


def joint_state_angles(data: bytes) -> tuple[int, dict[str, float]] | None:
    """:func:`angles_of` read straight from a ``joint_states`` message's CDR bytes (XCDR1 little
    endian, as the project writes them); None for other bytes (another encoding, a velocity or effort,
    a truncated message): decode those with rclpy."""
    try:
        if data[:2] != CDR_LE[:2] or (stamp_ns := header_stamp_ns(data)) is None:
            return None
        pos = 8 + 4 + _U32.unpack_from(data, 12)[0]  # past the frame_id
        pos += -pos % 4
        n = _U32.unpack_from(data, 4 + pos)[0]
        pos += 4
        names = []
        for _ in range(n):
            pos += -pos % 4
            size = _U32.unpack_from(data, 4 + pos)[0]
            text = data[8 + pos:8 + pos + size]
            if not size or len(text) != size or text.find(0) != size - 1:
                return None  # not one NUL, at the end: rclpy's reading of it
            names.append(str(text[:-1], "utf-8"))
            pos += 4 + size
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
    except (struct.error, UnicodeDecodeError):
        return None
    return stamp_ns, dict(zip(names, values, strict=True))


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
