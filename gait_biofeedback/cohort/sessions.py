"""The recordings of a batch: what ``GLOB_OR_DIR`` names, each with a session name unique in the batch
(its path below the common folder, ``/`` → ``__``), and the fingerprint that says whether a session
already analysed is still the same recording."""

from __future__ import annotations

import glob
import os
import re
from dataclasses import dataclass
from pathlib import Path

BAG_METADATA = "metadata.yaml"


@dataclass(frozen=True)
class Recording:
    name: str
    path: Path


def is_recording(path: Path) -> bool:
    """An ``.mcap`` file, or a rosbag2 folder: its metadata file, or (cut off before it was written)
    parts named as rosbag2 names them, ``<folder>_<k>.mcap``; a folder of other .mcap files is a
    folder of recordings."""
    if path.is_file():
        return path.suffix == ".mcap"
    if not path.is_dir():
        return False
    parts = list(path.glob("*.mcap"))
    own = re.compile(re.escape(path.name) + r"_\d+\.mcap")
    return (path / BAG_METADATA).is_file() or (bool(parts) and all(own.fullmatch(p.name) for p in parts))


def _below(folder: Path, exclude: Path | None) -> list[Path]:
    """Recordings under ``folder``; a bag folder is one recording (its .mcap parts are not others)."""
    found: list[Path] = []
    for here, dirs, files in os.walk(folder):
        place = Path(here)
        if exclude is not None and place.resolve() == exclude:
            dirs.clear()
            continue
        if place != folder and is_recording(place):
            found.append(place)
            dirs.clear()
            continue
        found += [place / f for f in files if f.endswith(".mcap")]
        dirs.sort()
    return found


def find_recordings(spec: str, exclude: str | Path | None = None) -> list[Recording]:
    """Recordings named by ``spec``: a bag folder or .mcap file, a folder searched recursively, or a
    glob pattern (``**`` recursive). ``exclude``: a folder left out (the batch's own output). Raises
    FileNotFoundError, naming ``spec``, when nothing is found."""
    out_dir = Path(exclude).resolve() if exclude is not None else None
    root = Path(spec)
    if root.exists():
        paths = [root] if is_recording(root) else _below(root, out_dir) if root.is_dir() else []
    else:
        paths = [Path(p) for p in sorted(glob.glob(spec, recursive=True)) if is_recording(Path(p))]
        paths = [p for p in paths if out_dir is None or out_dir not in p.resolve().parents]
    if not paths:
        raise FileNotFoundError(f"batch: no recording (a rosbag2 folder or .mcap file) in {spec!r}; give a "
                                "folder of recordings, one recording, or a glob such as 'sessions/*/raw'")
    paths = sorted({p.resolve() for p in paths})
    common = Path(os.path.commonpath([p.parent for p in paths]))
    recordings = [Recording(_name(p, common), p) for p in paths]
    names = [r.name for r in recordings]
    if clash := sorted({n for n in names if names.count(n) > 1}):
        same = [str(r.path) for r in recordings if r.name in clash]
        raise ValueError(f"batch: {', '.join(same)} would share the session name(s) {clash}; rename one")
    return recordings


def _name(path: Path, common: Path) -> str:
    relative = path.relative_to(common)
    if path.suffix == ".mcap":
        relative = relative.with_suffix("")
    return "__".join(relative.parts) or path.stem


def fingerprint(path: Path) -> dict[str, int]:
    """Total size and newest modification time of the recording's files: a changed recording is
    analysed again."""
    files = [path] if path.is_file() else [p for p in path.rglob("*") if p.is_file()]
    stats = [p.stat() for p in files]
    newest = max((s.st_mtime_ns for s in stats), default=0)
    return {"bytes": sum(s.st_size for s in stats), "mtime_ns": newest}
