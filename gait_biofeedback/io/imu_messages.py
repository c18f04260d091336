"""ImuSeries <-> sensor_msgs/Imu + sensor_msgs/MagneticField, and IMU bags.

Topics: ``/<segment>/imu/data_raw`` (Imu: orientation unknown, so orientation_covariance[0] = -1;
other covariances 0 = unknown) and ``/<segment>/imu/mag`` (MagneticField, when the series has a
magnetometer). header.frame_id = series.frame_id; header.stamp = the sample time.

Time: ``t`` (float s) becomes integer nanoseconds (nearest), i.e. t is quantised to 1 ns. Reading
gives back the float nearest to ns/1e9, so a t on the 1 ns grid (e.g. k/100 s, or any epoch time,
whose float spacing is coarser than 1 ns) round-trips exactly.

Bulk paths (:func:`write_imu_bag`, :func:`read_imu_bag`) pack and unpack the CDR bytes with numpy
instead of building rclpy objects (≈10× faster); the tests check they match rclpy's serialisation.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu, MagneticField

from gait_biofeedback.core.segments import ImuSeries, mag_topic, raw_topic
from gait_biofeedback.io.bag_reader import BagReader
from gait_biofeedback.io.bag_writer import BagWriter
from gait_biofeedback.io.schemas import type_name_of

IMU_TYPE = "sensor_msgs/msg/Imu"
MAG_TYPE = "sensor_msgs/msg/MagneticField"
CDR_LE = b"\x00\x01\x00\x00"
_NS = 1_000_000_000
# Doubles after the header: orientation (4), its covariance (9), angular velocity (3), covariance (9),
# linear acceleration (3), covariance (9); MagneticField: field (3), covariance (9).
IMU_DOUBLES, MAG_DOUBLES = 37, 12
_GYR, _ACC = slice(13, 16), slice(25, 28)


def seconds_to_ns(t: np.ndarray) -> np.ndarray:
    """Float seconds -> nearest int64 nanoseconds (exact split into whole and fractional seconds)."""
    t = np.asarray(t, dtype=float)
    whole = np.floor(t)
    return whole.astype(np.int64) * _NS + np.rint((t - whole) * 1e9).astype(np.int64)


def ns_to_seconds(ns: np.ndarray) -> np.ndarray:
    """Int nanoseconds -> the float nearest to ns/1e9 (Python's correctly rounded int division)."""
    return np.array([n / _NS for n in np.asarray(ns, dtype=np.int64).tolist()], dtype=float)


def topics_of(segment: str) -> tuple[str, str]:
    """Absolute (raw Imu topic, MagneticField topic) of ``segment``."""
    return "/" + raw_topic(segment), "/" + mag_topic(segment)


# -- rclpy messages -------------------------------------------------------------------------------


def _stamp(header: Any, ns: int, frame_id: str) -> None:
    header.stamp.sec, header.stamp.nanosec = divmod(int(ns), _NS)
    header.frame_id = frame_id


def imu_series_to_messages(series: ImuSeries) -> Iterator[tuple[str, Any, int]]:
    """``(topic, message, t_ns)`` for every sample: an Imu, then a MagneticField if mag is present."""
    imu_topic, mag_name = topics_of(series.segment)
    for i, ns in enumerate(seconds_to_ns(series.t).tolist()):
        imu = Imu()
        _stamp(imu.header, ns, series.frame_id)
        imu.orientation_covariance[0] = -1.0
        gx, gy, gz = series.gyr[i].tolist()
        ax, ay, az = series.acc[i].tolist()
        imu.angular_velocity.x, imu.angular_velocity.y, imu.angular_velocity.z = gx, gy, gz
        imu.linear_acceleration.x, imu.linear_acceleration.y, imu.linear_acceleration.z = ax, ay, az
        yield imu_topic, imu, ns
        if series.mag is not None:
            mag = MagneticField()
            _stamp(mag.header, ns, series.frame_id)
            mag.magnetic_field.x, mag.magnetic_field.y, mag.magnetic_field.z = series.mag[i].tolist()
            yield mag_name, mag, ns


# -- CDR with numpy -------------------------------------------------------------------------------


def _record_dtype(frame_id: bytes, n_doubles: int) -> np.dtype:
    """Packed layout of one XCDR1 little-endian message: encapsulation, stamped header, doubles."""
    string_len = len(frame_id) + 1
    pad = -(12 + string_len) % 8
    fields = [("enc", "S4"), ("sec", "<i4"), ("nanosec", "<u4"), ("len", "<u4"), ("frame", f"S{string_len}")]
    if pad:
        fields.append(("pad", f"V{pad}"))
    fields.append(("d", "<f8", (n_doubles,)))
    return np.dtype(fields)


def _encode(ns: np.ndarray, frame_id: str, doubles: np.ndarray) -> list[bytes]:
    frame = frame_id.encode("utf-8")
    dtype = _record_dtype(frame, doubles.shape[1])
    records = np.zeros(len(ns), dtype=dtype)
    sec, nanosec = np.divmod(ns, _NS)
    if len(sec) and (sec.min() < -(2**31) or sec.max() >= 2**31):
        raise ValueError("time stamps do not fit builtin_interfaces/Time (int32 seconds)")
    records["enc"], records["sec"], records["nanosec"] = CDR_LE, sec, nanosec
    records["len"], records["frame"], records["d"] = len(frame) + 1, frame, doubles
    blob, size = records.tobytes(), dtype.itemsize
    return [blob[i : i + size] for i in range(0, len(blob), size)]


def encode_imu(series: ImuSeries) -> tuple[np.ndarray, list[bytes], list[bytes] | None]:
    """``(t_ns, Imu payloads, MagneticField payloads or None)``, as serialize_message would give."""
    ns = seconds_to_ns(series.t)
    doubles = np.zeros((len(ns), IMU_DOUBLES))
    doubles[:, 3], doubles[:, 4] = 1.0, -1.0  # orientation w = 1, orientation_covariance[0] = -1
    doubles[:, _GYR], doubles[:, _ACC] = series.gyr, series.acc
    imu = _encode(ns, series.frame_id, doubles)
    mag = None
    if series.mag is not None:
        mag = _encode(ns, series.frame_id, np.hstack([series.mag, np.zeros((len(ns), 9))]))
    return ns, imu, mag


def decode_stamped(
    payloads: list[bytes], msg_class: type, n_doubles: int
) -> tuple[np.ndarray, np.ndarray, str]:
    """``(t_ns, doubles (N, n_doubles), first frame_id)`` of Imu/MagneticField payloads."""
    ns = np.empty(len(payloads), dtype=np.int64)
    doubles = np.empty((len(payloads), n_doubles))
    frame_id = ""
    by_size: dict[int, list[int]] = {}
    for i, p in enumerate(payloads):
        by_size.setdefault(len(p), []).append(i)
    for indices in by_size.values():
        first = payloads[indices[0]]
        frame_len = int.from_bytes(first[12:16], "little") if len(first) >= 16 else 0
        dtype = _record_dtype(b"x" * max(frame_len - 1, 0), n_doubles)
        records = None
        if first[:4] == CDR_LE and dtype.itemsize == len(first):
            records = np.frombuffer(b"".join(payloads[i] for i in indices), dtype=dtype)
            if np.any(records["len"] != frame_len) or np.any(records["enc"] != CDR_LE):
                records = None
        if records is None:  # other encapsulation or layout: let rclpy decode
            for i in indices:
                ns[i], doubles[i], name = _decode_with_rclpy(payloads[i], msg_class)
                frame_id = frame_id or name
            continue
        ns[indices] = records["sec"].astype(np.int64) * _NS + records["nanosec"]
        doubles[indices] = records["d"]
        frame_id = frame_id or records["frame"][0].decode("utf-8")
    return ns, doubles, frame_id


def _decode_with_rclpy(payload: bytes, msg_class: type) -> tuple[int, np.ndarray, str]:
    msg = deserialize_message(payload, msg_class)
    ns = msg.header.stamp.sec * _NS + msg.header.stamp.nanosec
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


# -- bags -----------------------------------------------------------------------------------------


def write_imu_bag(
    path: str | Path,
    imu: dict[str, ImuSeries],
    extra: Iterable[tuple[str, Any, int]] = (),
    **writer_options: Any,
) -> Path:
    """Write IMU series (and ``extra`` ``(topic, rclpy message, t_ns)``) to a bag, in time order.

    Log time = header stamp. ``writer_options`` go to :class:`BagWriter` (e.g. ``overwrite=True``).
    Returns the bag folder.
    """
    streams: list[tuple[str, str, np.ndarray, list[bytes]]] = []
    for key, series in imu.items():
        if key != series.segment:
            raise ValueError(f"imu[{key!r}] holds the series of segment {series.segment!r}; keys must match")
        ns, imu_payloads, mag_payloads = encode_imu(series)
        imu_topic, mag_name = topics_of(series.segment)
        streams.append((imu_topic, IMU_TYPE, ns, imu_payloads))
        if mag_payloads is not None:
            streams.append((mag_name, MAG_TYPE, ns, mag_payloads))
    extra_items = [(topic, type_name_of(msg), int(t), serialize_message(msg)) for topic, msg, t in extra]
    for topic, type_name, t, data in extra_items:
        streams.append((topic, type_name, np.array([t], dtype=np.int64), [data]))

    all_ns = np.concatenate([s[2] for s in streams]) if streams else np.zeros(0, dtype=np.int64)
    stream_of = np.concatenate([np.full(len(s[2]), k) for k, s in enumerate(streams)]) if streams else all_ns
    sample_of = np.concatenate([np.arange(len(s[2])) for s in streams]) if streams else all_ns
    order = np.argsort(all_ns, kind="stable")
    with BagWriter(path, **writer_options) as writer:
        write = writer.write_serialized
        for t, k, i in zip(
            all_ns[order].tolist(), stream_of[order].tolist(), sample_of[order].tolist(), strict=True
        ):
            topic, type_name, _, payloads = streams[k]
            write(topic, type_name, payloads[i], t)
    return writer.path


def read_imu_bag(path: str | Path, segments: Iterable[str] | None = None) -> dict[str, ImuSeries]:
    """IMU series of a bag (folder or .mcap), keyed by segment; inverse of :func:`write_imu_bag`.

    A segment is the name before ``/imu/data_raw`` of an Imu topic. Times are header stamps, sorted.
    mag is None without a ``/<segment>/imu/mag`` topic; if its stamps differ from the Imu ones it
    is linearly interpolated onto them.
    """
    with BagReader(path) as reader:
        types = reader.topics()
        found = {
            topic.split("/")[-3]: topic
            for topic, type_name in types.items()
            if type_name == IMU_TYPE and topic.endswith("/imu/data_raw") and topic.count("/") >= 3
        }
        wanted = list(found) if segments is None else list(segments)
        if missing := [s for s in wanted if s not in found]:
            raise ValueError(
                f"{path}: no raw IMU topic for segment(s) {missing}; the bag has {sorted(found)}"
            )
        mag_topics = {s: found[s][: -len("data_raw")] + "mag" for s in wanted}
        mag_topics = {s: t for s, t in mag_topics.items() if types.get(t) == MAG_TYPE}
        payloads: dict[str, list[bytes]] = {
            t: [] for t in [*(found[s] for s in wanted), *mag_topics.values()]
        }
        for topic, _, data, _ in reader.raw_messages(topics=payloads):
            payloads[topic].append(data)
    result = {}
    for segment in wanted:
        ns, doubles, frame_id = decode_stamped(payloads[found[segment]], Imu, IMU_DOUBLES)
        order = np.argsort(ns, kind="stable")
        ns, doubles = ns[order], doubles[order]
        mag = None
        if segment in mag_topics and payloads[mag_topics[segment]]:
            mag_ns, mag_doubles, _ = decode_stamped(payloads[mag_topics[segment]], MagneticField, MAG_DOUBLES)
            mag_order = np.argsort(mag_ns, kind="stable")
            mag_ns, mag = mag_ns[mag_order], mag_doubles[mag_order, :3]
            if not np.array_equal(mag_ns, ns):
                rel = (mag_ns - ns[0]) / 1e9 if len(ns) else mag_ns / 1e9
                at = (ns - ns[0]) / 1e9 if len(ns) else ns / 1e9
                mag = np.column_stack([np.interp(at, rel, mag[:, k]) for k in range(3)])
        result[segment] = ImuSeries(
            segment, ns_to_seconds(ns), doubles[:, _ACC], doubles[:, _GYR], mag, frame_id
        )
    return result
