"""One instruction at a time, the feedback schedules and the knowledge base (issue 49 items 4-6), on
hand-made cues whose expected instruction and firing pattern are worked out by hand in each test."""

from __future__ import annotations

import math

import pytest

from gait_biofeedback.core.biofeedback.evaluator import Band, Cue, compare
from gait_biofeedback.core.biofeedback.instruction import (
    InstructionSelector,
    KnowledgeBaseError,
    load_rules,
    rules_from_dict,
)
from gait_biofeedback.core.biofeedback.instruction_params import InstructionParams
from gait_biofeedback.core.biofeedback.schedule import KIND_CUE, KIND_INSTRUCTION, FeedbackSchedule
from gait_biofeedback.core.stamps import NS_PER_S

DEG = math.pi / 180.0
BANDS = {  # config/targets.yaml, SI
    "hip_extension_peak_stance": (5 * DEG, 20 * DEG, "rad"),
    "knee_flexion_peak_swing": (55 * DEG, 70 * DEG, "rad"),
    "ankle_dorsiflexion_at_ic": (-5 * DEG, 6 * DEG, "rad"),
    "cadence": (96 / 60, 126 / 60, "Hz"),
    "gait_speed": (1.0, 1.6, "m/s"),
    "step_length_symmetry": (-0.08, 0.08, "1"),
}


def cue(quantity: str, side: str, measured: float, stride: int = 1, t_s: float = 1.0) -> Cue:
    low, high, unit = BANDS[quantity]
    error, severity = compare(measured, Band(low, high, unit))
    return Cue(quantity, side, unit, measured, low, high, error, severity, 0.0, 0.0, stride,
               round(t_s * NS_PER_S))


def rule(rule_id: str, quantity: str, direction: str, priority: int, side: str = "any") -> dict:
    return {"id": rule_id, "quantity": quantity, "direction": direction, "priority": priority,
            "text": f"do {rule_id}", "source": "a test", "side": side}


SHIPPED = load_rules()


def test_the_highest_priority_wins_over_a_larger_deviation():
    # left: hip extension 2 deg (0.2 band widths below 5-20), knee in swing 40 deg (1 width below 55-70)
    stride = [cue("hip_extension_peak_stance", "left", 2 * DEG),
              cue("knee_flexion_peak_swing", "left", 40 * DEG), cue("cadence", "", 80 / 60)]
    got = InstructionSelector(SHIPPED, paretic_side="left").update(stride)
    assert (got.rule.id, got.text, got.new) == ("push_off_hip_extension", "Push off more with your left leg",
                                                True)
    assert got.cue.quantity == "hip_extension_peak_stance"


def test_a_tie_in_priority_goes_to_the_largest_deviation_in_band_widths():
    rules = rules_from_dict({"rules": [rule("quicker", "cadence", "below", 50), rule("faster", "gait_speed",
                                                                                  "below", 50)]})
    # cadence 90 steps/min: 6 below a band 30 wide = 0.2; speed 0.85 m/s: 0.15 below 0.6 = 0.25 → speed
    got = InstructionSelector(rules).update([cue("cadence", "", 90 / 60), cue("gait_speed", "", 0.85)])
    assert got.rule.id == "faster"
    # cadence 78 steps/min: 18/30 = 0.6 > 0.25 → cadence
    got = InstructionSelector(rules).update([cue("cadence", "", 78 / 60), cue("gait_speed", "", 0.85)])
    assert got.rule.id == "quicker"


def test_the_focus_holds_for_its_strides_then_the_higher_priority_takes_it():
    rules = rules_from_dict({"rules": [rule("quicker", "cadence", "below", 30),
                                       rule("heel", "ankle_dorsiflexion_at_ic", "below", 80)]})
    selector = InstructionSelector(rules, hold_strides=3)
    slow = cue("cadence", "", 80 / 60)
    toes_down = cue("ankle_dorsiflexion_at_ic", "right", -12 * DEG)
    ids = [selector.update([slow]).rule.id,                       # stride 1: only cadence: its focus
           selector.update([slow, toes_down]).rule.id,            # 2: held (2 of 3)
           selector.update([cue("cadence", "", 110 / 60), toes_down]).rule.id,  # 3: held, cadence in band
           selector.update([slow, toes_down]).rule.id]            # 4: hold over: the heel rule (80 > 30)
    assert ids == ["quicker", "quicker", "quicker", "heel"]
    assert selector.focus.new and selector.focus.text == "do heel"
    # in band and nothing else outside: the focus stays, in band, past its hold
    for _ in range(4):
        kept = selector.update([cue("ankle_dorsiflexion_at_ic", "right", 0.0)])
    assert (kept.rule.id, kept.outside, kept.held) == ("heel", False, 5)
    # once held, any quantity outside takes it, whatever its priority
    assert selector.update([slow]).rule.id == "quicker"


def test_a_focus_is_not_dropped_on_the_other_foot_s_stride():
    selector = InstructionSelector(SHIPPED, hold_strides=1, paretic_side="left")
    left = selector.update([cue("hip_extension_peak_stance", "left", 0.0)])
    right = selector.update([cue("cadence", "", 110 / 60)])  # a right stride: nothing of the left hip
    assert left.rule.id == right.rule.id == "push_off_hip_extension" and not right.new and right.held == 2


def test_the_paretic_side_is_the_one_fed_back():
    left_hip = cue("hip_extension_peak_stance", "left", 0.0)
    right_heel = cue("ankle_dorsiflexion_at_ic", "right", -12 * DEG)
    # the shipped rules for these are stroke rules (side: paretic): without a paretic side, none fires
    assert InstructionSelector(SHIPPED, paretic_side="none").update([left_hip, right_heel]) is None
    assert InstructionSelector(SHIPPED, paretic_side="left").update([left_hip, right_heel]).text == \
        "Push off more with your left leg"
    assert InstructionSelector(SHIPPED, paretic_side="right").update([left_hip, right_heel]).text == \
        "Land on your right heel"
    assert InstructionSelector(SHIPPED, paretic_side="right").update([left_hip]) is None
    # step-length symmetry (L - R) / mean below its band: the left steps are the shorter
    shorter_left = cue("step_length_symmetry", "", -0.2)
    assert InstructionSelector(SHIPPED, paretic_side="left").update([shorter_left]).text == \
        "Take a longer step with your left leg"
    assert InstructionSelector(SHIPPED, paretic_side="right").update([shorter_left]) is None
    # a rule that names the other leg still fires on it
    rules = rules_from_dict({"rules": [rule("other", "hip_extension_peak_stance", "below", 10,
                                            "non_paretic")]})
    assert InstructionSelector(rules, paretic_side="right").update([left_hip]).rule.id == "other"
    assert InstructionSelector(rules, paretic_side="left").update([left_hip]) is None


def test_the_shipped_knowledge_base_loads_and_a_rule_on_an_unmeasured_quantity_never_fires():
    ids = {r.id: r for r in SHIPPED}
    assert ids["push_off_trailing_limb"].quantity == "trailing_limb_angle"
    assert all(r.source for r in SHIPPED)
    # every quantity measured here, far below its band: the trailing-limb rule (95) is never chosen
    stride = [cue(q, "left", low - 2 * (high - low)) for q, (low, high, _) in BANDS.items()]
    chosen = InstructionSelector(SHIPPED, paretic_side="left").update(stride)
    assert chosen.rule.id == "push_off_hip_extension"


@pytest.mark.parametrize(("change", "message"), [
    ({"colour": "red"}, "unknown key 'colour'"),
    ({"source": None}, "no source (each rule cites where it comes from)"),
    ({"direction": "under"}, "direction 'under'; use below or above"),
    ({"quantity": "knee_flexon_peak_swing"}, "unknown quantity 'knee_flexon_peak_swing'"),
    ({"priority": 0}, "priority 0; use a whole number from 1 to 100"),
    ({"side": "paretik"}, "side 'paretik'"),
    ({"text": "Push {leg}"}, "no braces but {side}"),
])
def test_a_malformed_rule_is_refused_with_its_name_and_fault(change, message):
    bad = {**rule("push", "cadence", "below", 10), **change}
    with pytest.raises(KnowledgeBaseError) as refused:
        rules_from_dict({"rules": [rule("fine", "gait_speed", "below", 5), bad]})
    assert str(refused.value).startswith("instructions: rule 2 (") and message in str(refused.value)


def test_a_knowledge_base_file_is_refused_naming_the_file(tmp_path):
    path = tmp_path / "kb.yaml"
    path.write_text("rules:\n  - {id: a, quantity: cadence, direction: below, priority: 3, text: go}\n")
    with pytest.raises(KnowledgeBaseError, match=r"kb\.yaml: instructions: rule 1 \('a'\): no source"):
        load_rules(path)
    path.write_text("rules:\n" + 2 * "  - {id: a, quantity: cadence, direction: below, priority: 3, "
                    "text: go, source: s}\n")
    with pytest.raises(KnowledgeBaseError, match="id 'a' is given to two rules"):
        load_rules(path)


# -- schedules: strides 1 s apart, one quantity (cadence, bilateral) -------------------------------------

def run_schedule(schedule: str, in_band: list[bool], **params) -> list:
    rules = rules_from_dict({"rules": [rule("quicker", "cadence", "below", 30)]})
    selector = InstructionSelector(rules, hold_strides=1)
    plan = FeedbackSchedule(InstructionParams(feedback_schedule=schedule, **{"words_every": 1, **params}))
    out = []
    for k, ok in enumerate(in_band):
        cues = [cue("cadence", "", (110 if ok else 80) / 60, stride=k + 1, t_s=float(k))]
        out.append(plan.decide(selector.update(cues), cues, k + 1, round(k * NS_PER_S)))
    return out


def test_every_stride_gives_each_stride_and_bandwidth_only_those_outside_the_band():
    pattern = [False, False, True, False, True, True]
    every = run_schedule("every_stride", pattern)
    assert [g.kind for g in every] == [KIND_INSTRUCTION, KIND_INSTRUCTION, KIND_CUE, KIND_INSTRUCTION,
                                       KIND_CUE, KIND_CUE]
    band = run_schedule("bandwidth", pattern)
    assert [g is not None for g in band] == [True, True, False, True, False, False]
    assert all(g.schedule == "bandwidth" and g.rate == 1.0 for g in band if g)


def test_faded_feedback_falls_from_every_stride_to_every_other_one():
    # given after n strides: floor(0.5 + sum of the shares); share 1 - 0.5 t / 60 s in the first minute:
    # sum over t = 0..59 s = 60 - 14.75 = 45.25 → 45 given; then 0.5 each: 75.25 → 75, 30 more
    given = run_schedule("faded", [False] * 120, fade_start=1.0, fade_end=0.5, fade_duration_s=60.0)
    first, second = sum(g is not None for g in given[:60]), sum(g is not None for g in given[60:])
    assert (first, second) == (45, 30)
    assert given[0].rate == 1.0 and [g for g in given if g][-1].rate == 0.5
    # strides 1-11 all given (shortfall sum k/120, k < 11: 55/120 < 0.5), the 12th not (66/120)
    assert [g is not None for g in given[:12]] == [True] * 11 + [False]


def test_a_summary_every_five_strides_counts_the_strides_in_band():
    # each block of 5: outside, outside, outside, in, in → given at its 5th stride, 2 of 5 in band
    given = run_schedule("summary", [False, False, False, True, True] * 4, summary_strides=5)
    assert [k + 1 for k, g in enumerate(given) if g] == [5, 10, 15, 20]
    assert {(g.kind, g.block_strides, g.block_in_band, g.instruction.text) for g in given if g} == \
        {(KIND_INSTRUCTION, 5, 2, "do quicker")}
    # a block wholly in band is told so without words
    given = run_schedule("summary", [False] * 5 + [True] * 5, summary_strides=5)
    assert [(g.kind, g.block_in_band) for g in given if g] == [(KIND_INSTRUCTION, 0), (KIND_CUE, 5)]


def test_the_words_come_on_a_new_focus_and_then_after_every_few_feedbacks_without_them():
    kinds = [g.kind for g in run_schedule("bandwidth", [False] * 9, words_every=4)]
    assert kinds == [KIND_INSTRUCTION, KIND_CUE, KIND_CUE, KIND_CUE] * 2 + [KIND_INSTRUCTION]


def test_no_feedback_on_a_stride_without_a_new_value_of_the_focus():
    """A left-hip focus: the right foot's stride (its cues stamped at its own closing IC) gives nothing."""
    selector = InstructionSelector(SHIPPED, hold_strides=1, paretic_side="left")
    plan = FeedbackSchedule(InstructionParams(feedback_schedule="every_stride"))
    left = [cue("hip_extension_peak_stance", "left", 0.0, stride=1, t_s=1.0)]
    right = [cue("cadence", "", 110 / 60, stride=1, t_s=1.55)]
    assert plan.decide(selector.update(left), left, 1, round(1.0 * NS_PER_S)).kind == KIND_INSTRUCTION
    assert selector.update(right).rule.id == "push_off_hip_extension"  # still the focus
    assert plan.decide(selector.focus, right, 1, round(1.55 * NS_PER_S)) is None
