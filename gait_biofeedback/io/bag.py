"""Recordings as rosbag2 bags with MCAP storage: write, read, repair; IMU series to and from bags.

A bag is a folder with ``metadata.yaml`` and ``<name>_0.mcap`` (``_1`` … when split), the layout
``ros2 bag record -s mcap`` writes. :func:`repair` turns what a crash leaves behind back into
such a bag.
"""

from __future__ import annotations

import contextlib
import os
import warnings
from pathlib import Path
from typing import Any

from mcap.writer import CompressionType, Writer

from gait_biofeedback.io.bag_metadata import (
    FileRecord,
    TopicRecord,
    bag_metadata,
    qos_from_text,
    read_metadata,
    write_metadata,
)
from gait_biofeedback.io.bag_reader import BagReader, BagRecoveryWarning, bag_files
from gait_biofeedback.io.bag_writer import BagWriter
from gait_biofeedback.io.imu_bag import read_imu_bag, write_imu_bag
from gait_biofeedback.io.mcap_file import McapFile
from gait_biofeedback.io.schemas import message_class, type_description_hash

__all__ = [
    "BagReader",
    "BagRecoveryWarning",
    "BagWriter",
    "message_class",
    "read_imu_bag",
    "repair",
    "write_imu_bag",
]


def repair(path: str | Path) -> dict[str, Any]:
    """Make a cut-off recording whole again; return a report of what was done.

    Every chunk of every .mcap file is checked (decompression, CRC). A file without a valid
    summary, or with a chunk that fails its check, is rewritten as a complete MCAP file (summary,
    chunk and message indexes) holding every message of its readable chunks; the original is kept
    as ``<file>.orig`` and ``damage`` names what was lost (bad chunks with their time range into the
    recording). For a bag folder, metadata.yaml is rebuilt from the files when it is missing or
    disagrees with them (the old one is kept as ``metadata.yaml.orig``).
    Report: ``{"path", "files": [{"file", "status": "ok"|"repaired", "messages", "damage",
    "original"}], "message_count", "metadata": "ok"|"created"|"rebuilt"|"not a folder"}``.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"nothing to repair at {path}: expected a rosbag2 folder or an .mcap file")
    files = bag_files(path) if path.is_dir() else [path]
    if not files:
        raise ValueError(f"{path} is a folder without .mcap files, so there is no recording to repair")
    report: dict[str, Any] = {"path": str(path), "files": [], "message_count": 0}
    file_records: list[FileRecord] = []
    topics: dict[str, TopicRecord] = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BagRecoveryWarning)  # what is wrong goes into the report
        with BagReader(path) as reader:
            reader.verify()
            lost = {str(f.path): [reader.describe(b) for b in f.bad_chunks] for f in reader.files}
    for file in files:
        entry = _repair_file(file, lost.get(str(file), []))
        report["files"].append(entry)
        mcap = McapFile.open(file)
        try:
            file_records.append(
                FileRecord(file.name, mcap.start_time or 0, mcap.end_time or 0, mcap.message_count)
            )
            _collect_topics(mcap, topics)
        finally:
            mcap.close()
        report["message_count"] += file_records[-1].message_count
    if path.is_dir():
        report["metadata"] = _refresh_metadata(path, file_records, list(topics.values()))
    else:
        report["metadata"] = "not a folder"
    return report


def _repair_file(file: Path, bad_chunks: list[str]) -> dict[str, Any]:
    mcap = McapFile.open(file)
    try:
        entry = {
            "file": str(file),
            "status": "ok",
            "messages": mcap.message_count,
            "damage": "",
            "original": None,
        }
        if mcap.complete and not bad_chunks:
            return entry
        tmp = file.with_name(f".{file.name}.repair")
        try:
            _rewrite(mcap, tmp)
        except OSError as exc:  # e.g. the disk is full: leave everything as it was
            with contextlib.suppress(OSError):
                tmp.unlink()
            raise OSError(f"cannot repair {file}: writing its repaired copy failed ({exc.strerror or exc}); "
                          f"it needs about {file.stat().st_size / 1e6:.1f} MB free on its disk. Nothing was "
                          "changed in it: free some space and repair again") from None
        damage = [mcap.damage] if mcap.damage else []
        entry.update(status="repaired", damage="; ".join([*damage, *bad_chunks]),
                     messages=mcap.message_count)
    finally:
        mcap.close()
    original = _free_name(file.with_name(file.name + ".orig"))
    os.replace(file, original)
    os.replace(tmp, file)
    entry["original"] = str(original)
    return entry


def _free_name(path: Path) -> Path:
    candidate, n = path, 1
    while candidate.exists():
        candidate, n = path.with_name(f"{path.name}.{n}"), n + 1
    return candidate


def _rewrite(mcap: McapFile, target: Path) -> None:
    """Write every recoverable record of ``mcap`` into a complete MCAP file at ``target``."""
    with open(target, "wb") as stream:
        writer = Writer(stream, compression=CompressionType.ZSTD)
        writer.start(profile=mcap.profile, library=mcap.library or "gait_biofeedback repair")
        schema_ids = {0: 0}
        for schema in mcap.schemas.values():
            schema_ids[schema.id] = writer.register_schema(schema.name, schema.encoding, schema.data)
        channel_ids = {}
        for channel in mcap.channels.values():
            channel_ids[channel.id] = writer.register_channel(
                channel.topic,
                channel.message_encoding,
                schema_ids.get(channel.schema_id, 0),
                channel.metadata,
            )
        for name, data in mcap.metadata:
            writer.add_metadata(name, data)
        for m in mcap.messages():
            if m.channel_id in channel_ids:
                writer.add_message(channel_ids[m.channel_id], m.log_time, m.data, m.publish_time, m.sequence)
        writer.finish()
        stream.flush()
        os.fsync(stream.fileno())


def _collect_topics(mcap: McapFile, topics: dict[str, TopicRecord]) -> None:
    for channel in mcap.channels.values():
        schema = mcap.schemas.get(channel.schema_id)
        type_name = schema.name if schema else ""
        record = topics.get(channel.topic)
        if record is None:
            record = topics[channel.topic] = TopicRecord(
                channel.topic,
                type_name,
                qos_from_text(channel.metadata.get("offered_qos_profiles", "")),
                channel.metadata.get("topic_type_hash", "") or _hash_or_empty(type_name),
            )
        record.message_count += mcap.channel_counts.get(channel.id, 0)


def _hash_or_empty(type_name: str) -> str:
    try:
        return type_description_hash(type_name)
    except ValueError:
        return ""


def _essentials(info: dict[str, Any]) -> tuple:
    """What a reader relies on in metadata.yaml: files, counts, time range, topics and types."""
    try:
        return (
            info["storage_identifier"],
            [Path(p).name for p in info["relative_file_paths"]],
            info["message_count"],
            info["starting_time"]["nanoseconds_since_epoch"],
            info["duration"]["nanoseconds"],
            sorted(
                (t["topic_metadata"]["name"], t["topic_metadata"]["type"], t["message_count"])
                for t in info["topics_with_message_count"]
            ),
        )
    except (KeyError, TypeError):
        return ()


def _refresh_metadata(bag_dir: Path, files: list[FileRecord], topics: list[TopicRecord]) -> str:
    document = bag_metadata(files, topics)
    existing = read_metadata(bag_dir)
    metadata_path = bag_dir / "metadata.yaml"
    if existing is not None and _essentials(existing) == _essentials(document["rosbag2_bagfile_information"]):
        return "ok"
    status = "created"
    if metadata_path.exists():
        os.replace(metadata_path, _free_name(metadata_path.with_name("metadata.yaml.orig")))
        status = "rebuilt"
    write_metadata(bag_dir, document)
    return status
