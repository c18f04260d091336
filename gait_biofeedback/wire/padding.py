"""Zero the alignment padding of XCDR1 message bytes, and cut them where the message ends.

rclpy's ``serialize_message`` (and a DDS publisher's serializer) skips the bytes that align a field to
its size without writing them: they hold whatever the buffer held before, fragments of the process's
memory. Recorded as they are, two analyses of the same input give different files, and a recording
can carry bytes of unrelated strings (measured: ``analyze`` of one session twice, 5,072 of 5,899
``/joint_states`` messages differed in their padding only). :func:`zero_padding` walks the bytes by
the type's field list and sets every padding byte to 0; every decoder reads the same message. The
same walk gives the message's exact size, which ``cdr.serialize`` cuts rclpy's longer buffer to.

XCDR1 little endian, as :mod:`gait_biofeedback.wire.cdr` describes it: offsets count after the
4-byte encapsulation; a primitive is aligned to its size (at most 8); a string or a sequence starts
with a 4-aligned uint32 length (a string's counts its NUL); a sequence or array of primitives aligns
its first element only, and an empty sequence has none; a nested message adds no alignment of its own.
"""

from __future__ import annotations

import importlib
import struct
from functools import cache

CDR_LE = b"\x00\x01\x00\x00"
IMU_DOUBLES, MAG_DOUBLES = 37, 12  # sensor_msgs/Imu, MagneticField: header, then float64 only

_SIZES = {"boolean": 1, "octet": 1, "byte": 1, "char": 1, "uint8": 1, "int8": 1, "uint16": 2, "int16": 2,
          "uint32": 4, "int32": 4, "float": 4, "uint64": 8, "int64": 8, "double": 8}
_U32 = struct.Struct("<I")
_STRING = (("s",),)  # the plan of a string element
_STAMPED = {"sensor_msgs/msg/Imu": IMU_DOUBLES, "sensor_msgs/msg/MagneticField": MAG_DOUBLES}

# A plan is a tuple of steps: ("p", size) a primitive, ("s",) a string, ("q", element plan or size) a
# sequence, ("a", n, element plan or size) a fixed array; a message's steps are inlined.


@cache
def _plan(type_name: str) -> tuple:
    package, _, name = type_name.rpartition("/")
    message = getattr(importlib.import_module(f"{package.split('/')[0]}.msg"), name)
    steps: list = []
    for field_type in message.get_fields_and_field_types().values():
        steps.extend(_field_steps(field_type))
    return tuple(steps) or (("p", 1),)  # a message without fields is encoded as one uint8


def _element(type_name: str) -> int | tuple:
    return _SIZES.get(type_name) or (_plan(type_name) if "/" in type_name else _field_steps(type_name))


def _field_steps(field_type: str) -> tuple:
    if field_type in _SIZES:
        return (("p", _SIZES[field_type]),)
    if field_type == "wstring" or field_type.startswith("wstring<"):
        raise ValueError("wstring: the width of its characters is not fixed by XCDR1")
    if field_type.startswith("sequence<"):
        return (("q", _element(field_type[len("sequence<"):-1].split(",")[0].strip())),)
    if field_type.endswith("]"):  # a fixed array: double[9], string[3], geometry_msgs/Point[2]
        base, n = field_type[:-1].rsplit("[", 1)
        return (("a", int(n), _element(base)),)
    if field_type == "string" or field_type.startswith("string<"):
        return (("s",),)
    return _plan(field_type)


def _walk(buf: bytearray, steps: tuple, pos: int) -> int:
    """Zero the padding of ``steps`` encoded at ``pos`` (after the encapsulation); the end offset."""
    for step in steps:
        kind = step[0]
        if kind == "p":
            pos = _align(buf, pos, step[1]) + step[1]
        elif kind == "s":
            pos = _string_end(buf, pos)
        else:
            if kind == "q":
                pos = _align(buf, pos, 4)
                n = _U32.unpack_from(buf, 4 + pos)[0]
                pos += 4
                element = step[1]
            else:
                n, element = step[1], step[2]
            if isinstance(element, int):
                if n:
                    pos = _align(buf, pos, element) + element * n
            elif element == _STRING:  # names, labels: without a walk each (a JointState has 18)
                for _ in range(n):
                    pos = _string_end(buf, pos)
                    if 4 + pos > len(buf):
                        raise IndexError("the bytes end inside the message")
            else:
                for _ in range(n):
                    pos = _walk(buf, element, pos)
        if 4 + pos > len(buf):
            raise IndexError("the bytes end inside the message")
    return pos


def _string_end(buf: bytearray, pos: int) -> int:
    """The end of the string encoded at ``pos`` (its length's padding zeroed)."""
    pos = _align(buf, pos, 4)
    return pos + 4 + _U32.unpack_from(buf, 4 + pos)[0]


def _align(buf: bytearray, pos: int, size: int) -> int:
    pad = -pos % size
    if pad:
        buf[4 + pos:4 + pos + pad] = bytes(pad)
    return pos + pad


def type_name_of(msg_or_class: object) -> str:
    """ROS 2 type name (``pkg/msg/Type``) of an rclpy message instance or class."""
    cls = msg_or_class if isinstance(msg_or_class, type) else type(msg_or_class)
    return f"{cls.__module__.split('.')[0]}/msg/{cls.__name__}"


def zero_padding(data: bytes, type_name: str, cut: bool = False) -> bytes:
    """``data`` (XCDR1 little endian of ``type_name``, ``pkg/msg/Type``) with every padding byte 0,
    and the bytes past the message's end (rclpy's buffer can run up to 8 past it: a JointState with
    empty ``velocity`` and ``effort``) zeroed, or dropped with ``cut``. Bytes this cannot walk
    (another encoding, an unknown type, a wstring, bytes that end inside the message or more than 8
    bytes after it, as another version of the type would) come back unchanged: a message is never
    lost for its padding. The encapsulation's options (bytes 2-3) are kept."""
    if data[:2] != CDR_LE[:2]:
        return data
    doubles = _STAMPED.get(type_name)
    if doubles is not None and len(data) >= 16:  # the hot path: header, then float64 only
        start = 16 + _U32.unpack_from(data, 12)[0]  # just past the frame_id's NUL
        offset = start + (-(start - 4) % 8)
        if offset + 8 * doubles == len(data):
            return b"".join((data[:start], bytes(offset - start), data[offset:])) if any(data[start:offset]) \
                else data
    buf = bytearray(data)
    try:
        end = 4 + _walk(buf, _plan(type_name), 0)
    except Exception:  # whatever the walk meets, the message is kept as it came
        return data
    if len(data) - end > 8:
        return data
    if cut:
        return bytes(buf[:end])
    buf[end:] = bytes(len(data) - end)
    return bytes(buf)
