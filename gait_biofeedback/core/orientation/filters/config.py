"""Tuned default parameters shipped in ``config/orientation_filters.yaml``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from gait_biofeedback.resources import config_path

TUNED_PATH = config_path("orientation_filters.yaml")


def load_tuned(path: Path | str | None = None) -> dict[str, dict[str, Any]]:
    """Per-algorithm parameter dicts from the YAML (``{algorithm: {param: value}}``); {} if absent."""
    p = Path(path) if path is not None else TUNED_PATH
    if not p.is_file():
        return {}
    data = yaml.safe_load(p.read_text()) or {}
    return {name: dict(entry.get("params", {})) for name, entry in data.get("algorithms", {}).items()}
