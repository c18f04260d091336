"""Cues in a clinician's words: "Bend your right knee more at heel strike" (issue 48 item 5).

A :class:`~gait_biofeedback.core.biofeedback.evaluator.Cue` says a quantity is above or below its band;
:func:`advice` says what the patient should do about it, :func:`quantity_label` names the quantity as
a clinician does (heel strike for initial contact, toe off for terminal contact). The tone mapping
(Hz, beeps/s) is the machine's concern and is not in these words. The symmetry indices are
``(left - right) / mean`` (:func:`~gait_biofeedback.core.gait.cycles.symmetry_index`): positive means
the left value is the larger.
"""

from __future__ import annotations

import math

from gait_biofeedback.core.biofeedback.evaluator import Cue

LABELS: dict[str, str] = {
    "knee_flexion_peak_swing": "Knee bend in swing", "knee_flexion_at_ic": "Knee bend at heel strike",
    "hip_extension_peak_stance": "Hip extension at the end of stance",
    "ankle_dorsiflexion_at_ic": "Toes up at heel strike", "stance_fraction": "Time on the foot (stance)",
    "step_time_symmetry": "Step timing symmetry", "cadence": "Cadence", "stride_length": "Stride length",
    "gait_speed": "Walking speed", "step_length": "Step length",
    "step_length_symmetry": "Step length symmetry",
}

# quantity → (advice when below the band, advice when above); {side} is "left" or "right"
_ADVICE: dict[str, tuple[str, str]] = {
    "knee_flexion_peak_swing": ("Bend your {side} knee more in swing", "Bend your {side} knee less in swing"),
    "knee_flexion_at_ic": ("Bend your {side} knee more at heel strike",
                           "Straighten your {side} knee more at heel strike"),
    "hip_extension_peak_stance": ("Stretch your {side} hip further back at the end of stance",
                                  "Bring your {side} hip less far back at the end of stance"),
    "ankle_dorsiflexion_at_ic": ("Lift your {side} toes more at heel strike",
                                 "Lift your {side} toes less at heel strike"),
    "stance_fraction": ("Stay longer on your {side} foot", "Move off your {side} foot sooner"),
    "step_time_symmetry": ("Even out your step timing: your right steps take longer",
                           "Even out your step timing: your left steps take longer"),
    "cadence": ("Take quicker steps", "Take slower steps"),
    "stride_length": ("Take longer strides with your {side} leg",
                      "Take shorter strides with your {side} leg"),
    "gait_speed": ("Walk faster", "Walk slower"),
    "step_length": ("Take a longer step with your {side} leg", "Take a shorter step with your {side} leg"),
    "step_length_symmetry": ("Even out your steps: your right steps are longer",
                             "Even out your steps: your left steps are longer"),
}


def quantity_label(quantity: str, side: str = "") -> str:
    """The quantity in a clinician's words, with its side: "Knee bend at heel strike (right)"."""
    label = LABELS.get(quantity, quantity.replace("_", " "))
    return f"{label} ({side})" if side else label


def advice(cue: Cue) -> str:
    """What to do about ``cue``: "Bend your right knee more at heel strike"; "In the target range" when
    it is in its band; "" for a quantity without words (an unknown one) or no measured value."""
    if cue.error == 0.0:
        return "In the target range"
    if cue.quantity not in _ADVICE or math.isnan(cue.error):  # NaN: nothing measured
        return ""
    below, above = _ADVICE[cue.quantity]
    return (below if cue.error < 0 else above).format(side=cue.side or "")
