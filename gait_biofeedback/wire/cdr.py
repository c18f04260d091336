"""One stamped message ↔ its CDR bytes without rclpy objects: sensor_msgs/Imu and MagneticField.

The hot paths of the node graph (raw subscriptions, publishing serialized bytes), the offline
``analyze`` path and the bulk bag reader/writer (numpy, :func:`encode_stamped` /
:func:`decode_stamped`) all use this one layout, so they see exactly the same numbers: XCDR1 little
endian — encapsulation ``00 01 00 00``, int32 sec, uint32 nanosec, uint32 length of frame_id (with
its NUL), the frame_id bytes and NUL, zero padding so the doubles start 8-aligned (counted after the
encapsulation), then the float64 fields (Imu: 37, MagneticField: 12, in declaration order, see
:data:`ORIENTATION` …), as :func:`record_dtype` defines it.

:func:`unpack_stamped` returns None for anything else (big endian, XCDR2, a size that does not
match); :func:`decode_imu` / :func:`decode_mag` then fall back to rclpy's ``deserialize_message``.
"""

from __future__ import annotations

import struct
from functools import cache
from typing import Any, NamedTuple

import numpy as np
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu, MagneticField

from gait_biofeedback.core.stamps import NS_PER_S
from gait_biofeedback.wire.padding import CDR_LE, IMU_DOUBLES, MAG_DOUBLES, type_name_of, zero_padding
from gait_biofeedback.wire.stamps import stamp_to_ns

_NS = NS_PER_S
_HEADER = 16  # encapsulation, sec, nanosec, string length

# Index of each field in the Imu doubles (MagneticField: field x, y, z at 0..2, covariance 3..11).
ORIENTATION = slice(0, 4)  # x, y, z, w
ORIENTATION_COV = slice(4, 13)
ANGULAR_VELOCITY = slice(13, 16)
ANGULAR_VELOCITY_COV = slice(16, 25)
LINEAR_ACCELERATION = slice(25, 28)
LINEAR_ACCELERATION_COV = slice(28, 37)
MAGNETIC_FIELD = slice(0, 3)


def record_dtype(frame_id: bytes, n_doubles: int) -> np.dtype:
    """Packed layout of one XCDR1 little-endian message: encapsulation, stamped header, doubles."""
    string_len = len(frame_id) + 1
    pad = -(12 + string_len) % 8
    fields = [("enc", "S4"), ("sec", "<i4"), ("nanosec", "<u4"), ("len", "<u4"), ("frame", f"S{string_len}")]
    if pad:
        fields.append(("pad", f"V{pad}"))
    fields.append(("d", "<f8", (n_doubles,)))
    return np.dtype(fields)


def encode_stamped(ns: np.ndarray, frame_id: str, doubles: np.ndarray) -> list[bytes]:
    """Bulk :func:`pack_stamped`: one message per row of ``doubles`` (N, n), stamped ``ns`` (N,)."""
    frame = frame_id.encode("utf-8")
    dtype = record_dtype(frame, doubles.shape[1])
    records = np.zeros(len(ns), dtype=dtype)
    sec, nanosec = np.divmod(ns, _NS)
    if len(sec) and (sec.min() < -(2**31) or sec.max() >= 2**31):
        raise ValueError("time stamps do not fit builtin_interfaces/Time (int32 seconds)")
    records["enc"], records["sec"], records["nanosec"] = CDR_LE, sec, nanosec
    records["len"], records["frame"], records["d"] = len(frame) + 1, frame, doubles
    blob, size = records.tobytes(), dtype.itemsize
    return [blob[i : i + size] for i in range(0, len(blob), size)]


def decode_stamped(
    payloads: list[bytes], msg_class: type, n_doubles: int, frames: list[str] | None = None
) -> tuple[np.ndarray, np.ndarray, str]:
    """``(t_ns, doubles (N, n_doubles), first frame_id)`` of Imu/MagneticField payloads; with a list
    ``frames``, each message's frame_id is put in it too (the bulk :func:`decode_imu`)."""
    ns = np.empty(len(payloads), dtype=np.int64)
    doubles = np.empty((len(payloads), n_doubles))
    frame_id = ""
    names: list[str] = [""] * len(payloads)
    by_size: dict[int, list[int]] = {}
    for i, p in enumerate(payloads):
        by_size.setdefault(len(p), []).append(i)
    for indices in by_size.values():
        first = payloads[indices[0]]
        frame_len = int.from_bytes(first[12:16], "little") if len(first) >= 16 else 0
        dtype = record_dtype(b"x" * max(frame_len - 1, 0), n_doubles)
        records = None
        if first[:4] == CDR_LE and dtype.itemsize == len(first):
            records = np.frombuffer(b"".join(payloads[i] for i in indices), dtype=dtype)
            if np.any(records["len"] != frame_len) or np.any(records["enc"] != CDR_LE):
                records = None
        if records is None:  # other encapsulation or layout: let rclpy decode
            for i in indices:
                ns[i], doubles[i], names[i] = decode_with_rclpy(payloads[i], msg_class)
                frame_id = frame_id or names[i]
            continue
        ns[indices] = records["sec"].astype(np.int64) * _NS + records["nanosec"]
        doubles[indices] = records["d"]
        frame_id = frame_id or records["frame"][0].decode("utf-8")
        if frames is not None:
            raw = records["frame"].tolist()
            text = {b: b.decode("utf-8") for b in set(raw)}
            for i, b in zip(indices, raw, strict=True):
                names[i] = text[b]
    if frames is not None:
        frames[:] = names
    return ns, doubles, frame_id


def decode_with_rclpy(payload: bytes, msg_class: type) -> tuple[int, np.ndarray, str]:
    """(stamp ns, doubles, frame_id) of any encoding rclpy reads (the slow path)."""
    msg = deserialize_message(payload, msg_class)
    ns = stamp_to_ns(msg.header.stamp)
    if msg_class is Imu:
        q, w, a = msg.orientation, msg.angular_velocity, msg.linear_acceleration
        values = [
            q.x,
            q.y,
            q.z,
            q.w,
            *msg.orientation_covariance,
            w.x,
            w.y,
            w.z,
            *msg.angular_velocity_covariance,
            a.x,
            a.y,
            a.z,
            *msg.linear_acceleration_covariance,
        ]
    else:
        f = msg.magnetic_field
        values = [f.x, f.y, f.z, *msg.magnetic_field_covariance]
    return ns, np.array(values, dtype=float), msg.header.frame_id


class Stamped(NamedTuple):
    """A decoded stamped message: header stamp (int ns), header.frame_id, the float64 fields."""

    ns: int
    frame_id: str
    values: tuple[float, ...]


_HEAD = struct.Struct("<iII")  # sec, nanosec, string length (after the encapsulation)
_DOUBLES = {IMU_DOUBLES: struct.Struct(f"<{IMU_DOUBLES}d"), MAG_DOUBLES: struct.Struct(f"<{MAG_DOUBLES}d")}
_layouts: dict[tuple[int, int], tuple[int, int]] = {}


def layout(string_len: int, n_doubles: int) -> tuple[int, int]:
    """(offset of the doubles, message size) in bytes when frame_id takes ``string_len`` bytes (NUL
    included), from the numpy record layout :func:`record_dtype`, so the bulk and the per-message
    codecs cannot disagree."""
    key = (string_len, n_doubles)
    found = _layouts.get(key)
    if found is None:
        dtype = record_dtype(b"x" * (string_len - 1), n_doubles)
        found = (dtype.fields["d"][1], dtype.itemsize)
        if len(_layouts) < 1024:
            _layouts[key] = found
    return found


def _doubles(n_doubles: int) -> struct.Struct:
    s = _DOUBLES.get(n_doubles)
    if s is None:
        s = _DOUBLES[n_doubles] = struct.Struct(f"<{n_doubles}d")
    return s


_STAMP_OF = {1: struct.Struct("<iI"), 0: struct.Struct(">iI")}  # encapsulation byte 1 → sec, nanosec


def header_stamp_ns(data: bytes) -> int | None:
    """``header.stamp`` (int ns) of a serialized message that starts with a std_msgs/Header (or is a
    builtin_interfaces/Time), read without decoding the rest: the time right after the XCDR1
    encapsulation, little endian when its byte 1 is 1, big endian when 0. None for other bytes (another
    encapsulation, fewer than 12 bytes). The one reader of raw stamps (nodes, ``analyze``, ``info``)."""
    if len(data) < 12 or data[0]:
        return None
    layout = _STAMP_OF.get(data[1])
    if layout is None:
        return None
    sec, nanosec = layout.unpack_from(data, 4)
    return sec * _NS + nanosec


def unpack_stamped(data: bytes, n_doubles: int) -> Stamped | None:
    """Stamp, frame_id and doubles of little-endian XCDR1 bytes; None if ``data`` is not exactly that
    layout (then use rclpy)."""
    if len(data) < _HEADER + 1 + 8 * n_doubles or data[:4] != CDR_LE:
        return None
    sec, nanosec, string_len = _HEAD.unpack_from(data, 4)
    if string_len < 1:
        return None
    offset, size = layout(string_len, n_doubles)
    end = _HEADER + string_len - 1
    if size != len(data) or data[end] != 0:
        return None
    return Stamped(sec * _NS + nanosec, str(data[_HEADER:end], "utf-8"),
                   _doubles(n_doubles).unpack_from(data, offset))


class StampedPacker:
    """:func:`pack_stamped` for one ``frame_id`` and number of doubles, its constant bytes (string
    length, frame id, padding) computed once."""

    _STAMP = struct.Struct("<iI")

    def __init__(self, frame_id: str, n_doubles: int) -> None:
        frame = frame_id.encode("utf-8")
        offset, _ = layout(len(frame) + 1, n_doubles)
        self._tail = struct.pack("<I", len(frame) + 1) + frame + bytes(offset - _HEADER - len(frame))
        self._doubles = _doubles(n_doubles)

    def pack(self, ns: int, values: tuple[float, ...] | list[float]) -> bytes:
        sec, nanosec = divmod(ns, _NS)
        return b"".join((CDR_LE, self._STAMP.pack(sec, nanosec), self._tail, self._doubles.pack(*values)))


@cache
def _packer(frame_id: str, n_doubles: int) -> StampedPacker:
    return StampedPacker(frame_id, n_doubles)


def pack_stamped(ns: int, frame_id: str, values: tuple[float, ...] | list[float]) -> bytes:
    """CDR bytes of a header stamped ``ns`` with ``frame_id`` and the float64 fields ``values``: the
    message ``serialize_message`` gives (which leaves the padding bytes uninitialised; here they are 0)."""
    return _packer(frame_id, len(values)).pack(ns, values)


def unpack_imu(data: bytes) -> Stamped | None:
    """A sensor_msgs/Imu's stamp, frame_id and 37 doubles (None: not the plain layout)."""
    return unpack_stamped(data, IMU_DOUBLES)


def unpack_mag(data: bytes) -> Stamped | None:
    """A sensor_msgs/MagneticField's stamp, frame_id and 12 doubles (None: not the plain layout)."""
    return unpack_stamped(data, MAG_DOUBLES)


def pack_imu(ns: int, frame_id: str, values: tuple[float, ...] | list[float]) -> bytes:
    """Serialized sensor_msgs/Imu of 37 doubles (:data:`ORIENTATION` … :data:`LINEAR_ACCELERATION_COV`)."""
    if len(values) != IMU_DOUBLES:
        raise ValueError(f"an Imu has {IMU_DOUBLES} doubles, got {len(values)}")
    return pack_stamped(ns, frame_id, values)


def _decode(data: bytes, msg_class: type, n_doubles: int) -> Stamped:
    fields = unpack_stamped(data, n_doubles)
    if fields is not None:
        return fields
    ns, values, frame_id = decode_with_rclpy(bytes(data), msg_class)
    return Stamped(int(ns), frame_id, tuple(values.tolist()))


def decode_imu(data: bytes) -> Stamped:
    """Serialized sensor_msgs/Imu → :class:`Stamped` (fast path, else rclpy's deserializer)."""
    return _decode(data, Imu, IMU_DOUBLES)


def decode_mag(data: bytes) -> Stamped:
    """Serialized sensor_msgs/MagneticField → :class:`Stamped` (fast path, else rclpy's deserializer)."""
    return _decode(data, MagneticField, MAG_DOUBLES)


# -- any rclpy message ------------------------------------------------------------------------------

def serialize(msg: Any) -> bytes:
    """``serialize_message`` of any rclpy message, cut to its exact XCDR1 size, its padding zeroed.

    rclpy's buffer can run past the encoding (a sensor_msgs/JointState with empty ``velocity`` and
    ``effort`` gets 8 trailing bytes); DDS sends the exact size, and strict readers (the PyPI
    ``rosbags``) refuse the longer form, so every message the project writes goes through here. The
    padding rclpy leaves unwritten is zeroed (:mod:`.padding`)."""
    return zero_padding(serialize_message(msg), type_name_of(msg), cut=True)
