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
from typing import NamedTuple

CDR_LE = b"\x00\x01\x00\x00"
_CDR_LE_HEAD = CDR_LE[:2]
IMU_DOUBLES, MAG_DOUBLES = 37, 12  # sensor_msgs/Imu, MagneticField: header, then float64 only

_SIZES = {"boolean": 1, "octet": 1, "byte": 1, "char": 1, "uint8": 1, "int8": 1, "uint16": 2, "int16": 2,
          "uint32": 4, "int32": 4, "float": 4, "uint64": 8, "int64": 8, "double": 8}
_U32 = struct.Struct("<I")
_STRING = (("s",),)  # the plan of a string element

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


def _walk(data: bytes, steps: tuple, pos: int, trace: list[tuple[int, int]]) -> int:
    """Walk ``steps`` encoded at ``pos`` (after the encapsulation), noting in ``trace`` each padding run
    as ``(offset in data, its size)`` and each length read as ``(offset, 0)``, in order; the end offset."""
    for step in steps:
        kind = step[0]
        if kind == "p":
            pos = _align(trace, pos, step[1]) + step[1]
        elif kind == "s":
            pos = _string_end(data, pos, trace)
        else:
            if kind == "q":
                pos = _align(trace, pos, 4)
                n = _U32.unpack_from(data, 4 + pos)[0]
                trace.append((4 + pos, 0))
                pos += 4
                element = step[1]
            else:
                n, element = step[1], step[2]
            if isinstance(element, int):
                if n:
                    pos = _align(trace, pos, element) + element * n
            elif element == _STRING:  # names, labels: without a walk each (a JointState has 18)
                for _ in range(n):
                    pos = _string_end(data, pos, trace)
                    if 4 + pos > len(data):
                        raise IndexError("the bytes end inside the message")
            else:
                for _ in range(n):
                    pos = _walk(data, element, pos, trace)
        if 4 + pos > len(data):
            raise IndexError("the bytes end inside the message")
    return pos


def _string_end(data: bytes, pos: int, trace: list[tuple[int, int]]) -> int:
    """The end of the string encoded at ``pos``."""
    pos = _align(trace, pos, 4)
    trace.append((4 + pos, 0))
    return pos + 4 + _U32.unpack_from(data, 4 + pos)[0]


def _align(trace: list[tuple[int, int]], pos: int, size: int) -> int:
    pad = -pos % size
    if pad:
        trace.append((4 + pos, pad))
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
    lost for its padding. The encapsulation's options (bytes 2-3) are kept. Bytes with nothing to
    change come back as the same object."""
    return padder(type_name)(data, cut)


class _Layout(NamedTuple):
    """Where one message's length fields and padding lie: any message of its type and size whose
    length fields hold the same values has them in the same places (the walk reads nothing else)."""

    fields: struct.Struct  # the length fields and padding runs, in order
    clean: tuple  # what ``fields`` reads when the padding is zero
    lengths: struct.Struct  # the length fields alone
    values: tuple  # their values
    pads: tuple[tuple[int, int], ...]  # (offset, size) of each padding run before the end
    end: int  # where the message ends (4 + the walk's end)


class Padder:
    """:func:`zero_padding` for one type: a message's layout is walked once per size and length
    fields' values (up to :attr:`PER_SIZE` layouts a size: frame ids of different lengths can give one
    size); a message of a known layout is then checked by one ``struct`` read (a copied Imu,
    MagneticField or JointState: no walk)."""

    MAX_SIZES = 64  # sizes remembered (messages of strings vary in size)
    PER_SIZE = 4
    __slots__ = ("_layouts", "type_name")

    def __init__(self, type_name: str) -> None:
        self.type_name = type_name
        self._layouts: dict[int, list[_Layout]] = {}

    def __call__(self, data: bytes, cut: bool = False) -> bytes:
        """``data`` zeroed (and cut) as :func:`zero_padding` says."""
        if not data.startswith(_CDR_LE_HEAD):
            return data
        for layout in self._layouts.get(len(data), ()):
            if layout.fields.unpack_from(data) == layout.clean:
                return data[:layout.end] if cut and layout.end < len(data) else data
            if layout.lengths.unpack_from(data) == layout.values:
                return _zeroed(data, layout, cut)
        layout = self._learn(data)
        if layout is None:
            return data
        if layout.fields.unpack_from(data) == layout.clean:
            return data[:layout.end] if cut and layout.end < len(data) else data
        return _zeroed(data, layout, cut)

    def _learn(self, data: bytes) -> _Layout | None:
        """Walk ``data``'s layout and remember it (None: it cannot be walked, see :func:`zero_padding`)."""
        trace: list[tuple[int, int]] = []
        try:
            end = 4 + _walk(data, _plan(self.type_name), 0, trace)
        except Exception:  # whatever the walk meets, the message is kept as it came
            return None
        if len(data) - end > 8:
            return None
        if len(data) > end:
            trace.append((end, len(data) - end))
        fields, lengths, cursor, lengths_cursor = ["<"], ["<"], 0, 0
        for at, size in trace:
            fields.append(f"{at - cursor}x{size}s" if size else f"{at - cursor}xI")
            cursor = at + (size or 4)
            if not size:
                lengths.append(f"{at - lengths_cursor}xI")
                lengths_cursor = at + 4
        clean = tuple(bytes(size) if size else _U32.unpack_from(data, at)[0] for at, size in trace)
        layout = _Layout(struct.Struct("".join(fields)), clean, struct.Struct("".join(lengths)),
                         tuple(v for v, (_, size) in zip(clean, trace, strict=True) if not size),
                         tuple((at, size) for at, size in trace if size and at < end), end)
        same_size = self._layouts.get(len(data))
        if same_size is None:
            if len(self._layouts) >= self.MAX_SIZES:
                self._layouts.clear()
            same_size = self._layouts[len(data)] = []
        if len(same_size) >= self.PER_SIZE:
            same_size.pop(0)
        same_size.append(layout)
        return layout


def _zeroed(data: bytes, layout: _Layout, cut: bool) -> bytes:
    buf = bytearray(data[:layout.end] if cut else data)
    for at, size in layout.pads:
        buf[at:at + size] = bytes(size)
    if len(buf) > layout.end:
        buf[layout.end:] = bytes(len(buf) - layout.end)
    return bytes(buf)


@cache
def padder(type_name: str) -> Padder:
    """The :class:`Padder` of ``type_name`` (one per type, shared)."""
    return Padder(type_name)
