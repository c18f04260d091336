"""Stroke gait training (issue 49 items 1-2, docs/guide/stroke.md): the paretic side in the parameters
and the targets file, the stroke quantities' geometry by hand, and each quantity against the simulated
hemiparetic walker's truth through `simulate`, `analyze` and `report` as a user runs them."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from conftest import csv_rows, run_cli

from gait_biofeedback.core.biofeedback.advice import advice
from gait_biofeedback.core.biofeedback.evaluator import (
    QUANTITIES,
    BiofeedbackEvaluator,
    BiofeedbackParams,
    Stride,
    default_targets_path,
    load_targets,
    targets_from_dict,
)
from gait_biofeedback.core.biofeedback.stroke import (
    pelvis_pitch_from_foot_flat,
    stroke_kinematics,
    trailing_limb_angle,
)
from gait_biofeedback.core.body import BodyDimensions
from gait_biofeedback.core.params import ParameterError, from_mapping
from gait_biofeedback.core.stamps import s_to_ns
from gait_biofeedback.report.analysis import analyse_session
from gait_biofeedback.report.extract import read_session
from gait_biofeedback.sim.simulator import hemiparetic, simulate
from gait_biofeedback.sim.stride_truth import stride_truth

DEG = math.pi / 180.0
BAND = {"low": 0.5, "high": 0.8, "unit": "m"}


# ------------------------------------------------------------------ the paretic side


def test_paretic_side_is_a_parameter_with_three_choices():
    assert from_mapping(BiofeedbackParams, {"paretic_side": "right"}).paretic_side == "right"
    assert BiofeedbackParams().paretic_side == "none"
    with pytest.raises(ParameterError, match="paretic_side"):
        from_mapping(BiofeedbackParams, {"paretic_side": "paretic"})


def test_paretic_bands_follow_the_paretic_side():
    spec = {"quantities": {"step_length": {**BAND, "paretic": {"low": 0.4}, "non_paretic": {"high": 0.9}}}}
    left = targets_from_dict(spec, "left")
    assert (left.band("step_length", "left").low, left.band("step_length", "left").high) == (0.4, 0.8)
    assert (left.band("step_length", "right").low, left.band("step_length", "right").high) == (0.5, 0.9)
    right = targets_from_dict(spec, "right")
    assert right.band("step_length", "right").low == 0.4 and right.band("step_length", "left").high == 0.9
    # the symmetry target: the ratio in percent, converted to a fraction
    ratio = targets_from_dict({"quantities": {"step_length_asymmetry_paretic": {
        "low": 95, "high": 110, "unit": "percent"}}}, "left").band("step_length_asymmetry_paretic", "left")
    assert (ratio.low, ratio.high) == pytest.approx((0.95, 1.10))
    # the shipped file loads with and without a paretic side
    assert load_targets(default_targets_path(), "left").paretic_side == "left"
    assert load_targets(default_targets_path()).band("trailing_limb_angle", "right").low == pytest.approx(
        15 * DEG)


@pytest.mark.parametrize(("entry", "side", "match"), [
    ({**BAND, "paretic": {"low": 0.4}}, "none", "needs the session's paretic_side"),
    ({**BAND, "paretic": {"low": 0.4}, "right": {"low": 0.3}}, "right", "right side's band is given twice"),
    ({**BAND, "paretic": 0.4}, "left", "must be a mapping"),
    ({**BAND, "paretic": {"lo": 0.4}}, "left", "must be a mapping"),
    ({**BAND, "symmetry": 95}, "left", "unknown keys \\['symmetry'\\]"),
    ({"low": "short", "high": 0.8}, "left", "step_length left low: expected a finite number"),
    ({"low": 0.5}, "left", "high: expected a finite number, got None"),
    ({**BAND, "sides": "left"}, "left", "sides must be a list"),
])
def test_a_malformed_entry_is_refused_naming_it(entry, side, match):
    with pytest.raises(ValueError, match=match):
        targets_from_dict({"quantities": {"step_length": entry}}, side)


def test_a_ratio_is_one_value_and_the_paretic_side_must_be_known():
    with pytest.raises(ValueError, match="one value for both sides"):
        targets_from_dict({"quantities": {"stance_time_asymmetry_paretic": {
            "low": 95, "high": 105, "unit": "percent", "paretic": {"low": 90}}}}, "left")
    with pytest.raises(ValueError, match="paretic_side"):
        targets_from_dict({}, "both")


# ------------------------------------------------------------------ geometry by hand


def test_trailing_limb_angle_of_a_straight_leg_behind_the_hip():
    lengths = BodyDimensions(thigh_length_m=0.42, shank_length_m=0.43, foot_length_m=0.14,
                             ankle_height_m=0.08)
    # leg straight, 20° behind the vertical, foot flat: ankle (-0.85 sin 20°, -0.85 cos 20°) =
    # (-0.290717, -0.798739), metatarsal heads 0.14 ahead and 0.08 below: (-0.150717, -0.878739)
    assert trailing_limb_angle(-20 * DEG, 0.0, 20 * DEG, 0.0, lengths) == pytest.approx(
        math.atan(0.150717 / 0.878739), abs=1e-5)
    # the same leg under a pelvis pitched 8° forward with the hip 8° more extended: the same line
    assert trailing_limb_angle(-28 * DEG, 0.0, 20 * DEG, 8 * DEG, lengths) == pytest.approx(
        math.atan(0.150717 / 0.878739), abs=1e-5)
    # standing straight: the toes are 0.14 m ahead of the hip line, 0.93 m below it
    assert trailing_limb_angle(0.0, 0.0, 0.0, 0.0, lengths) == pytest.approx(-math.atan(0.14 / 0.93),
                                                                             abs=1e-6)


def test_stroke_kinematics_of_a_hand_made_stride():
    """Stride 10.0-11.0 s, TC at 10.6, the other IC at 10.5. In foot flat (10.12-10.27 s) the chain
    h - k + d is 8°, so the pelvis pitch is -8°; at 10.5 s hip -12°, knee 0, ankle 12°; the ankle then
    plantarflexes to -15° at 10.65 s (push-off 27°); the knee's least flexion in 10.1-10.5 s is -4°."""
    t = np.arange(10.0, 11.0001, 0.01)
    hip = np.interp(t, [10.0, 10.3, 10.5, 11.0], [20, 0, -12, 20]) * DEG
    knee = np.interp(t, [10.0, 10.1, 10.3, 10.5, 10.7, 11.0], [2, 6, -4, 0, 40, 2]) * DEG
    # ankle = 8° - hip + knee in foot flat, 12° at the other IC, down to -15° at 10.65 s
    ankle = np.where((t >= 10.1) & (t <= 10.3), 8 * DEG - hip + knee,
                     np.interp(t, [10.0, 10.1, 10.3, 10.5, 10.65, 11.0], [0, -6, 4, 12, -15, 0]) * DEG)
    angles = np.stack([hip, knee, ankle], axis=1)
    assert pelvis_pitch_from_foot_flat(t, angles, 10.0, 10.6) == pytest.approx(-8 * DEG, abs=1e-9)
    lengths = BodyDimensions()
    out = stroke_kinematics(t, angles, 10.0, 10.6, 10.5, 11.0, lengths)
    assert out["knee_hyperextension_stance"] == pytest.approx(-4 * DEG, abs=1e-9)
    assert out["propulsion"] == pytest.approx(27 * DEG, abs=1e-9)
    # world: thigh -20°, shank -20°, foot -8°
    assert out["trailing_limb_angle"] == pytest.approx(
        trailing_limb_angle(-20 * DEG, 0.0, 12 * DEG, 0.0, lengths), abs=1e-9)
    # the other foot's IC unknown: no trailing limb angle, no push-off; TC unknown: nothing
    assert set(stroke_kinematics(t, angles, 10.0, 10.6, math.nan, 11.0, lengths)) == {
        "knee_hyperextension_stance"}
    assert stroke_kinematics(t, angles, 10.0, math.nan, 10.5, 11.0, lengths) == {}


def test_paretic_ratios_over_the_window():
    evaluator = BiofeedbackEvaluator(load_targets(default_targets_path(), "right"))
    for k, (side, stance) in enumerate([("left", 0.70), ("right", 0.56), ("left", 0.72), ("right", 0.58)]):
        t0 = 10.0 + 0.55 * k
        stride = Stride(side, k, s_to_ns(t0), s_to_ns(t0 + stance), s_to_ns(t0 + 1.1), foot_angle_ic=0.3,
                        max_foot_height=0.12)
        result = evaluator.evaluate(stride)
    ratio = result.kinematics["stance_time_asymmetry_paretic"]
    assert ratio == pytest.approx(0.57 / 0.71, abs=1e-9)  # right (paretic) 0.56, 0.58; left 0.70, 0.72
    assert result.kinematics["foot_strike_angle"] == 0.3 and result.kinematics["swing_foot_clearance"] == 0.12
    cue = next(c for c in result.cues if c.quantity == "stance_time_asymmetry_paretic")
    assert cue.side == "" and cue.error == pytest.approx(0.57 / 0.71 - 0.95, abs=1e-9)
    assert advice(cue) == "Stay longer on your affected leg"  # too short a paretic stance
    none = BiofeedbackEvaluator(load_targets(default_targets_path()))
    for side in ("left", "right"):
        out = none.evaluate(Stride(side, 0, s_to_ns(10.0), s_to_ns(10.6), s_to_ns(11.0)))
    assert "stance_time_asymmetry_paretic" not in out.kinematics


# ------------------------------------------------------------------ the simulated hemiparetic walker

# Errors measured (seed 3, walk 30 s, `benchmarks/stroke.py`; mean ± SD, largest): trailing limb angle
# paretic -1.5 ± 0.3° (2.0), other -2.3 ± 0.2° (2.6); push-off -1.3 / +0.5° (1.4); least knee flexion
# +1.9 / +0.4° (1.9); strike angle +0.7 / +0.1° (0.7); clearance -0.12 / -0.05 cm (0.15); step
# length +2.5 / -0.8 cm (2.8). Limits: about twice the largest.
LIMITS = {"trailing_limb_angle": 5.0 * DEG, "propulsion": 3.0 * DEG, "knee_hyperextension_stance": 4.0 * DEG,
          "foot_strike_angle": 1.5 * DEG, "swing_foot_clearance": 0.003, "step_length": 0.055}


@pytest.fixture(scope="module")
def hemiparetic_walk(tmp_path_factory):
    root = tmp_path_factory.mktemp("stroke")
    rc, _, err = run_cli("simulate", "--scenario", "hemiparetic", "--duration", "30", "--seed", "3",
                         "-o", str(root / "raw"))
    assert rc == 0, err
    rc, _, err = run_cli("analyze", str(root / "raw"), "-o", str(root / "analyzed"), "--calibrate-at",
                         "12:walking")
    assert rc == 0, err
    rc, _, err = run_cli("report", str(root / "analyzed"), "-o", str(root / "report"), "--paretic-side",
                         "left")
    assert rc == 0, err
    analysis = analyse_session(read_session(root / "analyzed"), load_targets(default_targets_path(), "left"))
    truth = stride_truth(simulate(hemiparetic(duration=30.0, seed=3)))
    return {"root": root, "analysis": analysis, "truth": truth}


def _matched(walk) -> list[tuple[dict, dict]]:
    """(row of a used stride, its true stride) by side and closing IC within 50 ms."""
    out = []
    for row in walk["analysis"].used:
        same = [tr for tr in walk["truth"]
                if tr["side"] == row["side"] and abs(tr["t_end"] - row["end_s"]) < 0.05]
        if len(same) == 1:
            out.append((row, same[0]))
    return out


def test_the_walker_has_the_hemiparetic_deviations_in_its_truth(hemiparetic_walk):
    steady = [tr for tr in hemiparetic_walk["truth"] if 12.0 < tr["t_start"] < 30.0]

    def mean(side: str, q: str) -> float:
        return float(np.mean([tr[q] for tr in steady if tr["side"] == side]))

    assert mean("left", "knee_hyperextension_stance") < -5 * DEG
    assert mean("right", "knee_hyperextension_stance") > 0
    assert mean("left", "trailing_limb_angle") < mean("right", "trailing_limb_angle") - 2 * DEG
    assert mean("left", "step_length") < 0.8 * mean("right", "step_length")
    assert mean("left", "stance_time") < 0.95 * mean("right", "stance_time")
    assert mean("left", "foot_strike_angle") < 6 * DEG < 15 * DEG < mean("right", "foot_strike_angle")
    assert mean("left", "propulsion") < 0.5 * mean("right", "propulsion")
    assert mean("left", "swing_foot_clearance") < 0.7 * mean("right", "swing_foot_clearance")


@pytest.mark.parametrize("quantity", sorted(LIMITS))
def test_each_quantity_is_within_its_accuracy_of_the_truth(hemiparetic_walk, quantity):
    pairs = [(row[quantity], tr[quantity]) for row, tr in _matched(hemiparetic_walk)
             if math.isfinite(row.get(quantity, math.nan))]
    assert len(pairs) >= 20, f"{quantity}: {len(pairs)} strides compared"
    errors = np.array([a - b for a, b in pairs])
    assert np.abs(errors).max() < LIMITS[quantity], (quantity, errors)


def test_paretic_ratios_match_the_true_ratios(hemiparetic_walk):
    """The last stride's window ratio against the truth's ratio of the same strides' means (the 10
    latest of each side up to that stride)."""
    pairs = _matched(hemiparetic_walk)
    row, last = pairs[-1]
    before = [tr for tr in hemiparetic_walk["truth"] if tr["t_end"] <= last["t_end"] + 1e-6]

    def true_ratio(q: str) -> float:
        side = {s: [tr[q] for tr in before if tr["side"] == s][-10:] for s in ("left", "right")}
        return float(np.mean(side["left"]) / np.mean(side["right"]))

    # stance times from the detected events: the paretic one exact, the other's 45 ms short (its IC
    # 25 ms late, its TC 20 ms early): the ratio 0.96 for a true 0.91; step length as above
    assert row["stance_time_asymmetry_paretic"] == pytest.approx(true_ratio("stance_time"), abs=0.1)
    assert row["stance_time_asymmetry_paretic"] < 1.0
    assert row["step_length_asymmetry_paretic"] == pytest.approx(true_ratio("step_length"), abs=0.1)
    assert row["step_length_asymmetry_paretic"] < 0.8  # clearly asymmetric: the paretic step is short


def test_the_report_carries_the_stroke_quantities(hemiparetic_walk):
    rows = csv_rows(Path(hemiparetic_walk["root"]) / "report" / "strides.csv")
    used = [r for r in rows if r["used"] == "True" and r["trailing_limb_angle"] not in ("", "nan")]
    assert len(used) >= 20
    left = np.median([float(r["knee_hyperextension_stance"]) for r in used if r["side"] == "left"])
    assert left < 0  # the paretic knee hyperextends
    assert any(r["stance_time_asymmetry_paretic"] not in ("", "nan") for r in used)


def test_the_dashboard_groups_every_quantity_as_the_evaluator_does():
    """The page's own lists (app.js: which quantities are one value for both sides, and each one's
    joint group for the feedback selection) name every quantity of the evaluator, as it groups them."""
    page = (Path(__file__).resolve().parents[1] / "gait_biofeedback" / "dashboard" / "app.js").read_text()
    listed = re.search(r"const BILATERAL = new Set\(\[(.*?)\]\)", page, re.S)[1]
    bilateral = set(re.findall(r'"(\w+)"', listed))
    groups = dict(re.findall(r"(\w+): \"(\w+)\"", re.search(r"const groups = \{(.*?)\};", page, re.S)[1]))
    assert bilateral == {q for q, (_, both, _) in QUANTITIES.items() if both}
    assert groups == {q: group for q, (group, _, _) in QUANTITIES.items()}


def test_the_simulator_refuses_a_wrong_paretic_setting():
    with pytest.raises(ValueError, match="paretic_side must be None, 'left' or 'right'"):
        simulate(hemiparetic(duration=5.0, paretic_side="both"))
    with pytest.raises(ValueError, match=r"paretic_stance_fraction 0\.5 outside"):
        simulate(hemiparetic(duration=5.0, paretic_stance_fraction=0.5))
