"""rosbag2 ``metadata.yaml`` (format version 9, as ``ros2 bag record -s mcap`` writes it on Jazzy).

The PyPI ``rosbags`` reader requires: version <= 9, storage_identifier, relative_file_paths (all
present), duration, starting_time, message_count and per topic name, type, serialization_format,
message_count; it matches each topic's offered_qos_profiles with the MCAP channel's, so both are
written from the same profile list.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from gait_biofeedback.core.safe_yaml import dump_yaml, load_yaml, load_yaml_file

METADATA_FILE = "metadata.yaml"
METADATA_VERSION = 9
ROS_DISTRO = "jazzy"
_INFINITE = {"sec": 9223372036, "nsec": 854775807}
MAX_METADATA_BYTES = 8 << 20
"""Largest metadata.yaml read (a bag of thousands of split files stays far below it)."""
MAX_METADATA_NODES = 200_000
MAX_QOS_BYTES = 64 << 10


def qos_profile(reliability: str = "reliable", durability: str = "volatile", depth: int = 100) -> list[dict]:
    """Offered QoS profile list in the rosbag2 v9 form (enum names, ``keep_last``)."""
    return [
        {
            "history": "keep_last",
            "depth": depth,
            "reliability": reliability,
            "durability": durability,
            "deadline": dict(_INFINITE),
            "lifespan": dict(_INFINITE),
            "liveliness": "automatic",
            "liveliness_lease_duration": dict(_INFINITE),
            "avoid_ros_namespace_conventions": False,
        }
    ]


def qos_to_text(profiles: list[dict]) -> str:
    """The string stored in an MCAP channel's ``offered_qos_profiles`` metadata."""
    return dump_yaml(profiles, sort_keys=False, default_flow_style=False).strip()


def qos_from_text(text: str) -> list[dict]:
    """Inverse of :func:`qos_to_text`; [] for empty or unparsable text."""
    try:
        loaded = load_yaml(text, max_bytes=MAX_QOS_BYTES) if text else []
    except yaml.YAMLError:
        return []
    return loaded if isinstance(loaded, list) else []


@dataclass
class TopicRecord:
    """One topic of a bag as metadata.yaml describes it."""

    name: str
    type_name: str
    offered_qos: list[dict] = field(default_factory=qos_profile)
    type_hash: str = ""
    message_count: int = 0


@dataclass
class FileRecord:
    """One storage file of a bag: name relative to the bag folder, log-time range, count."""

    path: str
    start_time: int = 0
    end_time: int = 0
    message_count: int = 0


def bag_metadata(files: list[FileRecord], topics: list[TopicRecord]) -> dict[str, Any]:
    """The metadata.yaml document for ``files`` and ``topics``."""
    counted = [f for f in files if f.message_count]
    start = min((f.start_time for f in counted), default=0)
    end = max((f.end_time for f in counted), default=0)
    return {
        "rosbag2_bagfile_information": {
            "version": METADATA_VERSION,
            "storage_identifier": "mcap",
            "duration": {"nanoseconds": end - start},
            "starting_time": {"nanoseconds_since_epoch": start},
            "message_count": sum(f.message_count for f in files),
            "topics_with_message_count": [
                {
                    "topic_metadata": {
                        "name": t.name,
                        "type": t.type_name,
                        "serialization_format": "cdr",
                        "offered_qos_profiles": t.offered_qos,
                        "type_description_hash": t.type_hash,
                    },
                    "message_count": t.message_count,
                }
                for t in topics
            ],
            "compression_format": "",
            "compression_mode": "",
            "relative_file_paths": [f.path for f in files],
            "files": [
                {
                    "path": f.path,
                    "starting_time": {"nanoseconds_since_epoch": f.start_time},
                    "duration": {"nanoseconds": f.end_time - f.start_time},
                    "message_count": f.message_count,
                }
                for f in files
            ],
            "custom_data": {},
            "ros_distro": ROS_DISTRO,
        }
    }


def write_metadata(bag_dir: Path, document: dict[str, Any]) -> Path:
    """Write ``metadata.yaml`` atomically (temp file + rename) and return its path."""
    path = Path(bag_dir) / METADATA_FILE
    tmp = path.with_name(f".{METADATA_FILE}.tmp")
    try:
        tmp.write_text(dump_yaml(document, sort_keys=False, default_flow_style=False), encoding="utf-8")
    except OSError:
        tmp.unlink(missing_ok=True)
        raise
    os.replace(tmp, path)
    return path


def read_metadata(bag_dir: Path) -> dict[str, Any] | None:
    """The ``rosbag2_bagfile_information`` mapping of ``bag_dir``, or None if absent or unreadable."""
    path = Path(bag_dir) / METADATA_FILE
    try:
        document = load_yaml_file(path, max_bytes=MAX_METADATA_BYTES, max_nodes=MAX_METADATA_NODES)
        info = document["rosbag2_bagfile_information"]
    except (OSError, yaml.YAMLError, TypeError, KeyError):
        return None
    return info if isinstance(info, dict) else None
