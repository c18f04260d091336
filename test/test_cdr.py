"""Per-message CDR codec (gait_biofeedback.wire.cdr) against rclpy's serializer."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from conftest import stamp_ns
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu, MagneticField

from gait_biofeedback.wire import cdr


def random_imu(frame_id: str, rng: np.random.Generator) -> Imu:
    msg = Imu()
    msg.header.frame_id = frame_id
    msg.header.stamp.sec = int(rng.integers(-(2**31), 2**31))
    msg.header.stamp.nanosec = int(rng.integers(0, 1_000_000_000))
    v = rng.normal(size=37).tolist()
    msg.orientation.x, msg.orientation.y, msg.orientation.z, msg.orientation.w = v[0:4]
    msg.orientation_covariance = v[4:13]
    msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = v[13:16]
    msg.angular_velocity_covariance = v[16:25]
    msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z = v[25:28]
    msg.linear_acceleration_covariance = v[28:37]
    return msg


def random_mag(frame_id: str, rng: np.random.Generator) -> MagneticField:
    msg = MagneticField()
    msg.header.frame_id = frame_id
    msg.header.stamp.sec, msg.header.stamp.nanosec = 1_700_000_000, int(rng.integers(0, 1_000_000_000))
    msg.magnetic_field.x, msg.magnetic_field.y, msg.magnetic_field.z = rng.normal(size=3).tolist()
    msg.magnetic_field_covariance = rng.normal(size=9).tolist()
    return msg


def imu_values(msg: Imu) -> tuple[float, ...]:
    q, w, a = msg.orientation, msg.angular_velocity, msg.linear_acceleration
    return (q.x, q.y, q.z, q.w, *msg.orientation_covariance, w.x, w.y, w.z, *msg.angular_velocity_covariance,
            a.x, a.y, a.z, *msg.linear_acceleration_covariance)


def padding_mask(frame_len: int, size: int) -> np.ndarray:
    """True on every byte that carries data (rclpy leaves the alignment padding uninitialised)."""
    offset, total = cdr.layout(frame_len + 1, (size - 16 - frame_len - 1) // 8)
    keep = np.ones(size, dtype=bool)
    keep[16 + frame_len + 1 : offset] = False
    assert total == size
    return keep


@pytest.mark.parametrize("frame_len", range(10))
def test_imu_round_trip_matches_rclpy(frame_len: int) -> None:
    rng = np.random.default_rng(frame_len)
    frame_id = "abcdefghij"[:frame_len]
    msg = random_imu(frame_id, rng)
    data = serialize_message(msg)
    fields = cdr.unpack_imu(data)
    assert fields is not None
    assert fields.ns == stamp_ns(msg.header.stamp) and fields.frame_id == frame_id
    assert fields.values == imu_values(msg)
    packed = cdr.pack_imu(fields.ns, fields.frame_id, fields.values)
    assert len(packed) == len(data)
    keep = padding_mask(frame_len, len(data))
    assert np.array_equal(np.frombuffer(packed, np.uint8)[keep], np.frombuffer(data, np.uint8)[keep])
    assert not any(np.frombuffer(packed, np.uint8)[~keep]), "padding is zero"
    assert deserialize_message(packed, Imu) == msg
    assert cdr.decode_imu(data) == fields


@pytest.mark.parametrize("frame_len", range(10))
def test_magnetic_field_round_trip_matches_rclpy(frame_len: int) -> None:
    rng = np.random.default_rng(100 + frame_len)
    msg = random_mag("x" * frame_len, rng)
    data = serialize_message(msg)
    fields = cdr.unpack_mag(data)
    assert fields is not None and fields.ns == stamp_ns(msg.header.stamp)
    assert fields.frame_id == "x" * frame_len
    f = msg.magnetic_field
    assert fields.values == (f.x, f.y, f.z, *msg.magnetic_field_covariance)
    packed = cdr.pack_stamped(fields.ns, fields.frame_id, fields.values)
    assert deserialize_message(packed, MagneticField) == msg
    assert cdr.decode_mag(data) == fields


def test_non_ascii_frame_id() -> None:
    msg = random_imu("käse_imu", np.random.default_rng(7))
    data = serialize_message(msg)
    fields = cdr.unpack_imu(data)
    assert fields is not None and fields.frame_id == "käse_imu"
    assert deserialize_message(cdr.pack_imu(*fields), Imu) == msg


def big_endian_imu(msg: Imu) -> bytes:
    """The same message in big-endian XCDR1 (encapsulation 00 00 00 00), which the fast path refuses."""
    frame = msg.header.frame_id.encode() + b"\x00"
    head = struct.pack(">iII", msg.header.stamp.sec, msg.header.stamp.nanosec, len(frame)) + frame
    head += bytes(-len(head) % 8)
    return b"\x00\x00\x00\x00" + head + struct.pack(">37d", *imu_values(msg))


def test_other_layouts_fall_back_to_rclpy() -> None:
    msg = random_imu("left_foot_imu", np.random.default_rng(3))
    data = serialize_message(msg)
    expected = cdr.unpack_imu(data)

    big = big_endian_imu(msg)
    assert deserialize_message(big, Imu) == msg, "test input is a valid message"
    assert cdr.unpack_imu(big) is None
    assert cdr.decode_imu(big) == expected

    longer = data + bytes(8)  # a size that does not match the layout
    assert cdr.unpack_imu(longer) is None
    assert cdr.decode_imu(longer) == expected

    assert cdr.unpack_imu(data[:-8]) is None
    assert cdr.unpack_imu(b"") is None
    assert cdr.unpack_mag(data) is None, "an Imu is not a MagneticField"
    bad_length = bytearray(data)
    bad_length[12:16] = (10_000).to_bytes(4, "little")
    assert cdr.unpack_imu(bytes(bad_length)) is None


def test_pack_imu_checks_the_field_count() -> None:
    with pytest.raises(ValueError):
        cdr.pack_imu(0, "x", (0.0,) * 36)


def test_header_stamp_is_read_without_decoding_the_message():
    """One reader of raw stamps, either byte order (the encapsulation's byte 1), anything else None."""
    from builtin_interfaces.msg import Time

    from gait_biofeedback.wire.cdr import IMU_DOUBLES, header_stamp_ns, pack_imu

    data = pack_imu(1_234_567_890_123, "chest_imu", [0.0] * IMU_DOUBLES)
    assert header_stamp_ns(data) == 1_234_567_890_123
    msg = random_imu("left_foot_imu", np.random.default_rng(5))
    stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
    assert header_stamp_ns(serialize_message(msg)) == stamp_ns
    assert header_stamp_ns(big_endian_imu(msg)) == stamp_ns
    assert header_stamp_ns(serialize_message(Time(sec=-3, nanosec=7))) == -3 * 1_000_000_000 + 7  # 12 bytes
    assert header_stamp_ns(data[:11]) is None
    assert header_stamp_ns(b"\x00\x07\x00\x00" + data[4:]) is None  # XCDR2: not this layout
    assert header_stamp_ns(b"\x01\x01\x00\x00" + data[4:]) is None


@pytest.mark.parametrize("recovering, heading", [(False, True), (True, False)])
def test_an_orientation_message_is_its_bytes_decoded(recovering: bool, heading: bool) -> None:
    """``orientation_fields`` are both the bytes the node publishes (``pack_imu`` of them) and, for
    ``analyze``, what ``decode_imu`` of those bytes gives (an integer variance from a parameter file
    included), and those bytes are what rclpy serializes of the same message."""
    from gait_biofeedback.core.orientation.stream import OrientationSample
    from gait_biofeedback.wire.imu import orientation_fields

    rng = np.random.default_rng(3)
    raw = cdr.decode_imu(serialize_message(random_imu("left_foot_imu", rng)))
    q = rng.normal(size=4)
    sample = OrientationSample(1_700_000_000_123_456_789, q / np.linalg.norm(q), rng.normal(size=3),
                               rng.normal(size=3), recovering, heading)
    fields = orientation_fields("left_foot", sample, raw, 2)
    data = cdr.pack_imu(*fields)
    assert cdr.Stamped(*fields) == cdr.decode_imu(data)
    assert all(type(v) is float for v in fields[2])
    assert cdr.serialize(deserialize_message(data, Imu)) == data


_JOINTS = ["left_hip_flexion", "left_hip_adduction", "left_hip_internal_rotation", "left_knee_flexion",
           "left_knee_adduction", "left_knee_internal_rotation", "left_ankle_dorsiflexion",
           "left_ankle_inversion", "left_ankle_internal_rotation"]


@pytest.mark.parametrize(("names", "recovering", "ns"), [
    ([], (), 0),
    (_JOINTS[:1], (), 1_700_000_000_123_456_789),
    (_JOINTS[:6], ("left_thigh",), 5),
    (_JOINTS + [n.replace("left", "right") for n in _JOINTS], ("left_thigh", "pelvis", "right_foot"),
     -1_500_000_001),
    (["genou_flexión", "x"], ("cuisse_gauche",), 123_456_789_000),  # non-ASCII: lengths in bytes
])
def test_joint_state_bytes_are_rclpys_and_read_back(names, recovering, ns) -> None:
    """The hand-written JointState codec against rclpy's serializer (padding zeroed, cut to size) of the
    message built field by field, and its deserializer: every layout the project writes (empty, 1, 6 and
    18 angles; marked recovering or not; a stamp before 1970; names of multi-byte characters), twice
    (the second time from the layout kept for those names)."""
    from sensor_msgs.msg import JointState

    from gait_biofeedback.wire.joints import (
        angles_of,
        joint_state_bytes,
        joint_state_msg,
        joint_state_of,
        recovering_of,
    )
    from gait_biofeedback.wire.stamps import ns_to_stamp

    rng = np.random.default_rng(len(names))
    for k in range(2):
        angles = {name: float(v) for name, v in zip(names, rng.normal(size=len(names)), strict=True)}
        stamp = ns + k
        reference = JointState(name=list(angles), position=list(angles.values()))
        reference.header.stamp = ns_to_stamp(stamp)
        if recovering:
            reference.header.frame_id = "recovering: " + ",".join(recovering)
        data = joint_state_bytes(angles, stamp, recovering)
        assert data == cdr.serialize(reference)
        assert joint_state_msg(angles, stamp, recovering) == reference
        decoded = deserialize_message(data, JointState)
        expected = (stamp, angles, tuple(recovering))
        assert joint_state_of(data) == (*angles_of(decoded), recovering_of(decoded)) == expected
        assert joint_state_of(serialize_message(reference)) == expected  # rclpy's own, longer bytes


def test_joint_states_of_another_form_are_left_to_rclpy() -> None:
    from gait_biofeedback.wire.joints import joint_state_bytes, joint_state_msg, joint_state_of

    msg = joint_state_msg({"a": 0.5, "b": -0.25}, 10)
    msg.velocity = [1.0, 2.0]
    assert joint_state_of(cdr.serialize(msg)) is None  # a velocity: not the project's form
    data = joint_state_bytes({"a": 0.5, "b": -0.25}, 10)
    assert joint_state_of(b"\x00\x00" + data[2:]) is None  # big endian
    assert joint_state_of(data[:30]) is None  # cut inside a name
    assert joint_state_of(data[:-6]) is None  # cut inside the sequences' counts
    # name "a" (length 2: "a", NUL) at byte 24 (encapsulation, stamp, empty frame_id, padding, count)
    assert data[24:30] == b"\x02\x00\x00\x00a\x00"
    assert joint_state_of(data[:29] + b"x" + data[30:]) is None  # no NUL: rclpy reads it its way
    assert joint_state_of(data[:28] + b"\x00" + data[29:]) is None  # a NUL inside: rclpy cuts there
    marked = joint_state_bytes({"a": 0.5}, 10, ("pelvis",))
    assert joint_state_of(marked) == (10, {"a": 0.5}, ("pelvis",))
    frame_end = 16 + len("recovering: pelvis")  # the frame_id's NUL
    assert marked[frame_end] == 0
    assert joint_state_of(marked[:frame_end] + b"x" + marked[frame_end + 1:]) is None  # frame_id without NUL
