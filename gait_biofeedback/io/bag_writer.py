"""Crash-safe rosbag2/MCAP writer: a bag folder with ``metadata.yaml`` and ``<name>_<i>.mcap`` files.

Each file is an MCAP file with profile ``ros2``: schema encoding ``ros2msg`` (full .msg text with
dependencies), message encoding ``cdr``. The open chunk is written out and the file flushed to the
OS at least every ``flush_period_s`` seconds of wall-clock time, so after a kill -9 the file is
readable (and :func:`gait_biofeedback.io.bag.repair`-able) up to its last complete chunk. Flushing
does not fsync: data survive a process crash, not a power cut. After a write error (a full disk)
:meth:`BagWriter.abandon` cuts the open file back to its last complete chunk, so what is on disk reads
cleanly.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from types import TracebackType
from typing import Any, BinaryIO

from gait_biofeedback.core.biofeedback.evaluator import DASHBOARD_LINK_FILE
from gait_biofeedback.core.calibration.stream import CALIBRATION_FILE
from gait_biofeedback.io.bag_metadata import (
    FileRecord,
    TopicRecord,
    bag_metadata,
    qos_profile,
    qos_to_text,
    write_metadata,
)
from gait_biofeedback.io.mcap_writer import McapWriter
from gait_biofeedback.io.params import COMPRESSIONS as COMPRESSION_NAMES
from gait_biofeedback.io.schemas import schema_text, type_description_hash, type_name_of
from gait_biofeedback.wire.cdr import serialize
from gait_biofeedback.wire.padding import Padder

SESSION_FILES = (CALIBRATION_FILE, DASHBOARD_LINK_FILE)
"""Files of a session that may be in its bag folder before the bag (a graph that crashed leaves the
dashboard's link)."""
TABLES_FOLDER = "tables"
"""The folder of Parquet tables ``analyze`` writes into its output bag folder
(:mod:`gait_biofeedback.report.tables`): part of the output, replaced with it."""
COMPRESSIONS = dict(zip(COMPRESSION_NAMES, ("zstd", "lz4", ""), strict=True))
LIBRARY = "gait_biofeedback"


def check_output(path: str | Path, overwrite: bool = False) -> None:
    """Raise, with a message that says what to do, unless a bag folder can be written at ``path``:
    it must not be a file, an existing folder must be empty or hold only the session's files
    (:data:`SESSION_FILES`; or hold only a bag, replaced with ``overwrite``), and a file must be creatable
    in it (tried, and removed again with any folder created for the try)."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise FileExistsError(f"{path} exists and is not a folder; a bag is written as a folder")
    if path.is_dir() and any(p.name not in SESSION_FILES for p in path.iterdir()):
        if not overwrite:
            raise FileExistsError(f"bag folder {path} exists and is not empty: write to another folder "
                                  "or remove it first")
        leftovers = [p for p in path.iterdir() if not _bag_part(p)]
        if leftovers:
            raise FileExistsError(f"{path} holds files that are not part of a bag ({leftovers[0].name}); "
                                  "refusing to overwrite it")
    created = [p for p in (path, *path.parents) if not p.exists()]
    probe = path / ".write-test"
    try:
        path.mkdir(parents=True, exist_ok=True)
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise OSError(f"cannot write the bag folder {path} ({exc.strerror}): choose a folder you can "
                      "write to") from None
    finally:
        for folder in created:
            with contextlib.suppress(OSError):
                folder.rmdir()


def _bag_part(path: Path) -> bool:
    if path.is_dir():
        return path.name == TABLES_FOLDER
    return path.suffix == ".mcap" or path.name in ("metadata.yaml", *SESSION_FILES)


Message = tuple[int, str, str, bytes, bool]
"""A message for :meth:`BagWriter.write_many`: (log time ns, topic, type name, CDR bytes, padding zeroed
already)."""
_RUN = 4096  # records handed to the MCAP writer at once, at most


@dataclass(slots=True)
class _Lane:
    """One topic of the bag: its record, its channel id in the open file (0: not registered there
    yet), its messages so far (the sequence number of the last) and its padding check (its own: a
    topic's messages share one layout)."""

    record: TopicRecord
    type_name: str
    channel_id: int
    sequence: int
    pad: Padder


@dataclass
class _McapPart:
    """One open .mcap file of the bag and what has gone into it."""

    path: Path
    stream: BinaryIO
    writer: McapWriter
    schema_ids: dict[str, int] = field(default_factory=dict)
    record: FileRecord = field(default_factory=lambda: FileRecord(""))
    good_offset: int = 0  # end of the last complete chunk handed to the OS
    good_end_ns: int = 0  # log time of the newest message before it
    good_messages: int = 0  # messages before it

    def size_estimate(self) -> int:
        """Bytes on disk plus the open chunk uncompressed (an upper bound of the final size)."""
        return self.stream.tell() + self.writer.pending_bytes


class BagWriter:
    """Write ROS 2 messages to a rosbag2 bag folder (MCAP storage).

    ``path`` is the bag folder; files are ``<path>/<path.name>_0.mcap``, ``_1.mcap`` … (a new one
    when ``split_size_bytes`` bytes or ``split_duration_s`` seconds of log time are exceeded).
    ``flush_period_s`` (s, wall clock) bounds how much a crash can lose; call :meth:`maybe_flush` from
    a timer when messages may stop arriving. ``flush_period_s=None`` (offline writers: ``analyze``,
    ``import``, ``simulate``, fault injection) closes chunks by size only, so that the same messages
    give the same file byte for byte. Use as a context manager or call :meth:`close`.
    Not thread-safe: call it from one thread.
    """

    def __init__(
        self,
        path: str | Path,
        *,
        compression: str = "zstd",
        flush_period_s: float | None = 1.0,
        split_size_bytes: int | None = None,
        split_duration_s: float | None = None,
        overwrite: bool = False,
        chunk_size: int = 1024 * 1024,
    ) -> None:
        if compression not in COMPRESSIONS:
            raise ValueError(f"compression {compression!r} unknown; use one of {sorted(COMPRESSIONS)}")
        if flush_period_s is not None and flush_period_s <= 0:
            raise ValueError(f"flush_period_s must be > 0 s, got {flush_period_s}")
        self.path = Path(path)
        self._compression = COMPRESSIONS[compression]
        self._flush_period = flush_period_s
        self._split_size = split_size_bytes
        self._split_ns = None if split_duration_s is None else round(split_duration_s * 1e9)
        self._chunk_size = chunk_size
        self._topics: dict[str, TopicRecord] = {}
        self._lanes: dict[str, _Lane] = {}
        self._records: list[FileRecord] = []
        self._last_flush = time.monotonic()
        self._closed = False
        self.files: list[Path] = []
        self.message_count = 0
        created = not self.path.exists()
        try:
            self._prepare_folder(overwrite)
            self._part = self._open_part()
        except OSError:  # e.g. a full disk: leave nothing behind that would block the next try
            if created:
                with contextlib.suppress(OSError):
                    self.path.rmdir()
            raise

    def _prepare_folder(self, overwrite: bool) -> None:
        check_output(self.path, overwrite)
        if self.path.is_dir() and overwrite:
            for p in self.path.iterdir():
                if p.is_dir():  # the tables of an analysis (check_output let nothing else by)
                    shutil.rmtree(p)
                else:
                    p.unlink()
        self.path.mkdir(parents=True, exist_ok=True)

    def _open_part(self) -> _McapPart:
        path = self.path / f"{self.path.name}_{len(self.files)}.mcap"
        stream = open(path, "wb")  # noqa: SIM115 - closed in _close_part
        self.files.append(path)
        try:
            writer = McapWriter(stream, chunk_size=self._chunk_size, compression=self._compression)
            writer.start(profile="ros2", library=LIBRARY)
            stream.flush()
        except OSError:  # e.g. a full disk: no half-started file is left behind
            with contextlib.suppress(OSError, ValueError):
                stream.raw.close()
            self.files.pop()
            path.unlink(missing_ok=True)
            raise
        part = _McapPart(path, stream, writer, record=FileRecord(path.name), good_offset=stream.tell())
        writer.on_chunk = partial(self._chunk_written, part)
        for lane in self._lanes.values():
            lane.channel_id = 0  # registered again in the new file, on its first message there
        self._records.append(part.record)
        return part

    def _close_part(self) -> None:
        self._part.writer.finish()
        self._part.stream.close()
        self._part.good_messages = self._part.record.message_count

    # -- writing --------------------------------------------------------------------------------

    def add_topic(
        self, topic: str, type_name: str, offered_qos: list[dict[str, Any]] | None = None
    ) -> TopicRecord:
        """Declare ``topic`` (done implicitly on its first message) with its offered QoS profiles."""
        if topic in self._topics:
            existing = self._topics[topic]
            if existing.type_name != type_name:
                raise ValueError(f"topic {topic} already carries {existing.type_name}, not {type_name}")
            return existing
        schema_text(type_name)  # fails early, with the search path, if the definition is missing
        record = TopicRecord(topic, type_name, offered_qos or qos_profile(), type_description_hash(type_name))
        self._topics[topic] = record
        self._lanes[topic] = _Lane(record, type_name, 0, 0, Padder(type_name))
        return record

    def write(self, topic: str, msg: Any, log_time_ns: int) -> None:
        """Serialise the rclpy message ``msg`` (exact CDR size) and write it at ``log_time_ns``."""
        self.write_many(((log_time_ns, topic, type_name_of(msg), serialize(msg), True),))

    def write_serialized(self, topic: str, type_name: str, data: bytes, log_time_ns: int,
                         padded: bool = False) -> None:
        """Write a CDR-serialised message of ``type_name`` (``pkg/msg/Type``), its padding bytes zeroed
        (:func:`~gait_biofeedback.wire.padding.zero_padding`; ``padded``: the caller's bytes come from
        :func:`~gait_biofeedback.wire.cdr.serialize`, zeroed already): :meth:`write_many` of one."""
        self.write_many(((log_time_ns, topic, type_name, data, padded),))

    def write_many(self, messages: Iterable[Message]) -> None:
        """Write ``messages`` (:data:`Message`: log time ns, topic, type name, CDR bytes, padding
        zeroed already) in their order, each as :meth:`write_serialized` says; the publish time is the
        log time. Per message: its topic's lane looked up, its padding checked, its record's fields; the
        records go into the file in runs (:meth:`McapWriter.add_messages`), the file's count and time
        range brought up to date once a run. A message that cannot be written (its topic carries
        another type) raises, those before it written."""
        if self._closed:
            raise ValueError(f"bag {self.path} is closed; open a new BagWriter to write more")
        lanes, splitting = self._lanes, self._split_size is not None or self._split_ns is not None
        pending: list[tuple[int, int, int, int, bytes]] = []  # records for the open file, in order
        add = pending.append
        try:
            for log_ns, topic, type_name, data, padded in messages:
                lane = lanes.get(topic)
                if lane is None or lane.type_name != type_name:
                    lane = self._lane(topic, type_name)
                log_ns = int(log_ns)
                if splitting or not lane.channel_id or len(pending) >= _RUN:
                    self._put(pending)  # what came before goes into the file first (and memory is bounded)
                    if splitting:
                        self._split_if_due(log_ns)
                    if not lane.channel_id:
                        lane.channel_id = self._register(self._part, lane.record)
                sequence = lane.sequence + 1
                add((log_ns, lane.channel_id, log_ns, sequence & 0xFFFFFFFF,
                     data if padded else lane.pad(data)))
                lane.sequence = sequence
        finally:
            self._put(pending)
        self.maybe_flush()

    def _put(self, pending: list[tuple[int, int, int, int, bytes]]) -> None:
        """The ``pending`` records into the open file (handed over once: the list is emptied), counted
        in its record and the bag's count."""
        if not pending:
            return
        records = pending.copy()
        pending.clear()
        record = self._part.record
        start, end = min(records)[0], max(records)[0]
        if record.message_count == 0 or start < record.start_time:
            record.start_time = start
        if end > record.end_time:
            record.end_time = end
        record.message_count += len(records)
        self.message_count += len(records)
        self._part.writer.add_messages(records)

    def _lane(self, topic: str, type_name: str) -> _Lane:
        """The lane of ``topic`` (declared now if new); ValueError if it carries another type."""
        lane = self._lanes.get(topic)
        if lane is not None:
            raise ValueError(f"topic {topic} carries {lane.type_name}; cannot write {type_name} to it")
        self.add_topic(topic, type_name)
        return self._lanes[topic]

    def _chunk_written(self, part: _McapPart) -> None:
        """A chunk of ``part`` closed: hand it to the OS, so that after a write error the file is cut
        back to here, not to the last flush."""
        part.stream.flush()
        part.good_offset = part.stream.tell()
        part.good_messages, part.good_end_ns = part.writer.written

    def _register(self, part: _McapPart, record: TopicRecord) -> int:
        schema_id = part.schema_ids.get(record.type_name)
        if schema_id is None:
            data = schema_text(record.type_name).encode("utf-8")
            schema_id = part.writer.register_schema(record.type_name, "ros2msg", data)
            part.schema_ids[record.type_name] = schema_id
        metadata = {"offered_qos_profiles": qos_to_text(record.offered_qos)}
        if record.type_hash:
            metadata["topic_type_hash"] = record.type_hash
        return part.writer.register_channel(record.name, "cdr", schema_id, metadata)

    def _split_if_due(self, log_time_ns: int) -> None:
        """Open the next file if the open one is full (size or duration)."""
        record = self._part.record
        if record.message_count == 0:
            return
        too_big = self._split_size is not None and self._part.size_estimate() >= self._split_size
        too_long = self._split_ns is not None and log_time_ns - record.start_time >= self._split_ns
        if too_big or too_long:
            self._close_part()
            self._part = self._open_part()
            self._write_metadata()

    def flush(self) -> None:
        """Write the open chunk to the file now and flush the file to the OS."""
        if self._closed:
            return
        self._part.writer.flush()  # a chunk written is marked good by _chunk_written
        self._last_flush = time.monotonic()

    def maybe_flush(self) -> None:
        """:meth:`flush` if ``flush_period_s`` seconds have passed since the last flush."""
        if self._flush_period is not None and time.monotonic() - self._last_flush >= self._flush_period:
            self.flush()

    @property
    def good_end_ns(self) -> int:
        """Log time of the newest message known to be in a complete chunk on disk (0: none yet)."""
        return self._part.good_end_ns

    @property
    def good_message_count(self) -> int:
        """Messages known to be in complete chunks on disk (every closed split file, and the open
        one up to its last complete chunk): what is left after :meth:`abandon`."""
        return self.message_count - self._part.record.message_count + self._part.good_messages

    def abandon(self) -> None:
        """After a write error: cut the open file back to its last complete chunk and close it
        without a summary (readers recover it; ``repair`` completes it once there is space). Nothing
        buffered is written any more. metadata.yaml is left to ``repair``. Idempotent."""
        if self._closed:
            return
        self._closed = True
        stream = self._part.stream
        with contextlib.suppress(OSError, ValueError):
            os.ftruncate(stream.fileno(), self._part.good_offset)
        with contextlib.suppress(OSError, ValueError):
            stream.raw.close()  # the buffered bytes can no longer reach any file
        with contextlib.suppress(OSError, ValueError):
            stream.close()

    def _write_metadata(self) -> None:
        for lane in self._lanes.values():
            lane.record.message_count = lane.sequence
        write_metadata(self.path, bag_metadata(self._records, list(self._topics.values())))

    def close(self) -> None:
        """Finish the open file (summary and indexes) and write metadata.yaml. Idempotent. On a write
        error the file is abandoned (:meth:`abandon`) and the error raised."""
        if self._closed:
            return
        try:
            self._close_part()
        except OSError:
            self.abandon()
            raise
        self._closed = True
        self._write_metadata()

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
