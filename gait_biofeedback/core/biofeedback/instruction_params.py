"""Parameters of the instruction choice and the feedback schedule (issue 49 items 4-5), declared once:
the ``biofeedback`` node's :class:`~gait_biofeedback.core.biofeedback.evaluator.BiofeedbackParams` has
them; :mod:`.instruction` and :mod:`.schedule` say what they do."""

from __future__ import annotations

from dataclasses import dataclass

from gait_biofeedback.core.params import param

SCHEDULES = ("every_stride", "bandwidth", "faded", "summary")


@dataclass(frozen=True)
class InstructionParams:
    """Parameters of the instruction choice and the feedback schedule (node ``biofeedback``)."""

    instructions_file: str = param("", "the knowledge base of instructions ('' = config/instructions.yaml)")
    instruction_hold_strides: int = param(6, "strides a focus holds before another instruction may take "
                                          "its place", "strides", low=1, high=1000)
    feedback_schedule: str = param("bandwidth", "when feedback is given: every stride, only outside the "
                                   "band (bandwidth), on a share falling over the session (faded), or a "
                                   "summary after every block of strides",
                                   choices=SCHEDULES)
    fade_start: float = param(1.0, "faded: share of strides given feedback at the start", "1", low=0.0,
                              high=1.0)
    fade_end: float = param(0.5, "faded: share of strides given feedback once faded", "1", low=0.0, high=1.0)
    fade_duration_s: float = param(600.0, "faded: time over which the share falls from fade_start to "
                                   "fade_end", "s", low=1.0, high=36000.0)
    summary_strides: int = param(10, "summary: strides per summary", "strides", low=1, high=1000)
    words_every: int = param(4, "the focus's words are given on its first feedback and again after this "
                             "many feedbacks without them (in between: a cue, shown without words; 1 = words "
                             "each time)", "feedbacks", low=1, high=1000)
