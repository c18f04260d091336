"""Parameter handling shared by the gain-regulated complementary filters (Madgwick, Mahony)."""

from __future__ import annotations

from typing import Any

from gait_biofeedback.core.orientation.gain_regulation import FuzzyGainRegulator, GainRegulator

FUZZY_DEVIATION = (0.02, 0.06, 0.02, 0.06, 0.1, 0.2, 0.1, 0.2)
"""Default VST3 input sets on a deviation Δ (fraction of the reference norm): L below 2-6 %, M around
6-10 %, H above 10-20 % (untuned starting point of ``tune``)."""


def regulator_from(params: dict[str, Any], prefix: str) -> GainRegulator | FuzzyGainRegulator:
    """Build the thesis-ch.-4 regulator from flat parameters ``<prefix>1..3``, ``s_acc1/2``, ``s_mag1/2``;
    ``scheme: fuzzy`` uses ``fuzzy_acc``, ``fuzzy_mag`` and ``fuzzy_<prefix>`` (8 numbers each)."""
    if params["scheme"] == "fuzzy":
        return FuzzyGainRegulator(params["fuzzy_acc"], params["fuzzy_mag"], params[f"fuzzy_{prefix}"])
    return GainRegulator(
        params["scheme"],
        gains=(params[f"{prefix}1"], params[f"{prefix}2"], params[f"{prefix}3"]),
        acc_thresholds=(params["s_acc1"], params["s_acc2"]),
        mag_thresholds=(params["s_mag1"], params["s_mag2"]),
    )
