"""A chunked, indexed MCAP writer, written from the MCAP specification (mcap.dev/spec), for speed.

The PyPI ``mcap`` writer builds every record through a general record builder: about 20 µs per
message, a sixth of ``analyze``'s time and a large share of the live recorder's. Here a message costs
one ``struct`` pack and two list extends (:meth:`McapWriter.add_messages` takes a run of them in one
call); what is counted per chunk (its time range, its messages per channel) is read from its message
index when it closes; a chunk is joined, checked (CRC-32) and compressed when it is full or flushed.
The file has what the ``mcap`` writer's defaults give, so every reader
(:mod:`gait_biofeedback.io.mcap_file`, ``rosbags``, ``mcap-ros2-support``, Foxglove) reads it alike:
header; schema and channel records inside the chunk in which they are registered; per chunk, one
message index record per channel after it; data end; a summary with the schemas, channels,
statistics and chunk indexes and their summary offsets; a footer whose CRC covers the summary.

Interface (what :class:`~gait_biofeedback.io.bag_writer.BagWriter` uses): :meth:`McapWriter.start`,
:meth:`McapWriter.register_schema`, :meth:`McapWriter.register_channel`, :meth:`McapWriter.add_messages`
(:meth:`McapWriter.add_message`: one), :attr:`McapWriter.on_chunk` (told of each chunk written),
:meth:`McapWriter.flush` (the open chunk to the stream, the stream to the OS: the crash-safety point)
and :meth:`McapWriter.finish`.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Callable, Iterable
from typing import BinaryIO

import lz4.frame
import zstandard

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06
OP_MESSAGE_INDEX, OP_CHUNK_INDEX, OP_STATISTICS, OP_SUMMARY_OFFSET, OP_DATA_END = 0x07, 0x08, 0x0B, 0x0E, 0x0F
COMPRESSIONS = ("zstd", "lz4", "")

_MESSAGE_HEAD = struct.Struct("<BQHIQQ")  # opcode, length, channel id, sequence, log time, publish time
_MESSAGE_HEAD_BYTES = 2 + 4 + 8 + 8
_MESSAGE_RECORD_BYTES = 1 + 8 + _MESSAGE_HEAD_BYTES
_RECORD_HEAD = struct.Struct("<BQ")


def _string(text: str) -> bytes:
    data = text.encode("utf-8")
    return struct.pack("<I", len(data)) + data


def _record(opcode: int, body: bytes) -> bytes:
    return _RECORD_HEAD.pack(opcode, len(body)) + body


def _compress(data: bytes, compression: str) -> bytes:
    if compression == "zstd":
        return zstandard.ZstdCompressor().compress(data)
    if compression == "lz4":
        return lz4.frame.compress(data)
    return data


class McapWriter:
    """Write one MCAP file to ``stream`` (opened for binary writing, positioned at its start).

    ``chunk_size``: uncompressed bytes after which a chunk is closed; ``compression``: ``"zstd"``,
    ``"lz4"`` or ``""``. Schema and channel ids count from 1 in order of registration."""

    def __init__(self, stream: BinaryIO, chunk_size: int = 1024 * 1024, compression: str = "zstd") -> None:
        if compression not in COMPRESSIONS:
            raise ValueError(f"compression {compression!r} unknown; use one of {list(COMPRESSIONS)}")
        self.stream = stream
        self.chunk_size = int(chunk_size)
        self.compression = compression
        self._schemas: list[bytes] = []  # their records, by id - 1
        self._channels: list[bytes] = []
        self._chunk_indexes: list[bytes] = []
        self._channel_counts: dict[int, int] = {}
        self._message_count = 0  # in the chunks written
        self._start_ns = 0
        self._end_ns = 0
        self.on_chunk: Callable[[], None] | None = None
        """Called after each chunk is written to the stream (the owner hands it to the OS there)."""
        self._new_chunk()

    def _new_chunk(self) -> None:
        self._parts: list[bytes] = []
        self._size = 0  # of the chunk's records so far
        self._index: dict[int, list[int]] = {}  # channel id → [log time, offset, log time, offset, …]

    def start(self, profile: str = "", library: str = "") -> None:
        """The magic and the header record."""
        self.stream.write(MAGIC + _record(OP_HEADER, _string(profile) + _string(library)))

    def _add_record(self, record: bytes) -> None:
        self._parts.append(record)
        self._size += len(record)

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        """A schema (``ros2msg`` text, for example); its id."""
        schema_id = len(self._schemas) + 1
        record = _record(OP_SCHEMA, struct.pack("<H", schema_id) + _string(name) + _string(encoding)
                         + struct.pack("<I", len(data)) + data)
        self._schemas.append(record)
        self._add_record(record)
        return schema_id

    def register_channel(self, topic: str, message_encoding: str, schema_id: int,
                         metadata: dict[str, str] | None = None) -> int:
        """A channel (topic) of a registered schema; its id."""
        channel_id = len(self._channels) + 1
        pairs = b"".join(_string(k) + _string(v) for k, v in (metadata or {}).items())
        record = _record(OP_CHANNEL, struct.pack("<HH", channel_id, schema_id) + _string(topic)
                         + _string(message_encoding) + struct.pack("<I", len(pairs)) + pairs)
        self._channels.append(record)
        self._channel_counts[channel_id] = 0
        self._add_record(record)
        return channel_id

    def add_message(self, channel_id: int, log_time: int, data: bytes, publish_time: int,
                    sequence: int = 0) -> None:
        """One message of a registered channel (log and publish time in ns): :meth:`McapWriter.add_messages`
        of one."""
        self.add_messages(((log_time, channel_id, publish_time, sequence, data),))

    def add_messages(self, messages: Iterable[tuple[int, int, int, int, bytes]]) -> None:
        """Messages ``(log time, channel id, publish time, sequence, data)`` (the order of
        :class:`~gait_biofeedback.io.mcap_file.RawMessage`) of registered channels, in their order. Per
        message: its record's head packed, its index entry; what is counted (the chunk's time range
        and message count, each channel's count) is taken from the chunk's message index when the
        chunk closes."""
        index_of, pack, limit = self._index, _MESSAGE_HEAD.pack, self.chunk_size
        parts, size = self._parts, self._size
        for log_time, channel_id, publish_time, sequence, data in messages:
            index = index_of.get(channel_id)
            if index is None:
                if channel_id not in self._channel_counts:
                    raise ValueError(f"channel {channel_id} is not registered")
                index = index_of[channel_id] = []
            index += (log_time, size)
            length = len(data)
            parts += (pack(OP_MESSAGE, _MESSAGE_HEAD_BYTES + length, channel_id, sequence, log_time,
                           publish_time), data)
            size += _MESSAGE_RECORD_BYTES + length
            self._size = size
            if size > limit:
                self._finish_chunk()
                index_of, parts, size = self._index, self._parts, self._size

    @property
    def pending_bytes(self) -> int:
        """Uncompressed bytes of the open chunk."""
        return self._size

    @property
    def written(self) -> tuple[int, int]:
        """(messages in the chunks written, log time of the newest of them; 0: none)."""
        return self._message_count, self._end_ns

    def _open_range(self) -> tuple[int, int]:
        if not self._index:
            return 0, 0
        return (min(min(entries[0::2]) for entries in self._index.values()),
                max(max(entries[0::2]) for entries in self._index.values()))

    def _finish_chunk(self) -> None:
        if not self._index:
            return  # a chunk of schema and channel records only waits for a message
        chunk_start, chunk_end = self._open_range()
        records = b"".join(self._parts)
        data = _compress(records, self.compression)
        body = (struct.pack("<QQQI", chunk_start, chunk_end, len(records), zlib.crc32(records))
                + _string(self.compression) + struct.pack("<Q", len(data)))
        chunk_offset = self.stream.tell()
        chunk = _RECORD_HEAD.pack(OP_CHUNK, len(body) + len(data)) + body
        index_offset = chunk_offset + len(chunk) + len(data)
        indexes, offsets = [], []
        messages = 0
        for channel_id in sorted(self._index):
            entries = self._index[channel_id]
            messages += len(entries) // 2
            self._channel_counts[channel_id] += len(entries) // 2
            offsets.append(struct.pack("<HQ", channel_id, index_offset + sum(map(len, indexes))))
            indexes.append(_record(OP_MESSAGE_INDEX, struct.pack(f"<HI{len(entries)}Q", channel_id,
                                                                   8 * len(entries), *entries)))
        index_bytes = b"".join(indexes)
        self.stream.write(chunk)
        self.stream.write(data)
        self.stream.write(index_bytes)
        offset_map = b"".join(offsets)
        head = struct.pack("<QQQQI", chunk_start, chunk_end, chunk_offset, len(chunk) + len(data),
                           len(offset_map))
        tail = _string(self.compression) + struct.pack("<QQ", len(data), len(records))
        self._chunk_indexes.append(_record(OP_CHUNK_INDEX,
                                           head + offset_map + struct.pack("<Q", len(index_bytes)) + tail))
        if self._message_count == 0:
            self._start_ns, self._end_ns = chunk_start, chunk_end
        else:
            self._start_ns = min(self._start_ns, chunk_start)
            self._end_ns = max(self._end_ns, chunk_end)
        self._message_count += messages
        self._new_chunk()
        if self.on_chunk is not None:
            self.on_chunk()

    def flush(self) -> None:
        """Write the open chunk (if it holds a message) and flush the stream to the OS (no fsync)."""
        self._finish_chunk()
        self.stream.flush()

    def finish(self) -> None:
        """Close the open chunk, write data end, summary, footer and the closing magic. The stream
        stays open."""
        self._finish_chunk()
        self.stream.write(_record(OP_DATA_END, struct.pack("<I", 0)))
        summary_start = self.stream.tell()
        groups: list[tuple[int, bytes]] = []
        counts = b"".join(struct.pack("<HQ", c, n) for c, n in self._channel_counts.items())
        statistics = _record(OP_STATISTICS, struct.pack(
            "<QHIIIIQQI", self._message_count, len(self._schemas), len(self._channels), 0, 0,
            len(self._chunk_indexes), self._start_ns, self._end_ns, len(counts)) + counts)
        for opcode, records in ((OP_SCHEMA, self._schemas), (OP_CHANNEL, self._channels),
                                (OP_STATISTICS, [statistics]), (OP_CHUNK_INDEX, self._chunk_indexes)):
            if records:
                groups.append((opcode, b"".join(records)))
        summary = b"".join(data for _, data in groups)
        offsets, position = [], summary_start
        for opcode, data in groups:
            offsets.append(_record(OP_SUMMARY_OFFSET, struct.pack("<BQQ", opcode, position, len(data))))
            position += len(data)
        summary_offset_start = summary_start + len(summary)
        summary += b"".join(offsets)
        footer_head = struct.pack("<BQQQ", OP_FOOTER, 8 + 8 + 4, summary_start, summary_offset_start)
        crc = zlib.crc32(footer_head, zlib.crc32(summary))
        self.stream.write(summary + footer_head + struct.pack("<I", crc) + MAGIC)
