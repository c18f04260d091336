"""Normative bands of the spatiotemporal parameters and the minimal clinically important differences.

Every band names its source. Where a source gives a mean and no range, the band is that mean ± a
margin this project chose (said in ``note``); a clinic replaces any band with its own data in a
YAML file (``gait-biofeedback report --norms FILE``, :func:`load_norms`). The joint-angle curves'
reference is :mod:`gait_biofeedback.core.biofeedback.normative` (coarse: textbook key values every 5 %,
a band of ± tolerance, not a published SD), and the report repeats that warning.

MCIDs (:data:`MCID`): gait speed 0.16 m/s (Tilson et al. 2010, first 60 days after stroke) and the
Gait Profile Score 1.6° (Baker et al. 2012). No MCID for stroke is used here for the other
parameters; the progress page marks their changes only as *detectable* (beyond the stride-to-stride
noise of the two sessions, :func:`gait_biofeedback.report.progress.detectable`), never as important.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import yaml

from gait_biofeedback.core.safe_yaml import describe, load_yaml_file, shown

PERRY = (
    "Perry J, Burnfield JM. Gait Analysis: Normal and Pathological Function. 2nd ed. SLACK; 2010 "
    "(adult free walking: 82 m/min, stride 1.41 m, 113 steps/min, stance 60 %, swing 40 %, "
    "double support 2 x 10 %)."
)
BOHANNON = (
    "Bohannon RW, Andrews AW. Normal walking speed: a descriptive meta-analysis. Physiotherapy. "
    "2011;97(3):182-189 (comfortable speed, group means 0.94-1.43 m/s from 20 to 99 years)."
)
ROBINSON = (
    "Robinson RO, Herzog W, Nigg BM. Use of force platform variables to quantify the effects of "
    "chiropractic manipulation on gait symmetry. J Manipulative Physiol Ther. 1987;10(4):172-176 "
    "(the symmetry index)."
)
TILSON = (
    "Tilson JK, Sullivan KJ, Cen SY, et al. Meaningful gait speed improvement during the first 60 days "
    "poststroke: minimal clinically important difference. Phys Ther. 2010;90(2):196-208."
)
BAKER_2009 = (
    "Baker R, McGinley JL, Schwartz MH, et al. The Gait Profile Score and Movement Analysis "
    "Profile. Gait Posture. 2009;30(3):265-269."
)
BAKER_2012 = (
    "Baker R, McGinley JL, Schwartz M, et al. The minimal clinically important difference for the "
    "Gait Profile Score. Gait Posture. 2012;35(4):612-615."
)


@dataclass(frozen=True)
class NormBand:
    """Healthy adults' band of one parameter, in SI units (``unit``)."""

    low: float
    high: float
    unit: str
    source: str
    note: str = ""

    def status(self, value: float) -> str:
        """ "in", "low", "high", or "unknown" (NaN)."""
        if value != value:
            return "unknown"
        return "low" if value < self.low else "high" if value > self.high else "in"


_MARGIN = "the source's mean ± 10 % (it gives no range)"
NORMS: dict[str, NormBand] = {
    "gait_speed": NormBand(0.94, 1.43, "m/s", BOHANNON),
    "stride_length": NormBand(1.27, 1.55, "m", PERRY, _MARGIN),
    "step_length": NormBand(0.63, 0.78, "m", PERRY, "half the stride, ± 10 %"),
    "cadence": NormBand(1.70, 2.07, "Hz", PERRY, _MARGIN + " (113 steps/min)"),
    "stride_time": NormBand(0.96, 1.17, "s", PERRY, "2 / cadence, ± 10 %"),
    "step_time": NormBand(0.48, 0.59, "s", PERRY, "1 / cadence, ± 10 %"),
    "stance_fraction": NormBand(0.57, 0.63, "1", PERRY, "60 % ± 3 points"),
    "swing_fraction": NormBand(0.37, 0.43, "1", PERRY, "40 % ± 3 points"),
    "double_support_fraction": NormBand(0.16, 0.24, "1", PERRY, "20 % ± 4 points"),
    "symmetry": NormBand(
        -0.10,
        0.10,
        "1",
        ROBINSON,
        "|SI| ≤ 10 % taken as symmetric (the definition's source gives no threshold)",
    ),
}
"""Parameter → band; ``symmetry`` applies to every symmetry index."""


@dataclass(frozen=True)
class Mcid:
    """Minimal clinically important difference of one parameter (SI units)."""

    value: float
    unit: str
    source: str


MCID: dict[str, Mcid] = {
    "gait_speed": Mcid(0.16, "m/s", TILSON),
    "gait_profile_score": Mcid(1.6 * 3.141592653589793 / 180.0, "rad", BAKER_2012),
}


def load_norms(path: str | Path) -> dict[str, NormBand]:
    """:data:`NORMS` with the bands of a YAML file replaced: ``<parameter>: {low, high, source}`` in the
    band's SI unit (m/s, m, Hz, s, fractions). An unknown parameter or a band without a source is refused."""
    path = Path(path)
    try:
        document = load_yaml_file(path) or {}
    except OSError as exc:
        raise ValueError(f"{path}: cannot read the normative bands: {exc}") from None
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: cannot read the normative bands: {describe(exc)}") from None
    if not isinstance(document, dict):
        raise ValueError(f"{path}: expected '<parameter>: {{low, high, source}}' entries")
    out = dict(NORMS)
    for name, spec in document.items():
        if name not in NORMS:
            raise ValueError(f"{path}: unknown parameter {shown(name)}; known: {', '.join(NORMS)}")
        if not isinstance(spec, dict) or not {"low", "high", "source"} <= set(spec):
            raise ValueError(f"{path}: {name} needs low, high and source (in {NORMS[name].unit})")
        try:
            low, high = float(spec["low"]), float(spec["high"])
        except (TypeError, ValueError):
            raise ValueError(
                f"{path}: {name}: low and high must be numbers (in {NORMS[name].unit})"
            ) from None
        if not low <= high:
            raise ValueError(f"{path}: {name}: low {low} > high {high}")
        out[name] = replace(
            NORMS[name], low=low, high=high, source=str(spec["source"]), note=str(spec.get("note", ""))
        )
    return out
