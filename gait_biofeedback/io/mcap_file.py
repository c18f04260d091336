"""Low-level, damage-tolerant reading of one MCAP file.

A complete file is indexed from its summary section (schemas, channels, statistics, chunk
indexes) once the summary passes its CRC. A file without a valid footer or summary (recorder
killed, disk full, copied while open, a flipped bit) is scanned record by record from the start;
a chunk that does not decompress or fails its CRC is set aside as a :class:`BadChunk` and the scan
goes on with the next record, and the scan stops at the first record that does not fit in the
file, so every readable chunk is recovered. Reading checks every chunk's CRC: a bad chunk is
skipped (its messages are not counted any more) and reported to :attr:`McapFile.on_bad_chunk`, so
changed data are never returned. The file is memory-mapped, not read into memory.
"""

from __future__ import annotations

import contextlib
import heapq
import mmap
import struct
import zlib
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import lz4.frame
import zstandard

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06
OP_MESSAGE_INDEX, OP_CHUNK_INDEX, OP_STATISTICS, OP_METADATA, OP_DATA_END = 0x07, 0x08, 0x0B, 0x0C, 0x0F
_RECORD_HEAD = struct.Struct("<BQ")
_MESSAGE_HEAD = struct.Struct("<HIQQ")
_MESSAGE_RECORD = struct.Struct("<BQHIQQ")  # a message record's opcode, length and head
_FOOTER_SIZE = 1 + 8 + 20
_NO_LIMIT = 2**64 - 1
_DAMAGE_ERRORS = (ValueError, struct.error, zstandard.ZstdError, RuntimeError, UnicodeDecodeError, IndexError)


class RawMessage(NamedTuple):
    """One MCAP message record, payload undecoded."""

    log_time: int
    channel_id: int
    publish_time: int
    sequence: int
    data: bytes


@dataclass(frozen=True)
class SchemaInfo:
    """An MCAP schema record."""

    id: int
    name: str
    encoding: str
    data: bytes


@dataclass(frozen=True)
class ChannelInfo:
    """An MCAP channel record."""

    id: int
    schema_id: int
    topic: str
    message_encoding: str
    metadata: dict[str, str]


@dataclass
class ChunkRef:
    """Where a chunk record's body lies in the file and what it covers."""

    offset: int
    start: int
    end: int
    channel_ids: frozenset[int] | None = None
    message_index: dict[int, int] | None = None  # channel id → offset of its message index record


@dataclass(frozen=True)
class BadChunk:
    """A chunk whose data cannot be trusted (does not decompress, fails its CRC, overruns)."""

    offset: int  # of the chunk record in the file
    start_ns: int  # log times it covers, as its header or index says
    end_ns: int
    messages: int | None  # how many it held, from the file's message indexes (None: unknown)
    reason: str


@dataclass
class McapFile:
    """Index of one MCAP file; :meth:`open` builds it, :meth:`messages` reads it."""

    path: Path
    size: int = 0
    complete: bool = False
    damage: str = ""
    profile: str = ""
    library: str = ""
    schemas: dict[int, SchemaInfo] = field(default_factory=dict)
    channels: dict[int, ChannelInfo] = field(default_factory=dict)
    chunks: list[ChunkRef] = field(default_factory=list)
    loose_messages: list[RawMessage] = field(default_factory=list)
    metadata: list[tuple[str, dict[str, str]]] = field(default_factory=list)
    channel_counts: Counter[int] = field(default_factory=Counter)
    start_time: int | None = None
    end_time: int | None = None
    bad_chunks: list[BadChunk] = field(default_factory=list)
    salvaged_definitions: int = 0  # channels known only from a chunk that failed its CRC
    on_bad_chunk: Callable[[McapFile, BadChunk], None] | None = None  # called once per bad chunk found
    _summary_problem: str = ""
    _buf: mmap.mmap | bytes = b""

    @classmethod
    def open(cls, path: Path) -> McapFile:
        """Index ``path``; raise ValueError when it is not an MCAP file at all."""
        mcap = cls(Path(path))
        with open(mcap.path, "rb") as f:
            mcap.size = f.seek(0, 2)
            mcap._buf = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) if mcap.size else b""
        head = bytes(mcap._buf[:8])
        if not MAGIC.startswith(head) or (mcap.size >= 9 and mcap._buf[8] != OP_HEADER):
            mcap.close()
            raise ValueError(f"{mcap.path} is not an MCAP file (it does not start with the MCAP magic bytes)")
        try:
            indexed = mcap._read_summary()
        except _DAMAGE_ERRORS:
            indexed = False
        if not indexed:
            mcap._reset_index()
            mcap._scan_data()
        return mcap

    def _reset_index(self) -> None:
        self.schemas.clear()
        self.channels.clear()
        self.chunks.clear()
        self.bad_chunks.clear()
        self.salvaged_definitions = 0
        self.channel_counts.clear()
        self.start_time = self.end_time = None

    def close(self) -> None:
        """Release the memory map."""
        if isinstance(self._buf, mmap.mmap):
            self._buf.close()
        self._buf = b""

    @property
    def message_count(self) -> int:
        """Readable messages: those on a channel the file defines."""
        return sum(n for c, n in self.channel_counts.items() if c in self.channels)

    def topic_types(self) -> dict[str, str]:
        """``{topic: schema name}`` of the channels in this file."""
        return {
            c.topic: self.schemas[c.schema_id].name if c.schema_id in self.schemas else ""
            for c in self.channels.values()
        }

    # -- indexing -------------------------------------------------------------------------------

    def _read_summary(self) -> bool:
        buf, size = self._buf, self.size
        footer_at = size - 8 - _FOOTER_SIZE
        if footer_at < 8 or buf[size - 8 :] != MAGIC or buf[footer_at] != OP_FOOTER:
            return False
        summary_start, _, crc = struct.unpack_from("<QQI", buf, footer_at + 9)
        if not 8 < summary_start <= footer_at:
            return False
        if crc and zlib.crc32(buf[summary_start : footer_at + 25]) != crc:
            self._summary_problem = "its summary section fails its CRC"
            return False
        self._parse_header()
        has_chunk_index = has_statistics = False
        for op, body in self._records(summary_start, footer_at):
            if op == OP_SCHEMA:
                self._add_schema(buf, body)
            elif op == OP_CHANNEL:
                self._add_channel(buf, body)
            elif op == OP_CHUNK_INDEX:
                has_chunk_index = True
                start, stop, chunk_offset = struct.unpack_from("<QQQ", buf, body)
                (map_len,) = struct.unpack_from("<I", buf, body + 32)
                entries = range(body + 36, body + 36 + map_len, 10)
                index = dict(struct.unpack_from("<HQ", buf, p) for p in entries)
                self.chunks.append(ChunkRef(chunk_offset + 9, start, stop, frozenset(index), index))
            elif op == OP_STATISTICS:
                has_statistics = True
                self._parse_statistics(body)
        if not has_statistics or (self.channel_counts.total() and not has_chunk_index):
            return False
        self.complete = True
        return True

    def _parse_header(self) -> None:
        if self.size >= 9 + 8:
            op, length = _RECORD_HEAD.unpack_from(self._buf, 8)
            if op == OP_HEADER and 17 + length <= self.size:
                self.profile, p = _string(self._buf, 17)
                self.library, _ = _string(self._buf, p)

    def _parse_statistics(self, body: int) -> None:
        buf = self._buf
        (message_count,) = struct.unpack_from("<Q", buf, body)
        start, end = struct.unpack_from("<QQ", buf, body + 8 + 2 + 4 * 4)
        p = body + 8 + 2 + 16 + 16
        (map_len,) = struct.unpack_from("<I", buf, p)
        for q in range(p + 4, p + 4 + map_len, 10):
            channel_id, count = struct.unpack_from("<HQ", buf, q)
            self.channel_counts[channel_id] = count
        if message_count:
            self.start_time, self.end_time = start, end

    def _scan_data(self) -> None:
        buf, pos = self._buf, 8
        self._parse_header()
        while True:
            if pos + 9 > self.size:
                if self.size < 8:
                    self.damage = "file ends inside the MCAP magic"
                elif pos < self.size:
                    self.damage = f"file ends inside a record header at byte {pos}"
                else:
                    self.damage = "no summary section"
                break
            op, length = _RECORD_HEAD.unpack_from(buf, pos)
            body, end = pos + 9, pos + 9 + length
            if end > self.size:
                self.damage = f"record at byte {pos} is cut off ({self.size - body} of {length} bytes)"
                break
            if op in (OP_DATA_END, OP_FOOTER):
                self.damage = self._summary_problem or "summary section missing or unreadable"
                break
            if op == OP_CHUNK:
                try:
                    self._index_chunk(body)
                except _DAMAGE_ERRORS as err:  # set aside; the records after it are still framed
                    self._set_aside(body, None, f"{type(err).__name__}: {err}")
                    self._salvage_definitions(body)
                pos = end
                continue
            try:
                self._scan_record(op, body, end)
            except _DAMAGE_ERRORS as err:
                self.damage = f"record at byte {pos} is corrupt ({type(err).__name__}: {err})"
                break
            pos = end
        if self.bad_chunks:
            self.damage += f"; {len(self.bad_chunks)} unreadable chunk(s) set aside"
        if self.salvaged_definitions:
            self.damage += (f"; {self.salvaged_definitions} topic definition(s) taken from an unreadable "
                            "chunk (check the topic names)")

    def _scan_record(self, op: int, body: int, end: int) -> None:
        buf = self._buf
        if op == OP_SCHEMA:
            self._add_schema(buf, body)
        elif op == OP_CHANNEL:
            self._add_channel(buf, body)
        elif op == OP_MESSAGE:
            message = _message(buf, body, end)
            self.loose_messages.append(message)
            self._count(message)
        elif op == OP_METADATA:
            name, p = _string(buf, body)
            self.metadata.append((name, _string_map(buf, p)))

    def _index_chunk(self, body: int) -> None:
        """Decompress, check and parse a chunk; index it only if all of it is readable. Its time
        range comes from its messages (the CRC does not cover the chunk header's)."""
        records = list(_chunk_records(self._chunk_data(body, check_crc=True)))
        messages = [_message(data, p, q) for op, data, p, q in records if op == OP_MESSAGE]
        self._add_definitions(records)
        for message in messages:
            self._count(message)
        times = [m.log_time for m in messages] or [0]
        self.chunks.append(ChunkRef(body, min(times), max(times), frozenset(m.channel_id for m in messages)))

    def _add_definitions(self, records: list[tuple[int, bytes, int, int]]) -> None:
        for op, data, p, _ in records:
            if op == OP_SCHEMA:
                self._add_schema(data, p)
            elif op == OP_CHANNEL:
                self._add_channel(data, p)

    def _salvage_definitions(self, body: int) -> None:
        """The schemas and channels of a chunk that fails its CRC but still decompresses: the writer
        puts each topic's definition only in the chunk of its first message, so without them every
        later message of the topic would be lost too. Its messages stay set aside."""
        try:
            records = list(_chunk_records(self._chunk_data(body, check_crc=False)))
            known = len(self.channels)
            self._add_definitions([r for r in records if r[0] in (OP_SCHEMA, OP_CHANNEL)])
        except _DAMAGE_ERRORS:
            return
        if len(self.channels) > known:
            self.salvaged_definitions += len(self.channels) - known

    def _count(self, message: RawMessage) -> None:
        self.channel_counts[message.channel_id] += 1
        t = message.log_time
        self.start_time = t if self.start_time is None else min(self.start_time, t)
        self.end_time = t if self.end_time is None else max(self.end_time, t)

    def _add_schema(self, buf: bytes | mmap.mmap, body: int) -> None:
        (schema_id,) = struct.unpack_from("<H", buf, body)
        name, p = _string(buf, body + 2)
        encoding, p = _string(buf, p)
        (n,) = struct.unpack_from("<I", buf, p)
        self.schemas[schema_id] = SchemaInfo(schema_id, name, encoding, bytes(buf[p + 4 : p + 4 + n]))

    def _add_channel(self, buf: bytes | mmap.mmap, body: int) -> None:
        channel_id, schema_id = struct.unpack_from("<HH", buf, body)
        topic, p = _string(buf, body + 4)
        encoding, p = _string(buf, p)
        self.channels[channel_id] = ChannelInfo(channel_id, schema_id, topic, encoding, _string_map(buf, p))

    def _records(self, pos: int, stop: int) -> Iterator[tuple[int, int]]:
        while pos + 9 <= stop:
            op, length = _RECORD_HEAD.unpack_from(self._buf, pos)
            yield op, pos + 9
            pos += 9 + length

    # -- reading --------------------------------------------------------------------------------

    def _chunk_data(self, body: int, check_crc: bool = False) -> bytes:
        _, _, size, crc = _chunk_head(self._buf, body)
        compression, p = _string(self._buf, body + 28)
        (n,) = struct.unpack_from("<Q", self._buf, p)
        raw = self._buf[p + 8 : p + 8 + n]
        self._release(p + 8, n)
        if compression == "zstd":
            data = zstandard.ZstdDecompressor().decompress(raw, max_output_size=size)
        elif compression == "lz4":
            data = lz4.frame.decompress(raw)
        elif compression == "":
            data = bytes(raw)
        else:
            raise ValueError(f"unsupported chunk compression {compression!r}")
        if check_crc and crc and zlib.crc32(data) != crc:
            raise ValueError("CRC mismatch")
        return data

    def _release(self, start: int, length: int) -> None:
        """Drop the mapped file's pages of a chunk just copied out from this process's resident memory
        (they are re-read from the page cache if needed): reading an hour's 390 MB file otherwise kept
        all of it resident, counted in the process' memory."""
        if isinstance(self._buf, mmap.mmap) and hasattr(mmap, "MADV_DONTNEED"):
            first = start - start % mmap.PAGESIZE
            with contextlib.suppress(OSError, ValueError):
                self._buf.madvise(mmap.MADV_DONTNEED, first, start + length - first)

    def _set_aside(self, body: int, chunk: ChunkRef | None, reason: str) -> None:
        """Record a bad chunk once: uncount its messages (per the message indexes), tell the owner."""
        if any(b.offset == body - 9 for b in self.bad_chunks):
            return
        if chunk is None:
            try:
                start, end, _, _ = _chunk_head(self._buf, body)
            except struct.error:
                start = end = 0
        else:
            start, end = chunk.start, chunk.end
            self.chunks.remove(chunk)
        counts = self._indexed_counts(chunk) if chunk is not None else None
        if counts is not None:
            self.channel_counts.subtract(counts)
        bad = BadChunk(body - 9, start, end, None if counts is None else sum(counts.values()), reason)
        self.bad_chunks.append(bad)
        if self.on_bad_chunk is not None:
            self.on_bad_chunk(self, bad)

    def _indexed_counts(self, chunk: ChunkRef) -> dict[int, int] | None:
        """Messages per channel in ``chunk`` from its message index records (16 bytes per entry)."""
        if not chunk.message_index:
            return None
        counts = {}
        try:
            for channel_id, offset in chunk.message_index.items():
                op, _, _, n = struct.unpack_from("<BQHI", self._buf, offset)
                if op != OP_MESSAGE_INDEX:
                    return None
                counts[channel_id] = n // 16
        except struct.error:
            return None
        return counts

    def verify(self) -> list[BadChunk]:
        """Check every chunk (decompress, CRC, record framing): the bad ones, now set aside."""
        for chunk in list(self.chunks):
            self._chunk_messages(chunk, None)
        return list(self.bad_chunks)

    def _chunk_messages(self, chunk: ChunkRef, channel_ids: frozenset[int] | None) -> list[RawMessage]:
        try:
            return _chunk_message_list(self._chunk_data(chunk.offset, check_crc=True), channel_ids)
        except _DAMAGE_ERRORS as err:
            self._set_aside(chunk.offset, chunk, f"{type(err).__name__}: {err}")
            return []

    def messages(
        self, channel_ids: frozenset[int] | None = None, start: int | None = None, stop: int | None = None
    ) -> Iterator[RawMessage]:
        """Messages with ``start <= log_time < stop``, in log-time order (ties keep file order)."""
        for batch in self.message_batches(channel_ids, start, stop):
            yield from batch

    def message_batches(
        self, channel_ids: frozenset[int] | None = None, start: int | None = None, stop: int | None = None
    ) -> Iterator[list[RawMessage]]:
        """:meth:`messages` in lists: a chunk's at once where chunks do not overlap in time (a reader
        that maps each message does it in one comprehension per chunk)."""
        lo, hi = start or 0, _NO_LIMIT if stop is None else stop
        chunks = sorted(
            (
                c
                for c in self.chunks
                if c.end >= lo
                and c.start < hi
                and (channel_ids is None or c.channel_ids is None or c.channel_ids & channel_ids)
            ),
            key=lambda c: (c.start, c.offset),
        )
        pending: list[tuple[int, int, RawMessage]] = []
        order = 0
        for m in self.loose_messages:
            if (channel_ids is None or m.channel_id in channel_ids) and lo <= m.log_time < hi:
                pending.append((m.log_time, order, m))
                order += 1
        heapq.heapify(pending)
        for i, chunk in enumerate(chunks):
            next_start = chunks[i + 1].start if i + 1 < len(chunks) else _NO_LIMIT + 1
            batch = self._chunk_messages(chunk, channel_ids)
            times = [m.log_time for m in batch]
            if lo or max(times, default=0) >= hi:  # some are out of the range
                batch = [m for m in batch if lo <= m.log_time < hi]
                times = [m.log_time for m in batch]
            # a sorted chunk whose last message is not after the next chunk's start goes out whole: at
            # equal times its messages come first, as the heap's order numbers put them
            if not pending and times == sorted(times) and (not times or times[-1] <= next_start):
                yield batch
                continue
            for m in batch:
                heapq.heappush(pending, (m.log_time, order, m))
                order += 1
            ready = []
            while pending and pending[0][0] < next_start:
                ready.append(heapq.heappop(pending)[2])
            yield ready
        yield [heapq.heappop(pending)[2] for _ in range(len(pending))]


def _string(buf: bytes | mmap.mmap, p: int) -> tuple[str, int]:
    (n,) = struct.unpack_from("<I", buf, p)
    return bytes(buf[p + 4 : p + 4 + n]).decode("utf-8"), p + 4 + n


def _string_map(buf: bytes | mmap.mmap, p: int) -> dict[str, str]:
    (n,) = struct.unpack_from("<I", buf, p)
    out: dict[str, str] = {}
    q, end = p + 4, p + 4 + n
    while q < end:
        key, q = _string(buf, q)
        out[key], q = _string(buf, q)
    return out


def _message(buf: bytes | mmap.mmap, body: int, end: int) -> RawMessage:
    channel_id, sequence, log_time, publish_time = _MESSAGE_HEAD.unpack_from(buf, body)
    return RawMessage(log_time, channel_id, publish_time, sequence, bytes(buf[body + 22 : end]))


def _chunk_head(buf: bytes | mmap.mmap, body: int) -> tuple[int, int, int, int]:
    return struct.unpack_from("<QQQI", buf, body)  # start, end, uncompressed size, uncompressed crc


def _chunk_message_list(data: bytes, channel_ids: frozenset[int] | None) -> list[RawMessage]:
    """The message records of a chunk's ``data`` (of ``channel_ids``; None: all), in file order: what
    :func:`_chunk_records` and :func:`_message` give, in one loop (a chunk holds thousands: the loop is
    ``analyze``'s reading). ValueError when a record overruns the chunk or a message record read is
    shorter than its head (other channels' are skipped unread, as before)."""
    out: list[RawMessage] = []
    append, head, message_record = out.append, _RECORD_HEAD.unpack_from, _MESSAGE_RECORD.unpack_from
    new = tuple.__new__  # a RawMessage without its constructor's call: half the cost
    pos, n = 0, len(data)
    while pos + 9 <= n:
        if pos + 31 <= n:  # read as a message record's head (one read: most records are messages)
            op, length, channel_id, sequence, log_time, publish_time = message_record(data, pos)
        else:
            (op, length), channel_id = head(data, pos), None
        body = pos + 9
        end = body + length
        if end > n:
            raise ValueError(f"chunk record at {pos} overruns the chunk")
        if op == OP_MESSAGE and (channel_ids is None or channel_id in channel_ids):
            if length < 22:
                raise ValueError(f"message record at {pos} is shorter than its head")
            append(new(RawMessage, (log_time, channel_id, publish_time, sequence, data[body + 22 : end])))
        pos = end
    return out


def _chunk_records(data: bytes) -> Iterator[tuple[int, bytes, int, int]]:
    pos, n = 0, len(data)
    while pos + 9 <= n:
        op, length = _RECORD_HEAD.unpack_from(data, pos)
        end = pos + 9 + length
        if end > n:
            raise ValueError(f"chunk record at {pos} overruns the chunk")
        yield op, data, pos + 9, end
        pos = end
