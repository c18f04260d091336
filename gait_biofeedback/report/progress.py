"""Progress over several sessions of one patient: each parameter per session and its change from the
first, flagged where it exceeds its minimal clinically important difference
(:data:`~gait_biofeedback.report.norms.MCID`: gait speed 0.16 m/s, Tilson et al. 2010; GPS 1.6°,
Baker et al. 2012). Parameters without a MCID are marked only "detectable" when the change exceeds
the 95 % limit of the difference of two stride means, ``1.96 sqrt(s1²/n1 + s2²/n2)`` (:func:`detectable`):
more than the strides' own variability explains, which says nothing of clinical importance."""

from __future__ import annotations

import math

from gait_biofeedback.report import figures
from gait_biofeedback.report.analysis import SessionAnalysis, mean_sd_n
from gait_biofeedback.report.content import DISPLAY, shown
from gait_biofeedback.report.document import Figure, Paragraph, Section, Table
from gait_biofeedback.report.norms import MCID

# (row label, display parameter, value source, side or None for both sides pooled)
ROWS: tuple[tuple[str, str, str, str | None], ...] = (
    ("gait speed", "gait_speed", "gait_speed", None),
    ("cadence", "cadence", "cadence", None),
    ("stride length", "stride_length", "stride_length", None),
    ("step length left", "step_length", "step_length", "left"),
    ("step length right", "step_length", "step_length", "right"),
    ("stance left", "stance_fraction", "stance_fraction", "left"),
    ("stance right", "stance_fraction", "stance_fraction", "right"),
    ("double support", "double_support_fraction", "double_support_fraction", None),
    ("step time symmetry", "symmetry", "symmetry:step_time", None),
    ("step length symmetry", "symmetry", "symmetry:step_length", None),
    ("Gait Profile Score", "gait_profile_score", "gps", None),
)


def detectable(mean1: float, sd1: float, n1: int, mean2: float, sd2: float, n2: int) -> bool:
    """True when ``|mean2 - mean1| > 1.96 sqrt(sd1²/n1 + sd2²/n2)`` (module docstring)."""
    if min(n1, n2) < 2 or not all(map(math.isfinite, (mean1, sd1, mean2, sd2))):
        return False
    return abs(mean2 - mean1) > 1.96 * math.sqrt(sd1**2 / n1 + sd2**2 / n2)


def _signed(name: str, change: float) -> str:
    """The change as shown with its sign; one that rounds to zero is shown as 0, unsigned."""
    text = shown(name, abs(change))
    if not text.strip("0."):
        return text
    return ("+" if change > 0 else "-") + text


def value_of(analysis: SessionAnalysis, source: str, side: str | None) -> tuple[float, float, int]:
    """(mean, SD, n) of one progress row in one session (SD NaN, n 0 for scores)."""
    if source == "gps":
        return analysis.gps["overall"], math.nan, 0
    if source.startswith("symmetry:"):
        return analysis.symmetry[source.split(":")[1]], math.nan, 0
    return mean_sd_n([r[source] for r in analysis.used if side is None or r["side"] == side])


def progress_section(labels: list[str], analyses: list[SessionAnalysis]) -> Section:
    """The progress page of sessions in the order given (the first is the baseline)."""
    section = Section("Progress across sessions")
    header = ["parameter", *labels, "change from first", "flag"]
    rows, plots = [], []
    for label, name, source, side in ROWS:
        values = [value_of(a, source, side) for a in analyses]
        first, last = values[0], values[-1]
        change = last[0] - first[0]
        mcid = MCID.get(name)
        if not math.isfinite(change):
            flag: tuple[str, str] = ("", "")
        elif mcid is not None:
            better = change < 0 if name == "gait_profile_score" else change > 0
            flag = (
                (
                    f"beyond MCID ({shown(name, mcid.value, True)}): {'better' if better else 'worse'}",
                    "in" if better else "bad",
                )
                if abs(change) >= mcid.value
                else (f"within MCID ({shown(name, mcid.value, True)})", "")
            )
        else:
            flag = ("detectable change", "warn") if detectable(*first, *last) else ("", "")
        rows.append(
            [
                f"{label} ({DISPLAY[name][2]})",
                *(shown(name, v[0]) for v in values),
                _signed(name, change) if math.isfinite(change) else "–",
                flag,
            ]
        )
        if source in ("gait_speed", "gps", "cadence", "stride_length"):
            plots.append((label, DISPLAY[name][2], [DISPLAY[name][1] * v[0] for v in values]))
    section.add(Table(header, rows))
    section.add(
        Paragraph(
            "Sessions in the order given on the command line; the first is the baseline. MCIDs: gait speed "
            "0.16 m/s (Tilson et al. 2010, subacute stroke), Gait Profile Score 1.6° (Baker et al. 2012). "
            "The other parameters have no MCID here: 'detectable change' means more than the "
            "stride-to-stride variability of the two sessions explains (1.96 sqrt(s1²/n1 + s2²/n2)), "
            "not that it matters clinically.",
            "note",
        )
    )
    section.add(Figure(figures.progress_plots(labels, plots), "Key parameters per session."))
    return section
