"""Where the shipped configuration files are: ``config/`` of a source checkout, else the installed
``share/gait_biofeedback/config`` (setup.py installs them there)."""

from __future__ import annotations

import sys
from pathlib import Path

CHECKOUT_CONFIG = Path(__file__).resolve().parents[1] / "config"
INSTALLED_CONFIG = Path(sys.prefix) / "share" / "gait_biofeedback" / "config"


def config_path(name: str) -> Path:
    """``config/<name>`` of the checkout if it exists, else the installed copy (whose absence the
    caller reports)."""
    checkout = CHECKOUT_CONFIG / name
    if checkout.exists() or not (INSTALLED_CONFIG / name).exists():
        return checkout
    return INSTALLED_CONFIG / name
