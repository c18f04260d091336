"""One stamped message ↔ its CDR bytes without rclpy objects: sensor_msgs/Imu and MagneticField.

The hot paths of the node graph (raw subscriptions, publishing serialized bytes) and the offline
``analyze`` path use these functions, so both see exactly the same numbers. The layout is the one
:func:`gait_biofeedback.io.imu_messages._record_dtype` defines for the bulk (numpy) path: XCDR1
little endian — encapsulation ``00 01 00 00``, int32 sec, uint32 nanosec, uint32 length of
frame_id (with its NUL), the frame_id bytes and NUL, zero padding so the doubles start 8-aligned
(counted after the encapsulation), then the float64 fields (Imu: 37, MagneticField: 12, in
declaration order, see :data:`ORIENTATION` …). The offsets here are taken from that dtype.

:func:`unpack_stamped` returns None for anything else (big endian, XCDR2, a size that does not
match); :func:`decode_imu` / :func:`decode_mag` then fall back to rclpy's ``deserialize_message``.
"""

from __future__ import annotations

import struct
from typing import NamedTuple

from sensor_msgs.msg import Imu, MagneticField

from gait_biofeedback.io.imu_messages import (
    CDR_LE,
    IMU_DOUBLES,
    MAG_DOUBLES,
    _decode_with_rclpy,
    _record_dtype,
)

__all__ = ["CDR_LE", "IMU_DOUBLES", "MAG_DOUBLES", "Stamped", "decode_imu", "decode_mag", "pack_imu",
           "pack_stamped", "unpack_imu", "unpack_mag", "unpack_stamped"]

_NS = 1_000_000_000
_HEADER = 16  # encapsulation, sec, nanosec, string length

# Index of each field in the Imu doubles (MagneticField: field x, y, z at 0..2, covariance 3..11).
ORIENTATION = slice(0, 4)  # x, y, z, w
ORIENTATION_COV = slice(4, 13)
ANGULAR_VELOCITY = slice(13, 16)
ANGULAR_VELOCITY_COV = slice(16, 25)
LINEAR_ACCELERATION = slice(25, 28)
LINEAR_ACCELERATION_COV = slice(28, 37)


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
    included), from the numpy record layout of :mod:`gait_biofeedback.io.imu_messages`, so the bulk
    and the per-message codecs cannot disagree."""
    key = (string_len, n_doubles)
    found = _layouts.get(key)
    if found is None:
        dtype = _record_dtype(b"x" * (string_len - 1), n_doubles)
        found = (dtype.fields["d"][1], dtype.itemsize)
        if len(_layouts) < 1024:
            _layouts[key] = found
    return found


def _doubles(n_doubles: int) -> struct.Struct:
    s = _DOUBLES.get(n_doubles)
    if s is None:
        s = _DOUBLES[n_doubles] = struct.Struct(f"<{n_doubles}d")
    return s


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


def pack_stamped(ns: int, frame_id: str, values: tuple[float, ...] | list[float]) -> bytes:
    """CDR bytes of a header stamped ``ns`` with ``frame_id`` and the float64 fields ``values``: the
    message ``serialize_message`` gives (which leaves the padding bytes uninitialised; here they are 0)."""
    frame = frame_id.encode("utf-8")
    string_len = len(frame) + 1
    offset, _ = layout(string_len, len(values))
    sec, nanosec = divmod(ns, _NS)
    return b"".join((CDR_LE, _HEAD.pack(sec, nanosec, string_len), frame,
                     bytes(offset - _HEADER - len(frame)), _doubles(len(values)).pack(*values)))


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
    ns, values, frame_id = _decode_with_rclpy(bytes(data), msg_class)
    return Stamped(int(ns), frame_id, tuple(values.tolist()))


def decode_imu(data: bytes) -> Stamped:
    """Serialized sensor_msgs/Imu → :class:`Stamped` (fast path, else rclpy's deserializer)."""
    return _decode(data, Imu, IMU_DOUBLES)


def decode_mag(data: bytes) -> Stamped:
    """Serialized sensor_msgs/MagneticField → :class:`Stamped` (fast path, else rclpy's deserializer)."""
    return _decode(data, MagneticField, MAG_DOUBLES)
