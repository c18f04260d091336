"""Feedback schedules from motor learning (issue 49 item 5): on which strides the focus is given.

Feedback on every trial guides performance but can hinder learning; less frequent, fading or summary
feedback helps retention (the guidance hypothesis). :class:`FeedbackSchedule` gives, on each stride,
the instruction in focus (:mod:`~gait_biofeedback.core.biofeedback.instruction`) or nothing:

* ``every_stride``: every stride with a focus, in band too (knowledge of results each time);
* ``bandwidth``: only strides whose focused quantity is outside its band (Sherwood DE. Effect of
  bandwidth knowledge of results on movement consistency. Percept Mot Skills 1988;66:535-42);
* ``faded``: a share of the strides with a focus that falls linearly from ``fade_start`` to
  ``fade_end`` over ``fade_duration_s`` of the session (Winstein CJ, Schmidt RA. Reduced frequency of
  knowledge of results enhances motor skill learning. J Exp Psychol Learn Mem Cogn 1990;16:677-91).
  The strides are chosen without chance: each stride adds the share to a credit (starting at 0.5), and
  a stride is given whenever the credit reaches 1 (then 1 is taken off): after ``n`` strides
  ``floor(0.5 + sum of the shares)`` have been given, and a share of 0.5 gives every other stride;
* ``summary``: after every ``summary_strides`` strides, the focus with how many of the block's
  strides had that quantity in band (Schmidt RA et al. Summary knowledge of results for skill
  acquisition: support for the guidance hypothesis. J Exp Psychol Learn Mem Cogn 1989;15:352-9).

Feedback is given only on a stride that measured the focused quantity (a per-side focus: the strides
of its foot), not again on the other foot's stride about the same value; a summary comes after its
block whatever stride closes it. What is given is a :class:`Given`: the words (``KIND_INSTRUCTION``:
shown and spoken) when the focused quantity is outside its band, on the focus's first feedback and
then after every ``words_every`` feedbacks given without them, or when a summary says it was outside
on a stride of its block; otherwise a cue (``KIND_CUE``: the result shown, no words: in band, or
outside between the words). Times are the strides' closing ICs, in s from the first stride the
schedule saw.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from gait_biofeedback.core.biofeedback.evaluator import SEVERITY_IN_BAND, Cue
from gait_biofeedback.core.biofeedback.instruction import Instruction
from gait_biofeedback.core.biofeedback.instruction_params import SCHEDULES, InstructionParams
from gait_biofeedback.core.stamps import NS_PER_S

KIND_CUE, KIND_INSTRUCTION = 0, 1  # as gait_biofeedback_msgs/FeedbackGiven
SOURCES = {
    "bandwidth": "Sherwood DE. Effect of bandwidth knowledge of results on movement consistency. Percept Mot "
                 "Skills 1988;66:535-42.",
    "faded": "Winstein CJ, Schmidt RA. Reduced frequency of knowledge of results enhances motor skill "
             "learning. J Exp Psychol Learn Mem Cogn 1990;16:677-91.",
    "summary": "Schmidt RA, Young DE, Swinnen S, Shapiro DC. Summary knowledge of results for skill "
               "acquisition: support for the guidance hypothesis. J Exp Psychol Learn Mem Cogn "
               "1989;15:352-9.",
}
"""Each schedule's source (every stride: the thesis' minimum, feedback on each stride, has none)."""


@dataclass(frozen=True)
class Given:
    """Feedback given on one stride: the focus (``instruction``), ``kind``, the ``schedule``, the share of
    strides given at this time (``rate``), and for a summary the strides summarised and those in band."""

    instruction: Instruction
    kind: int
    schedule: str
    rate: float
    stride_index: int
    stamp_ns: int
    block_strides: int = 1
    block_in_band: int = 0


class FeedbackSchedule:
    """Which strides get the focus (module docstring); :meth:`decide` once per stride, in order."""

    def __init__(self, params: InstructionParams | None = None) -> None:
        self.params = params or InstructionParams()
        if self.params.feedback_schedule not in SCHEDULES:
            raise ValueError(f"feedback_schedule {self.params.feedback_schedule!r}; use one of "
                             f"{', '.join(SCHEDULES)}")
        self.schedule = self.params.feedback_schedule
        self._first_ns: int | None = None
        self._credit = 0.5  # a stride is given when the credit reaches 1: the first one is
        self._block = 0
        self._block_results: dict[tuple[str, str], list[int]] = {}  # (quantity, side) → [strides, in band]
        self._block_focus: Instruction | None = None
        self._words_for: tuple[str, str] | None = None  # (rule, side) whose words were given last
        self._without_words = 0  # feedbacks of that focus given since, without words

    def rate(self, t_s: float) -> float:
        """Share of strides given feedback ``t_s`` into the session (1 but for ``faded``)."""
        if self.schedule != "faded":
            return 1.0
        p = self.params
        return p.fade_start + (p.fade_end - p.fade_start) * min(max(t_s, 0.0) / p.fade_duration_s, 1.0)

    def decide(self, instruction: Instruction | None, cues: Iterable[Cue], stride_index: int,
               stamp_ns: int) -> Given | None:
        """The feedback given on the stride of ``cues`` closing at ``stamp_ns``, or None (silence)."""
        if self._first_ns is None:
            self._first_ns = stamp_ns
        rate = self.rate((stamp_ns - self._first_ns) / NS_PER_S)
        if self.schedule == "summary":
            return self._summary(instruction, cues, stride_index, stamp_ns)
        if instruction is None or instruction.cue.stamp_ns != stamp_ns:  # nothing new of the focus
            return None
        if self.schedule == "bandwidth" and not instruction.outside:
            return None
        if self.schedule == "faded":
            self._credit += rate
            if self._credit < 1.0 - 1e-9:
                return None
            self._credit -= 1.0
        return Given(instruction, self._kind(instruction), self.schedule, rate, stride_index, stamp_ns, 1,
                     int(not instruction.outside))

    def _kind(self, instruction: Instruction) -> int:
        """Words or a cue for feedback given now on ``instruction`` (module docstring)."""
        if not instruction.outside:
            return KIND_CUE
        focus = (instruction.rule.id, instruction.side)
        if focus == self._words_for and self._without_words + 1 < self.params.words_every:
            self._without_words += 1
            return KIND_CUE
        self._words_for, self._without_words = focus, 0
        return KIND_INSTRUCTION

    def _summary(self, instruction: Instruction | None, cues: Iterable[Cue], stride_index: int,
                 stamp_ns: int) -> Given | None:
        for c in cues:
            counts = self._block_results.setdefault((c.quantity, c.side), [0, 0])
            counts[0] += 1
            counts[1] += c.severity == SEVERITY_IN_BAND
        self._block += 1
        self._block_focus = instruction or self._block_focus
        if self._block < self.params.summary_strides:
            return None
        instruction = instruction or self._block_focus  # the block's last focus, if it ended in band
        results, self._block_results, self._block = self._block_results, {}, 0
        if instruction is None:
            return None
        strides, in_band = results.get((instruction.cue.quantity, instruction.cue.side), (0, 0))
        kind = KIND_INSTRUCTION if in_band < strides or instruction.outside else KIND_CUE
        return Given(instruction, kind, self.schedule, 1.0, stride_index, stamp_ns, strides, in_band)
