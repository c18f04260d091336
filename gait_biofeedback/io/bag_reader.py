"""Read a rosbag2 bag folder (MCAP storage) or a bare .mcap file, damaged ones included."""

from __future__ import annotations

import heapq
import itertools
import re
import warnings
from collections.abc import Iterable, Iterator
from operator import itemgetter
from pathlib import Path
from types import TracebackType
from typing import Any

from rclpy.serialization import deserialize_message

from gait_biofeedback.io.mcap_file import BadChunk, McapFile
from gait_biofeedback.io.schemas import message_class


class BagRecoveryWarning(UserWarning):
    """A file of the bag is damaged; only its readable chunks are read."""


def bag_files(path: Path) -> list[Path]:
    """The .mcap files of a bag folder, by split index (``<name>_<i>.mcap``); metadata.yaml is not
    consulted, so a stale or missing one does not hide files."""
    return sorted(path.glob("*.mcap"), key=_split_index)


def _split_index(path: Path) -> tuple[int, str]:
    match = re.search(r"_(\d+)\.mcap$", path.name)
    return (int(match.group(1)) if match else -1, path.name)


class BagReader:
    """Messages of a bag folder or .mcap file, in log-time order across its split files.

    A file without a valid summary (recording cut off) is read up to its last complete chunk; a
    :class:`BagRecoveryWarning` names the file and the number of messages recovered. A chunk that
    fails its CRC is skipped with a :class:`BagRecoveryWarning` naming the time range lost, when it
    is met while reading or by :meth:`verify`; every warning is also kept in :attr:`warnings`.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if not self.path.exists():
            raise FileNotFoundError(f"no bag at {self.path}: expected a rosbag2 folder or an .mcap file")
        if self.path.is_dir():
            paths = bag_files(self.path)
            if not paths:
                raise ValueError(f"{self.path} is a folder without .mcap files, so it is not an MCAP bag")
        else:
            paths = [self.path]
        self.files: list[McapFile] = []
        self.warnings: list[str] = []
        self._classes: dict[str, type] = {}  # type name → rclpy message class
        try:
            for p in paths:
                self.files.append(McapFile.open(p))
        except BaseException:
            self.close()
            raise
        for f in self.files:
            if not f.complete:
                text = (
                    f"{f.path}: damaged or unfinished MCAP file ({f.damage}); recovered "
                    f"{f.message_count} messages from {len(f.chunks)} complete chunks"
                )
                self.warnings.append(text)
                warnings.warn(text, BagRecoveryWarning, stacklevel=2)
            for bad in f.bad_chunks:
                self._bad_chunk(f, bad, warn=False)
            f.on_bad_chunk = self._bad_chunk

    def _bad_chunk(self, f: McapFile, bad: BadChunk, warn: bool = True) -> None:
        text = f"{f.path}: {self.describe(bad)}"
        self.warnings.append(text)
        if warn:
            warnings.warn(text, BagRecoveryWarning, stacklevel=3)

    def describe(self, bad: BadChunk) -> str:
        """A bad chunk in words: where, why, which time range of the recording it took away."""
        starts = [self.start_time_ns] if self.message_count else []
        starts += [b.start_ns for f in self.files for b in f.bad_chunks if b.start_ns > 0]
        t0 = min(starts, default=0)
        lost = "" if bad.messages is None else f", {bad.messages} messages"
        return (f"chunk at byte {bad.offset} unreadable ({bad.reason}): data from "
                f"{(bad.start_ns - t0) / 1e9:.2f} s to {(bad.end_ns - t0) / 1e9:.2f} s into the recording "
                f"skipped{lost}")

    def verify(self) -> list[str]:
        """Check every chunk of every file (a full read); the bad ones in words (see :meth:`describe`)."""
        out = []
        for f in self.files:
            known = len(f.bad_chunks)
            f.on_bad_chunk = None
            try:
                f.verify()
            finally:
                f.on_bad_chunk = self._bad_chunk
            for bad in f.bad_chunks[known:]:
                self._bad_chunk(f, bad, warn=False)
            out += [f"{f.path}: {self.describe(b)}" for b in f.bad_chunks]
        return out

    def topics(self) -> dict[str, str]:
        """``{topic: type name}``, e.g. ``{"/left_foot/imu/data_raw": "sensor_msgs/msg/Imu"}``."""
        out: dict[str, str] = {}
        for f in self.files:
            out.update(f.topic_types())
        return out

    @property
    def message_count(self) -> int:
        """Messages in the bag (for damaged files: the recoverable ones)."""
        return sum(f.message_count for f in self.files)

    def message_counts(self) -> dict[str, int]:
        """``{topic: number of messages}``."""
        counts: dict[str, int] = {}
        for f in self.files:
            for channel_id, n in f.channel_counts.items():
                channel = f.channels.get(channel_id)
                if channel is not None:
                    counts[channel.topic] = counts.get(channel.topic, 0) + n
        return counts

    @property
    def start_time_ns(self) -> int:
        """Log time of the first message (0 for an empty bag)."""
        return min((f.start_time for f in self.files if f.start_time is not None), default=0)

    @property
    def end_time_ns(self) -> int:
        """Log time of the last message (0 for an empty bag)."""
        return max((f.end_time for f in self.files if f.end_time is not None), default=0)

    @property
    def duration_ns(self) -> int:
        """Last minus first log time."""
        return self.end_time_ns - self.start_time_ns

    def raw_messages(
        self, topics: Iterable[str] | None = None, start_ns: int | None = None, stop_ns: int | None = None
    ) -> Iterator[tuple[str, str, bytes, int]]:
        """``(topic, type name, CDR bytes, log_time_ns)`` with ``start_ns <= log_time < stop_ns``."""
        wanted = None if topics is None else set(topics)
        types = self.topics()
        batches = [self._file_batches(f, types, wanted, start_ns, stop_ns) for f in self.files]
        if len(batches) == 1:  # most bags are one file: no merge (its key calls were a 6th of reading's time)
            for batch in batches[0]:
                yield from batch
            return
        yield from heapq.merge(*(itertools.chain.from_iterable(b) for b in batches), key=itemgetter(3))

    def _file_batches(
        self, f: McapFile, types: dict[str, str], wanted: set[str] | None, start_ns: int | None,
        stop_ns: int | None,
    ) -> Iterator[list[tuple[str, str, bytes, int]]]:
        """:meth:`raw_messages` of one file (``types``: the bag's), a list per batch of
        :meth:`McapFile.message_batches`."""
        name_of = {c.id: (c.topic, types[c.topic]) for c in f.channels.values()
                   if wanted is None or c.topic in wanted}
        ids = frozenset(name_of) if wanted is not None else None
        for batch in f.message_batches(ids, start_ns, stop_ns):
            yield [(*name_of[m[1]], m[4], m[0]) for m in batch if m[1] in name_of]

    def messages(
        self, topics: Iterable[str] | None = None, start_ns: int | None = None, stop_ns: int | None = None
    ) -> Iterator[tuple[str, Any, int]]:
        """``(topic, rclpy message, log_time_ns)``; the message class is imported from the type name."""
        for topic, type_name, data, log_time in self.raw_messages(topics, start_ns, stop_ns):
            yield topic, self.decode(topic, type_name, data), log_time

    def decode(self, topic: str, type_name: str, data: bytes) -> Any:
        """One message of :meth:`raw_messages` as an rclpy message; ValueError saying what to do when it
        does not decode with this version's definition of its type."""
        cls = self._classes.get(type_name)
        if cls is None:
            cls = self._classes[type_name] = message_class(type_name)
        try:
            return deserialize_message(data, cls)
        except Exception as exc:  # rclpy raises RMWError (not exported) for bytes of another definition
            raise ValueError(
                f"{self.path}: a {type_name} message on {topic} does not decode with this version's "
                f"definition ({exc}); a recording made by an older version? Its raw sensor topics "
                "still are: run `gait-biofeedback analyze` on it again") from None

    def close(self) -> None:
        """Release the files."""
        for f in self.files:
            f.close()

    def __enter__(self) -> BagReader:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
