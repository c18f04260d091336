"""Biofeedback core: comparison with bands, the audio cue rule, targets file, hand-made strides."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gait_biofeedback.core.biofeedback import normative as normative_gait
from gait_biofeedback.core.biofeedback.evaluator import (
    SEVERITY_IN_BAND,
    SEVERITY_MILD,
    SEVERITY_SEVERE,
    AudioRule,
    Band,
    BiofeedbackEvaluator,
    Stride,
    compare,
    default_targets_path,
    load_targets,
    sagittal_stick_figure,
    select_audio_cue,
    targets_from_dict,
)
from gait_biofeedback.core.body import BodyDimensions
from gait_biofeedback.core.stamps import s_to_ns

DEG = math.pi / 180


def test_compare_error_and_severity():
    band = Band(55 * DEG, 70 * DEG, "rad")
    assert compare(60 * DEG, band) == (0.0, SEVERITY_IN_BAND)
    assert compare(55 * DEG, band) == (0.0, SEVERITY_IN_BAND)  # edges are inside
    error, severity = compare(50 * DEG, band)
    assert error == pytest.approx(-5 * DEG) and severity == SEVERITY_MILD
    error, severity = compare(86 * DEG, band)  # 16° above: more than the 15° band width
    assert error == pytest.approx(16 * DEG) and severity == SEVERITY_SEVERE


def test_audio_rule_silent_in_band_pitch_and_rate_follow_the_error():
    rule = AudioRule(base_frequency=660.0, octaves=1.0, min_rate=1.0, max_rate=6.0)
    band = Band(0.0, 1.0, "1")
    assert rule.cue(0.0, band) == (0.0, 0.0)
    f_hi, r_small = rule.cue(0.1, band)
    f_hi2, r_big = rule.cue(0.5, band)
    f_lo, r_lo = rule.cue(-0.5, band)
    assert 660 < f_hi < f_hi2 < 1320 and 330 < f_lo < 660  # too much → higher, too little → lower
    assert f_hi2 == pytest.approx(660 * 2 ** 0.5) and f_lo == pytest.approx(660 * 2 ** -0.5)
    assert 1.0 < r_small < r_big < 6.0 and r_lo == pytest.approx(r_big)
    assert rule.cue(3.0, band) == pytest.approx((1320.0, 6.0))  # saturates at one band width


def test_targets_file_converts_to_si_and_validates():
    targets = load_targets(default_targets_path())
    cadence = targets.band("cadence", "left")
    assert (cadence.low, cadence.high) == pytest.approx((1.6, 2.1)) and cadence.unit == "Hz"
    knee = targets.band("knee_flexion_peak_swing", "right")
    assert knee.low == pytest.approx(55 * DEG) and knee.unit == "rad"
    assert targets.band("stance_fraction", "left").high == pytest.approx(0.65)
    ref = targets.to_json()["reference"]["knee_flexion"]
    assert len(ref["percent"]) == 21 and np.allclose(np.subtract(ref["high"], ref["low"]), 14 * DEG)

    custom = targets_from_dict({"quantities": {
        "knee_flexion_peak_swing": {"low": 40, "high": 70, "unit": "deg", "left": {"low": 30, "high": 50}},
        "cadence": {"enabled": False, "low": 1, "high": 2, "unit": "Hz"},
        "stance_fraction": {"low": 0.55, "high": 0.65, "unit": "1", "sides": ["right"]}}})
    assert custom.band("knee_flexion_peak_swing", "left").high == pytest.approx(50 * DEG)
    assert custom.band("knee_flexion_peak_swing", "right").high == pytest.approx(70 * DEG)
    assert custom.band("cadence", "") is None and custom.band("stance_fraction", "left") is None
    with pytest.raises(ValueError, match="unknown quantity"):
        targets_from_dict({"quantities": {"walking_speed": {"low": 1, "high": 2, "unit": "1"}}})
    with pytest.raises(ValueError, match="unit"):
        targets_from_dict({"quantities": {"cadence": {"low": 1, "high": 2, "unit": "deg"}}})
    with pytest.raises(ValueError, match="low"):
        targets_from_dict({"quantities": {"cadence": {"low": 3, "high": 2, "unit": "Hz"}}})


def _hand_made_stride(evaluator: BiofeedbackEvaluator, side: str, knee_peak_deg: float, t0: float = 10.0,
                      stride_time: float = 1.2, gap: tuple[float, float] | None = None,
                      doubtful: tuple[float, float] | None = None) -> Stride:
    """Feed one stride: hip cos from 25° to -12°, knee 3° at IC with a swing bump, ankle 2°."""
    t = t0 + np.arange(0.0, stride_time + 0.1, 0.01)
    u = (t - t0) / stride_time
    hip = DEG * (6.5 + 18.5 * np.cos(2 * np.pi * u))  # max 25° at IC, min -12° at 50 %
    swing = np.clip((u - 0.6) / 0.4, 0, 1)
    knee = DEG * (3 + (knee_peak_deg - 3) * np.sin(np.pi * swing) ** 2)
    ankle = np.full_like(t, 2 * DEG)
    for k in range(len(t)):
        if gap is not None and gap[0] <= t[k] < gap[1]:
            continue
        marked = doubtful is not None and doubtful[0] <= t[k] < doubtful[1]
        evaluator.add_angles(side, s_to_ns(float(t[k])), float(hip[k]), float(knee[k]), float(ankle[k]),
                             doubtful=marked)
    return Stride(side, 7, s_to_ns(t0), s_to_ns(t0 + 0.6 * stride_time), s_to_ns(t0 + stride_time),
                  stance_fraction=0.6, cadence=2 / stride_time, step_time_symmetry=0.3)


def test_hand_made_stride_gives_the_expected_cues():
    evaluator = BiofeedbackEvaluator(load_targets(default_targets_path()))
    stride = _hand_made_stride(evaluator, "left", knee_peak_deg=45.0)
    assert evaluator.covers(stride)
    result = evaluator.evaluate(stride)
    cues = {c.quantity: c for c in result.cues}
    # no step time: no trailing limb angle nor push-off (they need the other foot's IC); no foot trajectory
    assert set(cues) == {"knee_flexion_peak_swing", "knee_flexion_at_ic", "hip_extension_peak_stance",
                         "ankle_dorsiflexion_at_ic", "stance_fraction", "cadence", "step_time_symmetry",
                         "knee_hyperextension_stance"}
    assert cues["knee_hyperextension_stance"].measured == pytest.approx(3 * DEG, abs=1e-6)  # flat 3° stance
    knee = cues["knee_flexion_peak_swing"]
    assert knee.measured == pytest.approx(45 * DEG, abs=0.1 * DEG)
    assert knee.error == pytest.approx(-10 * DEG, abs=0.1 * DEG) and knee.severity == SEVERITY_MILD
    assert 0 < knee.audio_frequency < 660 and knee.audio_rate > 1  # too little flexion → lower tone
    assert cues["hip_extension_peak_stance"].measured == pytest.approx(12 * DEG, abs=0.05 * DEG)
    assert cues["knee_flexion_at_ic"].measured == pytest.approx(3 * DEG, abs=1e-6)
    assert cues["ankle_dorsiflexion_at_ic"].severity == SEVERITY_IN_BAND
    assert cues["ankle_dorsiflexion_at_ic"].audio_rate == 0.0 and cues["ankle_dorsiflexion_at_ic"].error == 0
    assert cues["stance_fraction"].severity == SEVERITY_IN_BAND and cues["stance_fraction"].side == "left"
    cadence = cues["cadence"]
    assert cadence.side == "" and cadence.measured == pytest.approx(2 / 1.2)
    sym = cues["step_time_symmetry"]
    assert sym.severity == SEVERITY_SEVERE and sym.error == pytest.approx(0.22)  # 30 % vs ±8 %
    assert all(c.stride_index == 7 and c.stamp_ns == 11_200_000_000 for c in result.cues)
    # curves: normalised 0..100 % every 2 %, starting at the IC value
    assert len(result.percent) == 51 and result.curves["hip_flexion"][0] == pytest.approx(25 * DEG, abs=1e-3)
    assert result.curves["knee_flexion"].max() == pytest.approx(45 * DEG, abs=0.2 * DEG)


def test_stride_with_a_gap_marked_angles_or_implausible_gives_only_temporal_or_no_cues():
    evaluator = BiofeedbackEvaluator(load_targets(default_targets_path()))
    stride = _hand_made_stride(evaluator, "right", knee_peak_deg=60.0, gap=(10.5, 10.8))
    result = evaluator.evaluate(stride)
    assert {c.quantity for c in result.cues} == {"stance_fraction", "cadence", "step_time_symmetry"}
    assert not result.curves
    stride.plausible = False
    assert evaluator.evaluate(stride).cues == []
    later = Stride("right", 8, 20_000_000_000, 20_700_000_000, 21_200_000_000, 0.6, 1.6, math.nan)
    assert not evaluator.covers(later)
    assert "step_time_symmetry" not in {c.quantity for c in evaluator.evaluate(later).cues}  # NaN: skipped
    # angles marked as recovering from a sensor dropout are left out: the same as a gap
    marked = _hand_made_stride(evaluator, "left", knee_peak_deg=20.0, doubtful=(10.0, 10.6))
    assert {c.quantity for c in evaluator.evaluate(marked).cues} == {"stance_fraction", "cadence",
                                                                      "step_time_symmetry"}


def test_select_audio_cue_follows_the_chosen_side_and_joint():
    evaluator = BiofeedbackEvaluator(load_targets(default_targets_path()))
    left = evaluator.evaluate(_hand_made_stride(evaluator, "left", knee_peak_deg=45.0)).cues
    right = evaluator.evaluate(_hand_made_stride(evaluator, "right", knee_peak_deg=62.0, t0=10.6)).cues
    cues = left + right
    worst = select_audio_cue(cues)
    assert worst.quantity == "step_time_symmetry"  # 1.4 band widths out
    knee = select_audio_cue(cues, side="left", joint="knee")
    assert knee.quantity == "knee_flexion_peak_swing" and knee.side == "left"
    assert select_audio_cue(cues, side="right", joint="knee") is None  # right knee in band: silence
    assert select_audio_cue(cues, side="right", joint="ankle") is None


def test_sagittal_stick_figure_geometry():
    zero = {f"{s}_{j}_{k}": 0.0 for s in ("left", "right") for j, kinds in
            (("hip", ("flexion", "adduction", "internal_rotation")),
             ("knee", ("flexion", "adduction", "internal_rotation")),
             ("ankle", ("dorsiflexion", "inversion", "internal_rotation"))) for k in kinds}
    body = BodyDimensions(thigh_length_m=0.43)
    lines = {(seg, k): v for k, (seg, *v) in enumerate(sagittal_stick_figure(zero, body))}
    segs = [seg for seg, _ in lines]
    assert segs.count("pelvis") == 2 and {"left_thigh", "right_shank", "right_foot"} <= set(segs)
    by_seg = {seg: v for (seg, _), v in lines.items() if seg != "pelvis"}
    x0, y0, x1, y1 = by_seg["left_thigh"]
    assert x1 == pytest.approx(x0) and y0 - y1 == pytest.approx(0.43)  # vertical thigh
    bent = dict(zero, left_hip_flexion=30 * DEG, left_knee_flexion=60 * DEG)
    b = {seg: v for seg, *v in sagittal_stick_figure(bent, body)}
    hip_x, _, knee_x, _ = b["left_thigh"]
    _, _, ankle_x, _ = b["left_shank"]
    assert knee_x - hip_x == pytest.approx(0.43 * math.sin(30 * DEG), abs=1e-6)  # knee forward
    assert ankle_x < knee_x  # the flexed knee puts the ankle behind it
    assert b["right_thigh"] == pytest.approx(by_seg["right_thigh"])  # the other leg unchanged


def test_reference_curves_reproduce_the_typed_key_values():
    for name, keys in normative_gait.KEY_VALUES_DEG.items():
        pct = np.array([p for p, _ in keys])
        values = normative_gait.reference_curve(name, pct) / DEG
        assert np.allclose(values, [v for _, v in keys], atol=1e-9)
    knee = normative_gait.reference_curve("knee_flexion") / DEG
    assert len(knee) == 21 and 55 < knee.max() < 65 and knee[0] == pytest.approx(knee[-1])
    with pytest.raises(ValueError):
        normative_gait.reference_curve("pelvis_tilt")
