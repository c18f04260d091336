"""ROS 2 message types by name: ros2msg schema text, type hash and the rclpy message class.

The schema text follows the MCAP ``ros2`` profile (as rosbag2 writes it): the type's own .msg
text, then for every type it depends on (depth first, each once) a line of 80 ``=``, a line
``MSG: pkg/Type`` and that type's .msg text. The .msg files are found under ``share/<pkg>/msg`` of
the prefixes in ``AMENT_PREFIX_PATH`` (default: this interpreter's prefix, where the PyPI ROS
wheels and our interface package install them).
"""

from __future__ import annotations

import importlib
import json
import os
import re
import sys
from functools import cache
from pathlib import Path

from gait_biofeedback.wire.padding import type_name_of  # noqa: F401 - re-exported: io's users import it here

SEPARATOR = "=" * 80
PRIMITIVE_TYPES = frozenset(
    {
        "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16",
        "int32", "uint32", "int64", "uint64", "string", "wstring",
    }
)  # fmt: skip
BUILT_IN_DEFINITIONS: dict[tuple[str, str], str] = {
    ("tf2_msgs", "TFMessage"): "geometry_msgs/TransformStamped[] transforms\n",
}
"""Definitions of standard types the PyPI ROS wheels do not ship, used when no .msg file is found: the
body's ``/tf`` (:mod:`gait_biofeedback.wire.tf`; ROS 2 Jazzy geometry2, tf2_msgs/msg/TFMessage.msg)."""
_FIELD_TYPE = re.compile(r"^\s*([A-Za-z][\w/]*)")
_CONSTANT = re.compile(r"\s*\w+\s*=")


def split_type_name(type_name: str) -> tuple[str, str]:
    """``"sensor_msgs/msg/Imu"`` or ``"sensor_msgs/Imu"`` -> ``("sensor_msgs", "Imu")``."""
    parts = type_name.split("/")
    if len(parts) == 3 and parts[1] == "msg":
        return parts[0], parts[2]
    if len(parts) == 2:
        return parts[0], parts[1]
    raise ValueError(f"{type_name!r} is not a ROS 2 message type name (expected 'pkg/msg/Type')")


@cache
def message_class(type_name: str) -> type:
    """The rclpy message class of ``type_name``, imported from its Python package."""
    package, name = split_type_name(type_name)
    try:
        return getattr(importlib.import_module(f"{package}.msg"), name)
    except (ImportError, AttributeError) as err:
        raise ValueError(
            f"message type {type_name!r} is not installed in this Python environment ({err}); "
            "install its interface package to deserialise it, or read raw bytes instead"
        ) from err


def share_dirs() -> list[Path]:
    """``share`` directories to search for interface definitions, in priority order."""
    prefixes = os.environ.get("AMENT_PREFIX_PATH") or sys.prefix
    dirs = [Path(p) / "share" for p in prefixes.split(os.pathsep) if p]
    fallback = Path(sys.prefix) / "share"
    if fallback not in dirs:
        dirs.append(fallback)
    return dirs


def _interface_file(package: str, name: str, suffix: str) -> Path | None:
    for share in share_dirs():
        path = share / package / "msg" / f"{name}{suffix}"
        if path.is_file():
            return path
    return None


@cache
def msg_text(package: str, name: str) -> str:
    """Text of ``share/<package>/msg/<name>.msg``."""
    path = _interface_file(package, name, ".msg")
    if path is None and (package, name) in BUILT_IN_DEFINITIONS:
        return BUILT_IN_DEFINITIONS[package, name]
    if path is None:
        searched = ", ".join(str(d) for d in share_dirs())
        raise ValueError(
            f"no definition {package}/msg/{name}.msg under {searched}; set AMENT_PREFIX_PATH to the "
            "prefix where the interface package is installed"
        )
    return path.read_text(encoding="utf-8")


def _dependencies(package: str, text: str) -> list[tuple[str, str]]:
    """Complex field types of one .msg text, in field order (constants and primitives skipped)."""
    deps: list[tuple[str, str]] = []
    for raw_line in text.splitlines():
        line = raw_line.split("#", 1)[0].strip()
        if not line:
            continue
        match = _FIELD_TYPE.match(line)
        if match is None:
            continue
        field_type = match.group(1)
        if _CONSTANT.match(line[line.find(" ") :]):
            continue  # constant: TYPE NAME=value
        if field_type in PRIMITIVE_TYPES:
            continue
        if field_type == "Header":
            deps.append(("std_msgs", "Header"))
        elif "/" in field_type:
            dep_package, dep_name = split_type_name(field_type)
            deps.append((dep_package, dep_name))
        else:
            deps.append((package, field_type))
    return deps


@cache
def schema_text(type_name: str) -> str:
    """Full ros2msg schema text of ``type_name`` with all its dependencies."""
    package, name = split_type_name(type_name)
    parts = [msg_text(package, name).rstrip("\n")]
    seen = {(package, name)}

    def visit(pkg: str, text: str) -> None:
        for dep in _dependencies(pkg, text):
            if dep in seen:
                continue
            seen.add(dep)
            dep_text = msg_text(*dep)
            parts.append(f"{SEPARATOR}\nMSG: {dep[0]}/{dep[1]}\n{dep_text.rstrip(chr(10))}")
            visit(dep[0], dep_text)

    visit(package, parts[0])
    return "\n".join(parts) + "\n"


@cache
def type_description_hash(type_name: str) -> str:
    """RIHS01 type hash from ``share/<pkg>/msg/<Type>.json``, or "" when that file is absent."""
    package, name = split_type_name(type_name)
    path = _interface_file(package, name, ".json")
    if path is None:
        return ""
    try:
        hashes = json.loads(path.read_text(encoding="utf-8")).get("type_hashes", [])
    except (OSError, ValueError):
        return ""
    full_name = f"{package}/msg/{name}"
    return next((h["hash_string"] for h in hashes if h.get("type_name") == full_name), "")
