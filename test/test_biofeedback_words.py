"""Cues in a clinician's words (issue 48 item 5): the advice follows the sign of the error against the
therapist's band of config/targets.yaml, and the tone (Hz, beeps/s) is not in it."""

from __future__ import annotations

import math

import pytest

from gait_biofeedback.core.biofeedback.advice import advice, quantity_label
from gait_biofeedback.core.biofeedback.evaluator import Cue, compare, default_targets_path, load_targets

TARGETS = load_targets(default_targets_path())


def _cue(quantity: str, side: str, measured: float) -> Cue:
    band = TARGETS.band(quantity, side)
    error, severity = compare(measured, band)
    frequency, rate = TARGETS.audio.cue(error, band)
    return Cue(quantity, side, band.unit, measured, band.low, band.high, error, severity, frequency, rate,
               3, 0)


@pytest.mark.parametrize(("quantity", "side", "measured", "words"), [
    # knee flexion at heel strike, band -2..10 deg: 4 deg of hyperextension is too little flexion
    ("knee_flexion_at_ic", "right", math.radians(-4.0), "Bend your right knee more at heel strike"),
    ("knee_flexion_at_ic", "left", math.radians(15.0), "Straighten your left knee more at heel strike"),
    ("knee_flexion_peak_swing", "left", math.radians(40.0), "Bend your left knee more in swing"),
    ("ankle_dorsiflexion_at_ic", "right", math.radians(-12.0), "Lift your right toes more at heel strike"),
    ("cadence", "", 80.0 / 60.0, "Take quicker steps"),  # band 96-126 steps/min
    ("gait_speed", "", 0.6, "Walk faster"),
    ("step_length_symmetry", "", 0.15, "Even out your steps: your left steps are longer"),
    ("knee_flexion_at_ic", "right", math.radians(5.0), "In the target range"),
])
def test_advice_says_what_to_do(quantity, side, measured, words):
    cue = _cue(quantity, side, measured)
    assert advice(cue) == words
    assert "Hz" not in words and "beep" not in words


def test_labels_are_clinical_words_with_the_side():
    assert quantity_label("knee_flexion_at_ic", "right") == "Knee bend at heel strike (right)"
    assert quantity_label("cadence") == "Cadence"
    assert all("_" not in quantity_label(q) and " IC" not in quantity_label(q)
               for q in ("knee_flexion_peak_swing", "hip_extension_peak_stance", "ankle_dorsiflexion_at_ic",
                         "stance_fraction", "step_time_symmetry", "stride_length", "step_length_symmetry"))
