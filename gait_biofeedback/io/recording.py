"""What an importer returns: one recording's IMU series, its source, its reference and warnings."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from gait_biofeedback.core.segments import ImuSeries


@dataclass
class Recording:
    """One imported recording.

    ``imu``: segment name -> samples in SI units. ``source``: what was read (importer kind and path).
    ``reference``: optional ground truth or vendor output, importer-specific (documented per importer),
    e.g. ``events``, ``opt_quat``, ``movement``, ``vendor_quat``. ``warnings``: things a user should know
    about the data (NaN samples kept, suspicious magnitudes), one sentence each; ``notes``: information
    that is no fault (a magnetometer left out), one sentence each.
    """

    imu: dict[str, ImuSeries]
    source: str
    reference: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def segments(self) -> list[str]:
        """Names of the segments with IMU data, in import order."""
        return list(self.imu)
