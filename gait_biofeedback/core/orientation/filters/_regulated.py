"""Parameter handling shared by the gain-regulated complementary filters (Madgwick, Mahony)."""

from __future__ import annotations

from typing import Any

from gait_biofeedback.core.orientation.gain_regulation import GainRegulator


def regulator_from(params: dict[str, Any], prefix: str) -> GainRegulator:
    """Build the thesis-ch.-4 regulator from flat parameters ``<prefix>1..3``, ``s_acc1/2``, ``s_mag1/2``."""
    return GainRegulator(
        params["scheme"],
        gains=(params[f"{prefix}1"], params[f"{prefix}2"], params[f"{prefix}3"]),
        acc_thresholds=(params["s_acc1"], params["s_acc2"]),
        mag_thresholds=(params["s_mag1"], params["s_mag2"]),
    )
