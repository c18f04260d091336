"""The dose of feedback (issue 49 item 6): per target fed back, how often its strides were in the target
range at the start and at the end of the session, and how many cues and instructions were given.

Feedback studies after stroke are "promising but inconsistent" partly because dosage and schedules are
seldom reported (Front. Neurol. 2021, doi 10.3389/fneur.2021.637199): this section reports both, from
the feedback given as it was recorded (``biofeedback/given``) and the strides compared with their
targets (``biofeedback/cues``). Shown only when instructions were recorded. The windows compared are
the first and the last 5 minutes (each the first and the second half of a session shorter than 10
minutes)."""

from __future__ import annotations

from collections import Counter

from gait_biofeedback.core.biofeedback.advice import quantity_label
from gait_biofeedback.core.biofeedback.evaluator import SEVERITY_IN_BAND
from gait_biofeedback.core.biofeedback.schedule import KIND_INSTRUCTION, SOURCES
from gait_biofeedback.core.words import plural
from gait_biofeedback.report.document import Paragraph, Section, Table
from gait_biofeedback.report.extract import SessionData

WINDOW_S = 300.0
SCHEDULE_WORDS = {
    "every_stride": "after every stride",
    "bandwidth": "only on strides outside the target range (bandwidth)",
    "faded": "on a share of the strides that fell over the session (faded)",
    "summary": "as a summary after every few strides",
}


def _minutes(seconds: float) -> str:
    return f"{seconds / 60:.0f} min" if seconds >= 60 else f"{seconds:.0f} s"


def in_band_share(cues: list[dict], t0: float, t1: float) -> tuple[int, int]:
    """(strides in band, strides compared) among ``cues`` whose stride closed in [t0, t1] s."""
    chosen = [c for c in cues if t0 <= c["t"] <= t1]
    return sum(c["severity"] == SEVERITY_IN_BAND for c in chosen), len(chosen)


def _share(in_band: int, compared: int) -> str:
    return f"{100.0 * in_band / compared:.0f} % of {compared}" if compared else "no stride"


def instructions_recorded(data: SessionData) -> bool:
    """The session's recording holds an instruction given (the section is shown only then)."""
    return any(g["kind"] == KIND_INSTRUCTION for g in data.given)


def dose_section(data: SessionData) -> Section:
    """Per target fed back: strides in band, first vs last minutes; cues and instructions given."""
    section = Section("Feedback given (dose)")
    schedules = Counter(g["schedule"] for g in data.given)
    words = "; ".join(SCHEDULE_WORDS.get(s, s.replace("_", " ")) for s, _ in schedules.most_common())
    instructions = sum(g["kind"] == KIND_INSTRUCTION for g in data.given)
    section.add(Paragraph(f"Feedback was given {words}: {plural(instructions, 'instruction')} (words shown "
                          f"and spoken) and {plural(len(data.given) - instructions, 'cue')} (the result "
                          "shown, no words).", "note"))
    window = min(WINDOW_S, data.duration_s / 2.0)
    end = data.duration_s
    rows = []
    targets: dict[tuple[str, str], list[dict]] = {}
    for g in data.given:
        targets.setdefault((g["quantity"], g["side"]), []).append(g)
    for (quantity, side), given in sorted(targets.items(), key=lambda kv: -len(kv[1])):
        cues = [c for c in data.cues if (c["quantity"], c["side"]) == (quantity, side)]
        first, last = in_band_share(cues, 0.0, window), in_band_share(cues, end - window, end)
        said = Counter(g["text"] for g in given if g["kind"] == KIND_INSTRUCTION)
        status = "" if not (first[1] and last[1]) else (
            "in" if last[0] * first[1] > first[0] * last[1] else "warn")
        rows.append([quantity_label(quantity, side), _share(*first), (_share(*last), status),
                     str(sum(g["kind"] != KIND_INSTRUCTION for g in given)), str(sum(said.values())),
                     "; ".join(f"“{text}”" for text, _ in said.most_common(2))])
    section.add(Table(["target", f"in range, first {_minutes(window)}", f"in range, last {_minutes(window)}",
                       "cues given", "instructions given", "words"], rows))
    cited = [SOURCES[s] for s in schedules if s in SOURCES]
    if cited:
        section.add(Paragraph("Schedule: " + " ".join(cited), "small"))
    return section
