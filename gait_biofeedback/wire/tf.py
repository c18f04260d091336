"""``/tf`` (tf2_msgs/msg/TFMessage): the body's segment frames
(:mod:`~gait_biofeedback.core.joints.body_pose`) as XCDR1 little-endian bytes, encoded in bulk.

tf2_msgs is not among the PyPI ROS wheels, so nothing here needs its rclpy class: the bytes are laid
out by hand (one structured numpy record per message, as :func:`~gait_biofeedback.wire.cdr.encode_stamped`
does) and the schema text is the one-line definition of tf2_msgs (``geometry_msgs/TransformStamped[]
transforms``, :mod:`gait_biofeedback.io.schemas`). Every transform of one message has the instant's stamp.
CDR (OMG XTypes 1.3 §7.4.3.5, XCDR1): sequence length uint32; per TransformStamped: stamp int32 sec,
uint32 nanosec, frame_id and child_frame_id as uint32 length with the NUL then the bytes, then, 8-aligned
from the end of the 4-byte encapsulation, translation x, y, z and rotation x, y, z, w as float64.
"""

from __future__ import annotations

import struct

import numpy as np

from gait_biofeedback.core.joints.body_pose import BODY_FRAMES
from gait_biofeedback.core.stamps import NS_PER_S
from gait_biofeedback.wire.padding import CDR_LE

TF_TYPE = "tf2_msgs/msg/TFMessage"
TF_TOPIC = "/tf"
_dtypes: dict[int, np.dtype] = {}


def _string_fields(name: str, text: bytes, pos: int) -> tuple[list[tuple], int]:
    pad = -pos % 4
    fields = [(f"{name}_pad", f"V{pad}")] if pad else []
    return [*fields, (f"{name}_len", "<u4"), (name, f"S{len(text) + 1}")], pos + pad + 4 + len(text) + 1


def tf_dtype(mask: int) -> np.dtype:
    """The packed record of one TFMessage holding the :data:`BODY_FRAMES` whose bit is set in ``mask``."""
    found = _dtypes.get(mask)
    if found is not None:
        return found
    fields: list[tuple] = [("enc", "S4"), ("count", "<u4")]
    pos = 4  # after the encapsulation
    for k, (child, parent) in enumerate(BODY_FRAMES):
        if not mask >> k & 1:
            continue
        fields += [(f"sec{k}", "<i4"), (f"nanosec{k}", "<u4")]  # pos is 4-aligned here
        part, pos = _string_fields(f"parent{k}", parent.encode(), pos + 8)
        fields += part
        part, pos = _string_fields(f"child{k}", child.encode(), pos)
        fields += part
        if pos % 8:
            fields.append((f"pad{k}", f"V{-pos % 8}"))
            pos += -pos % 8
        fields.append((f"d{k}", "<f8", (7,)))
        pos += 56
    dtype = np.dtype(fields)
    _dtypes[mask] = dtype
    return dtype


def tf_messages(stamps_ns: np.ndarray, trans: np.ndarray, rot: np.ndarray, present: np.ndarray
                ) -> list[bytes]:
    """One TFMessage per instant (stamps (N,) ns; translations (N, 8, 3) m, rotations (N, 8, 4) w, x, y,
    z and present (N, 8) of :func:`~gait_biofeedback.core.joints.body_pose.body_transforms`) holding its
    present frames; b"" for an instant with none."""
    stamps_ns = np.asarray(stamps_ns, dtype=np.int64)
    n = len(stamps_ns)
    out = [b""] * n
    if not n:
        return out
    sec, nanosec = np.divmod(stamps_ns, NS_PER_S)
    if sec.min() < -(2**31) or sec.max() >= 2**31:
        raise ValueError("time stamps do not fit builtin_interfaces/Time (int32 seconds)")
    doubles = np.concatenate([trans, rot[..., [1, 2, 3, 0]]], axis=2)  # x, y, z, qx, qy, qz, qw
    masks = (np.asarray(present, dtype=np.int64) << np.arange(len(BODY_FRAMES))).sum(axis=1)
    for mask in np.unique(masks).tolist():
        if not mask:
            continue
        rows = np.flatnonzero(masks == mask)
        dtype = tf_dtype(mask)
        records = np.zeros(len(rows), dtype=dtype)
        records["enc"], records["count"] = CDR_LE, bin(mask).count("1")
        for k, (child, parent) in enumerate(BODY_FRAMES):
            if not mask >> k & 1:
                continue
            records[f"sec{k}"], records[f"nanosec{k}"] = sec[rows], nanosec[rows]
            records[f"parent{k}_len"], records[f"parent{k}"] = len(parent) + 1, parent.encode()
            records[f"child{k}_len"], records[f"child{k}"] = len(child) + 1, child.encode()
            records[f"d{k}"] = doubles[rows, k]
        blob, size = records.tobytes(), dtype.itemsize
        for j, i in enumerate(rows.tolist()):
            out[i] = blob[j * size:(j + 1) * size]
    return out



def tf_message(stamp_ns: int, trans: list, rot: list, present: list) -> bytes:
    """One instant's TFMessage (:func:`~gait_biofeedback.core.joints.body_pose.body_transforms_at`'s
    translations, rotations w, x, y, z and present flags): the bytes :func:`tf_messages` gives, its
    stamps and doubles packed into a copy of the layout's constant bytes (b"" when no frame is present)."""
    mask = sum(1 << k for k, here in enumerate(present) if here)
    if not mask:
        return b""
    found = _templates.get(mask)
    if found is None:
        found = _templates[mask] = _template(mask)
    template, places = found
    sec, nanosec = divmod(int(stamp_ns), NS_PER_S)
    out = bytearray(template)
    for k, at_stamp, at_doubles in places:
        (x, y, z), (w, qx, qy, qz) = trans[k], rot[k]
        _STAMP.pack_into(out, at_stamp, sec, nanosec)
        _DOUBLES.pack_into(out, at_doubles, x, y, z, qx, qy, qz, w)
    return bytes(out)


_STAMP = struct.Struct("<iI")
_DOUBLES = struct.Struct("<7d")
_templates: dict[int, tuple[bytes, list[tuple[int, int, int]]]] = {}


def _template(mask: int) -> tuple[bytes, list[tuple[int, int, int]]]:
    """(the record of ``mask`` with its constant fields and zero stamps and doubles, [(frame index, offset
    of its stamp, offset of its doubles)])."""
    dtype = tf_dtype(mask)
    frames = [k for k in range(len(BODY_FRAMES)) if mask >> k & 1]
    record = tf_messages([0], np.zeros((1, len(BODY_FRAMES), 3)), np.zeros((1, len(BODY_FRAMES), 4)),
                         np.array([[bool(mask >> k & 1) for k in range(len(BODY_FRAMES))]]))[0]
    places = [(k, dtype.fields[f"sec{k}"][1], dtype.fields[f"d{k}"][1]) for k in frames]
    return record, places
