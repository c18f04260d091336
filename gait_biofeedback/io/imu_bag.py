"""Whole IMU recordings ↔ bags: :class:`~gait_biofeedback.core.segments.ImuSeries` per segment on
``/<segment>/imu/data_raw`` (+ ``/<segment>/imu/mag``), header.frame_id = the series' frame id,
header.stamp = the sample time.

Time: ``t`` (float s) becomes integer nanoseconds (nearest), i.e. t is quantised to 1 ns. Reading
gives back the float nearest to ns/1e9, so a t on the 1 ns grid (e.g. k/100 s, or any epoch time,
whose float spacing is coarser than 1 ns) round-trips exactly. Both directions pack and unpack the
CDR bytes with numpy (:mod:`gait_biofeedback.wire.cdr`) instead of building rclpy objects (≈10×
faster); the tests check they match rclpy's serialisation.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from sensor_msgs.msg import Imu, MagneticField

from gait_biofeedback.core.segments import ImuSeries
from gait_biofeedback.core.stamps import ns_to_seconds
from gait_biofeedback.io.bag_reader import BagReader
from gait_biofeedback.io.bag_writer import BagWriter
from gait_biofeedback.io.schemas import type_name_of
from gait_biofeedback.wire import topics
from gait_biofeedback.wire.cdr import (
    ANGULAR_VELOCITY,
    IMU_DOUBLES,
    LINEAR_ACCELERATION,
    MAG_DOUBLES,
    decode_stamped,
    serialize,
)
from gait_biofeedback.wire.imu import encode_series, series_topics


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
    for key, series in imu.items():
        if key != series.segment:
            raise ValueError(f"imu[{key!r}] holds the series of segment {series.segment!r}; keys must match")
    extra_streams = [(topic, type_name_of(msg), np.array([int(t)], dtype=np.int64), [serialize(msg)])
                     for topic, msg, t in extra]
    with BagWriter(path, **{"flush_period_s": None, **writer_options}) as writer:
        write_series(writer, imu, extra_streams)
    return writer.path


Stream = tuple[str, str, np.ndarray, list[bytes]]
"""(topic, type name, log times ns, CDR payloads) of one topic's messages."""


def write_series(writer: BagWriter, imu: dict[str, ImuSeries], extra: Sequence[Stream] = ()) -> None:
    """The messages of IMU series (and ``extra`` streams) into ``writer`` by log time = header stamp; at
    one time by series, Imu before MagneticField, then ``extra`` (a stable sort)."""
    imu_type, mag_type = topics.raw_imu("x").type_name, topics.magnetometer("x").type_name
    streams: list[Stream] = []
    for series in imu.values():
        ns, imu_payloads, mag_payloads = encode_series(series)
        imu_topic, mag_name = series_topics(series.segment)
        streams.append((imu_topic, imu_type, ns, imu_payloads))
        if mag_payloads is not None:
            streams.append((mag_name, mag_type, ns, mag_payloads))
    streams += extra
    if not streams:
        return
    all_ns = np.concatenate([s[2] for s in streams])
    stream_of = np.concatenate([np.full(len(s[2]), k) for k, s in enumerate(streams)])
    sample_of = np.concatenate([np.arange(len(s[2])) for s in streams])
    order = np.argsort(all_ns, kind="stable")
    writer.write_many((t, streams[k][0], streams[k][1], streams[k][3][i], False) for t, k, i in zip(
        all_ns[order].tolist(), stream_of[order].tolist(), sample_of[order].tolist(), strict=True))


DECODE_BLOCK = 20_000
"""Messages of a topic decoded together: the payloads are kept only this long, so reading an hour
(2.9 M messages of 8 sensors, about 1 GB of CDR) holds the decoded columns and one block."""


class _Columns:
    """One topic's messages decoded a block at a time into the columns wanted (``columns``: slices of the
    message's doubles), stamps int ns, in arrays sized for ``expected`` messages (the file's count;
    grown if it holds more)."""

    def __init__(self, msg_class: type, n_doubles: int, columns: Sequence[slice], expected: int) -> None:
        self.msg_class, self.n_doubles, self.columns = msg_class, n_doubles, columns
        self.payloads: list[bytes] = []
        self.ns = np.empty(expected, np.int64)
        self.values = [np.empty((expected, c.stop - c.start)) for c in columns]
        self.size = 0
        self.frame_id = ""

    def add(self, data: bytes) -> None:
        self.payloads.append(data)
        if len(self.payloads) >= DECODE_BLOCK:
            self._decode()

    def _decode(self) -> None:
        if not self.payloads:
            return
        ns, doubles, frame_id = decode_stamped(self.payloads, self.msg_class, self.n_doubles)
        self.frame_id = self.frame_id or frame_id
        self.payloads = []
        end = self.size + len(ns)
        if end > len(self.ns):  # more than the file's summary said (a repaired file)
            grown = max(end, 2 * len(self.ns))
            self.ns = np.resize(self.ns, grown)
            self.values = [np.resize(v, (grown, v.shape[1])) for v in self.values]
        self.ns[self.size:end] = ns
        for out, c in zip(self.values, self.columns, strict=True):
            out[self.size:end] = doubles[:, c]
        self.size = end

    def sorted(self) -> tuple[np.ndarray, list[np.ndarray]]:
        """(stamps, columns), ordered by stamp (a stable sort: log order among equal stamps)."""
        self._decode()
        ns, values = self.ns[:self.size], [v[:self.size] for v in self.values]
        if len(ns) > 1 and np.any(ns[1:] < ns[:-1]):
            order = np.argsort(ns, kind="stable")
            ns, values = ns[order], [v[order] for v in values]
        return ns, values


def read_imu_bag(path: str | Path, segments: Iterable[str] | None = None) -> dict[str, ImuSeries]:
    """IMU series of a bag (folder or .mcap), keyed by segment; inverse of :func:`write_imu_bag`.

    A segment is the name before ``/imu/data_raw`` of an Imu topic. Times are header stamps, sorted.
    mag is None without a ``/<segment>/imu/mag`` topic; if its stamps differ from the Imu ones it
    is linearly interpolated onto them. Memory: the series (sized from the file's message counts), and
    :data:`DECODE_BLOCK` messages.
    """
    with BagReader(path) as reader:
        found, mag_found = topics.recorded_imu_topics(reader.topics())
        wanted = list(found) if segments is None else list(segments)
        if missing := [s for s in wanted if s not in found]:
            raise ValueError(
                f"{path}: no raw IMU topic for segment(s) {missing}; the bag has {sorted(found)}"
            )
        mag_topics = {s: mag_found[s] for s in wanted if s in mag_found}
        counts = reader.message_counts()
        imu_columns = (LINEAR_ACCELERATION, ANGULAR_VELOCITY)
        columns = {found[s]: _Columns(Imu, IMU_DOUBLES, imu_columns, counts.get(found[s], 0)) for s in wanted}
        columns.update({t: _Columns(MagneticField, MAG_DOUBLES, (slice(0, 3),), counts.get(t, 0))
                        for t in mag_topics.values()})
        for topic, _, data, _ in reader.raw_messages(topics=columns):
            columns[topic].add(data)
    result = {}
    for segment in wanted:
        imu = columns[found[segment]]
        ns, (acc, gyr) = imu.sorted()
        mag = None
        if segment in mag_topics:
            mag_ns, (mag_values,) = columns[mag_topics[segment]].sorted()
            if len(mag_ns):
                mag = mag_values
                if not np.array_equal(mag_ns, ns):
                    rel = (mag_ns - ns[0]) / 1e9 if len(ns) else mag_ns / 1e9
                    at = (ns - ns[0]) / 1e9 if len(ns) else ns / 1e9
                    mag = np.column_stack([np.interp(at, rel, mag[:, k]) for k in range(3)])
        result[segment] = ImuSeries(segment, ns_to_seconds(ns), acc, gyr, mag, imu.frame_id)
    return result
