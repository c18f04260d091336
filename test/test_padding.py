"""Recorded messages have their CDR padding zeroed (wire/padding.py): same input, same bytes."""

from __future__ import annotations

import struct

import pytest
from conftest import rosbags_typestore
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Empty
from visualization_msgs.msg import Marker, MarkerArray

import gait_biofeedback_msgs.msg as project_msgs
from gait_biofeedback.io import bag_writer
from gait_biofeedback.io.bag_reader import BagReader
from gait_biofeedback.io.bag_writer import BagWriter
from gait_biofeedback.io.schemas import type_name_of
from gait_biofeedback.wire import padding
from gait_biofeedback.wire.cdr import pack_imu, serialize

JOINT_STATES = "sensor_msgs/msg/JointState"


def joint_state_by_hand(fill: int) -> tuple[bytes, list[int]]:
    """JointState(frame_id "ab", name ["x"], position [1.5]) encoded field by field, its padding bytes
    set to ``fill``; and the padding's offsets in the bytes (after the 4-byte encapsulation: the
    frame_id ends at 15, the name sequence's length is 4-aligned at 16; "x" ends at 26, the position
    sequence's length at 28; its double at 32 is already 8-aligned)."""
    pad1, pad2 = bytes([fill]), bytes([fill] * 2)
    body = (struct.pack("<iII", 7, 9, 3) + b"ab\0" + pad1 + struct.pack("<II", 1, 2) + b"x\0" + pad2
            + struct.pack("<I", 1) + struct.pack("<d", 1.5) + struct.pack("<II", 0, 0))
    return b"\x00\x01\x00\x00" + body, [4 + 15, 4 + 26, 4 + 27]


def test_joint_state_padding_is_zeroed_where_derived_by_hand() -> None:
    dirty, where = joint_state_by_hand(0xAA)
    clean, _ = joint_state_by_hand(0)
    msg = JointState(name=["x"], position=[1.5])
    msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id = 7, 9, "ab"
    assert len(serialize(msg)) == len(clean)  # the layout by hand is rclpy's
    assert deserialize_message(dirty, JointState) == msg
    assert [dirty[i] for i in where] == [0xAA] * 3
    assert padding.zero_padding(dirty, JOINT_STATES) == clean


def test_imu_padding_is_zeroed() -> None:
    """"left_foot_imu" + NUL (14 bytes) ends at 12 + 14 = 26 after the encapsulation; the doubles
    start at 32: bytes 30-35 of the message are padding."""
    clean = pack_imu(123_456_789, "left_foot_imu", [float(i) for i in range(37)])
    assert clean[30:36] == bytes(6)
    dirty = clean[:30] + b"\xff" * 6 + clean[36:]
    assert padding.zero_padding(dirty, "sensor_msgs/msg/Imu") == clean
    assert padding.zero_padding(clean, "sensor_msgs/msg/Imu") is clean  # nothing to do: not copied


@pytest.mark.parametrize("damage", ["truncated", "big endian", "unknown type", "no package", "far too long",
                                    "huge count"])
def test_bytes_it_cannot_walk_come_back_unchanged(damage: str) -> None:
    dirty, _ = joint_state_by_hand(0xAA)
    type_name = JOINT_STATES
    if damage == "truncated":
        dirty = dirty[:30]
    elif damage == "big endian":
        dirty = b"\x00\x00\x00\x00" + dirty[4:]
    elif damage == "unknown type":
        type_name = "no_such_pkg/msg/Thing"
    elif damage == "no package":
        type_name = "JointState"
    elif damage == "far too long":  # as another version of the type, with more fields, would be
        dirty += b"\xaa" * 16
    else:  # the name sequence's count
        dirty = dirty[:20] + struct.pack("<I", 0xFFFFFFFF) + dirty[24:]
    assert padding.zero_padding(dirty, type_name) == dirty


def test_the_encapsulation_options_are_kept_and_a_short_overrun_zeroed() -> None:
    """XTypes 1.3 writers may set the options bytes (2-3) of the header; rclpy's buffer runs up to
    8 bytes past the message: zeroed (``cut``: dropped)."""
    dirty, _ = joint_state_by_hand(0xAA)
    clean, _ = joint_state_by_hand(0)
    with_options = dirty[:3] + b"\x03" + dirty[4:]
    assert padding.zero_padding(with_options, JOINT_STATES) == clean[:3] + b"\x03" + clean[4:]
    overrun = dirty + b"\xee" * 8
    assert padding.zero_padding(overrun, JOINT_STATES) == clean + bytes(8)
    assert padding.zero_padding(overrun, JOINT_STATES, cut=True) == clean


def _filled(msg_class: type, depth: int = 0):
    """An instance with every string, sequence and array non-empty, of odd sizes (so that padding
    appears), nested messages filled the same way."""
    msg = msg_class()
    for name, field_type in msg_class.get_fields_and_field_types().items():
        value = getattr(msg, name)
        if field_type == "string":
            setattr(msg, name, "abc"[: 1 + depth % 3])
        elif field_type.startswith("sequence<") and depth < 2:
            element = field_type[len("sequence<"):-1]
            if element == "string":
                setattr(msg, name, ["a", "bcde"])
            elif "/" in element:
                pkg, _, cls = element.rpartition("/")
                element_class = getattr(__import__(f"{pkg}.msg", fromlist=[cls]), cls)
                setattr(msg, name, [_filled(element_class, depth + 1) for _ in range(2)])
            elif element in ("double", "float"):
                setattr(msg, name, [0.25, -1.0, 3.0])
        elif hasattr(value, "get_fields_and_field_types"):
            setattr(msg, name, _filled(type(value), depth + 1))
    return msg


def _message_types() -> list[type]:
    project = [getattr(project_msgs, n) for n in dir(project_msgs) if n[0].isupper()]
    return [*project, Imu, JointState, DiagnosticArray, DiagnosticStatus, KeyValue, Marker, MarkerArray,
            Empty]


@pytest.fixture(scope="module")
def rosbags_store():
    return rosbags_typestore()


@pytest.mark.parametrize("msg_class", _message_types(), ids=lambda c: c.__name__)
def test_every_recorded_type_comes_out_as_rosbags_encodes_it(msg_class: type, rosbags_store) -> None:
    """The PyPI ``rosbags`` writes zeroed padding and the exact size (its reader refuses another size):
    rclpy's bytes, zeroed and cut, are its bytes."""
    msg = _filled(msg_class)
    type_name = type_name_of(msg)
    ours = serialize(msg)
    canonical = rosbags_store.serialize_cdr(rosbags_store.deserialize_cdr(ours, type_name), type_name)
    assert ours == canonical
    longer = serialize_message(msg)[:len(canonical)] + b"\xee" * 8  # rclpy's buffer ran past the message
    assert padding.zero_padding(longer, type_name, cut=True) == canonical


def test_the_bag_writer_records_zeroed_padding(tmp_path) -> None:
    dirty, _ = joint_state_by_hand(0xAA)
    clean, _ = joint_state_by_hand(0)
    with BagWriter(tmp_path / "bag") as writer:
        writer.write_serialized("/joint_states", JOINT_STATES, dirty, 1_000)
    with BagReader(tmp_path / "bag") as reader:
        (_, _, data, *_), = list(reader.raw_messages(["/joint_states"]))
    assert bytes(data) == clean


def _write_joint_states(path, **options) -> bytes:
    clean, _ = joint_state_by_hand(0)
    with BagWriter(path, **options) as writer:
        for k in range(300):
            writer.write_serialized("/joint_states", JOINT_STATES, clean, 1_000 + k)
    return (path / f"{path.name}_0.mcap").read_bytes()


def test_an_offline_writer_gives_the_same_file_whatever_the_wall_clock(tmp_path, monkeypatch) -> None:
    """``flush_period_s=None`` closes chunks by size only; the live default closes one each wall-clock
    second, so a slow run (here a clock that jumps 0.5 s per reading) splits the same messages
    differently."""
    quick = _write_joint_states(tmp_path / "quick", flush_period_s=None)
    live_quick = _write_joint_states(tmp_path / "live_quick")
    ticks = iter(range(10**6))
    monkeypatch.setattr(bag_writer.time, "monotonic", lambda: 0.5 * next(ticks))
    assert _write_joint_states(tmp_path / "slow", flush_period_s=None) == quick
    assert _write_joint_states(tmp_path / "live_slow") != live_quick


def test_field_types_read_as_xcdr1_lays_them_out() -> None:
    assert padding._field_steps("string[3]") == (("a", 3, (("s",),)),)
    assert padding._field_steps("string<5>") == (("s",),)
    assert padding._field_steps("sequence<int32, 5>") == (("q", 4),)
    assert padding._field_steps("double[9]") == (("a", 9, 8),)
    with pytest.raises(ValueError, match="wstring"):
        padding._field_steps("wstring[2]")
