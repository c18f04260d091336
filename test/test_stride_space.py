"""Spatial values of a stride: pairing IC→IC strides with the foot trajectory's stance-to-stance strides
(issue 16), and the step length from the legs' geometry (hand-made numbers)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gait_biofeedback.core.biofeedback.evaluator import (
    BiofeedbackEvaluator,
    Stride,
    ankle_ahead,
    default_targets_path,
    load_targets,
    step_length,
)
from gait_biofeedback.core.body import BodyDimensions
from gait_biofeedback.core.gait.cycles import GaitCycle
from gait_biofeedback.core.gait.spatial import SpatialPairing
from gait_biofeedback.core.spatial.provisional import ProvisionalStride
from gait_biofeedback.core.spatial.strides import SpatialStride

S = 1_000_000_000
DEG = math.pi / 180


def _cycle(index: int, start_s: float, end_s: float) -> GaitCycle:
    nan = math.nan
    return GaitCycle("left", index, round(start_s * S), round(end_s * S), None, end_s - start_s, nan, nan,
                     nan, nan, nan, nan, nan, nan, nan, True)


def _stride(off_s: float, flat_s: float, length: float = 1.3, flags: tuple[str, ...] = ()) -> SpatialStride:
    return SpatialStride(0, 0, 0, 0, length, 1.0, length, 0.12, math.nan, 0.35, -1.1, 0.01, 0.02, flags,
                         foot_off_ns=round(off_s * S), foot_flat_ns=round(flat_s * S))


def test_a_stride_gets_the_trajectory_stride_of_its_swing():
    pairing = SpatialPairing(wait_s=0.4)
    pairing.add_cycle(_cycle(1, 10.0, 11.1))
    assert pairing.due(round(11.2 * S)) == []  # the next stance has not closed the trajectory yet
    pairing.add_stride(_stride(10.5, 11.18))
    ((cycle, space, revision),) = pairing.due(round(11.3 * S))
    assert cycle.index == 1 and space.flag == "" and not revision and not space.provisional
    assert space.stride_length == 1.3 and space.gait_speed == pytest.approx(1.3 / 1.1)
    assert space.foot_angle_tc == -1.1 and space.max_foot_height == 0.12


def test_a_missed_stance_gives_no_values_to_either_stride():
    """The trajectory saw no stance between two ICs: its stride spans both, so neither has values."""
    pairing = SpatialPairing(wait_s=0.4)
    pairing.add_cycle(_cycle(1, 10.0, 11.0))
    assert pairing.due(round(11.39 * S)) == []
    ((_, first, _),) = pairing.due(round(11.4 * S))
    assert math.isnan(first.stride_length) and first.flag.startswith("no stance of the foot within 0.4 s")
    pairing.add_cycle(_cycle(2, 11.0, 12.0))
    pairing.add_stride(_stride(10.5, 12.1, length=2.6))
    ((_, second, _),) = pairing.due(round(12.2 * S))
    assert math.isnan(second.stride_length) and second.flag.startswith("a stance was missed")


def test_a_flagged_trajectory_stride_gives_no_values_an_informative_flag_keeps_them():
    pairing = SpatialPairing(wait_s=0.4)
    pairing.add_cycle(_cycle(1, 10.0, 11.0))
    pairing.add_stride(_stride(10.5, 11.1, flags=("no stance for 2.7 s: spatial values unknown",)))
    pairing.add_cycle(_cycle(2, 11.0, 12.0))
    pairing.add_stride(_stride(11.5, 12.1, flags=("started from standing",)))
    (_, bad, _), (_, good, _) = pairing.due(round(12.2 * S))
    assert math.isnan(bad.stride_length) and bad.flag == "no stance for 2.7 s: spatial values unknown"
    assert good.stride_length == 1.3 and good.flag == ""


def test_a_stride_goes_out_at_ic_plus_50_ms_with_its_provisional_length_and_its_smoothed_values_follow():
    """At the last sample at or before IC + 50 ms (100 Hz: 11.05 s) the trajectory is asked once; the stride
    goes out with the provisional length, speed, foot height and angles, then its revision with the
    smoothed values."""
    pairing = SpatialPairing(wait_s=0.4, provisional_after_s=0.05, period_s=0.01)
    pairing.add_cycle(_cycle(1, 10.0, 11.0))
    asked = []

    def provisional():
        asked.append(True)
        return ProvisionalStride(round(10.5 * S), 1.25, 0.12, 0.3, -0.9)

    assert pairing.due(round(11.04 * S), provisional) == [] and not asked
    ((cycle, space, revision),) = pairing.due(round(11.05 * S), provisional)
    assert cycle.index == 1 and not revision and space.provisional and space.flag == ""
    assert space.stride_length == 1.25 and space.gait_speed == pytest.approx(1.25)
    assert (space.max_foot_height, space.foot_angle_ic, space.foot_angle_tc) == (0.12, 0.3, -0.9)
    assert math.isnan(space.turning_angle) and math.isnan(space.min_toe_clearance)
    assert pairing.due(round(11.2 * S), provisional) == [] and len(asked) == 1
    pairing.add_stride(_stride(10.5, 11.18))
    ((cycle, space, revision),) = pairing.due(round(11.3 * S), provisional)
    assert cycle.index == 1 and revision and not space.provisional and space.stride_length == 1.3


def test_without_a_provisional_value_of_its_own_swing_a_stride_waits_for_the_smoothed_one():
    """None (the foot's first strides), or a swing that left before the opening IC (a missed stance):
    the stride is held as without provisional values, and asked only once; a reset releases a
    pending revision without values."""
    pairing = SpatialPairing(wait_s=0.4, provisional_after_s=0.05, period_s=0.01)
    pairing.add_cycle(_cycle(1, 10.0, 11.0))
    answers = iter([None, ProvisionalStride(round(9.5 * S), 2.6, 0.1, 0.2, -0.3)])
    assert pairing.due(round(11.05 * S), lambda: next(answers)) == []
    assert pairing.due(round(11.06 * S), lambda: next(answers)) == []  # asked once: no second answer used
    pairing.add_stride(_stride(10.5, 11.18))
    ((_, space, revision),) = pairing.due(round(11.3 * S), lambda: next(answers))
    assert not revision and not space.provisional and space.stride_length == 1.3
    pairing.add_cycle(_cycle(2, 11.0, 12.0))
    left_before = ProvisionalStride(round(10.9 * S), 1.3, 0.1, 0.2, -0.3)
    assert pairing.due(round(12.05 * S), lambda: left_before) == []  # left before its IC
    pairing.add_cycle(_cycle(3, 12.0, 13.0))
    pairing.release("x")  # the held ones go out without values
    pairing.add_cycle(_cycle(4, 13.0, 14.0))
    fourth = ProvisionalStride(round(13.5 * S), 1.2, 0.1, 0.2, -0.3)
    ((_, space, _),) = pairing.due(round(14.05 * S), lambda: fourth)
    assert space.provisional
    ((cycle, space, revision),) = pairing.release("state reset (gap): spatial values unknown")
    assert cycle.index == 4 and revision and math.isnan(space.stride_length)
    assert space.flag.startswith("state reset")


def test_step_length_by_hand():
    legs = BodyDimensions(thigh_length_m=0.4, shank_length_m=0.45)
    assert ankle_ahead(30 * DEG, 0.0, legs) == pytest.approx(0.85 * 0.5)
    assert ankle_ahead(30 * DEG, 30 * DEG, legs) == pytest.approx(0.2)  # the shank vertical
    assert step_length(1.4, 0.8, 0.6) == pytest.approx(0.8)
    assert math.isnan(step_length(1.4, -0.05, 0.6)) and math.isnan(step_length(math.nan, 0.8, 0.6))


def test_an_asymmetric_step_from_the_joint_angles():
    """Right stride 1.0-2.0 s, the left IC at 1.45 s (step time 0.55 s). At 2.0 s the right hip is at
    +20°, the left at -10°; at 1.45 s the left at +12°, the right at -6° (knees straight)."""
    evaluator = BiofeedbackEvaluator(load_targets(default_targets_path()))
    pose = {1.45: {"left": 12.0, "right": -6.0}, 2.0: {"left": -10.0, "right": 20.0}}
    for t, hips in pose.items():
        for dt in (-0.01, 0.0, 0.01):
            for side, hip in hips.items():
                evaluator.add_angles(side, round((t + dt) * S), hip * DEG, 0.0, 0.0)
    stride = Stride("right", 3, 1 * S, round(1.6 * S), 2 * S, step_time=0.55, stride_length=1.3,
                    gait_speed=1.3, turning_angle=19 * DEG)
    # the foot's first stride of a walk (nothing evaluated before it ends at its start) gives none
    assert evaluator.spatial(stride) == {}
    before = Stride("right", 2, 0, round(0.6 * S), 1 * S, step_time=0.55, stride_length=1.3, gait_speed=1.3,
                    turning_angle=0.0)
    evaluator.spatial(before)
    got = evaluator.spatial(stride)
    legs = 0.42 + 0.43  # the default thigh + shank
    own = legs * (math.sin(20 * DEG) + math.sin(10 * DEG))
    other = legs * (math.sin(12 * DEG) + math.sin(6 * DEG))
    assert got["step_length"] == pytest.approx(1.3 * own / (own + other))  # 0.826 m of 1.3
    assert got["stride_length"] == 1.3 and got["gait_speed"] == 1.3
    flagged = Stride("right", 4, 1 * S, round(1.6 * S), 2 * S, step_time=0.55, stride_length=1.3,
                     spatial_flag="a stance was missed")
    assert evaluator.spatial(flagged) == {}
    # a turn (over 20°, or an angle not known: a provisional one not trusted) gives no spatial cue
    for turning in (-21 * DEG, 40 * DEG, math.nan):
        turn = Stride("right", 5, 3 * S, round(3.6 * S), 4 * S, step_time=0.55, stride_length=0.8,
                      gait_speed=0.8, turning_angle=turning)
        assert turn.turning and evaluator.spatial(turn) == {}
    assert len(evaluator.steps["right"]) == 1  # the turns' steps are not in the symmetry


def test_the_rest_of_the_swing_by_hand():
    """Two swings learn their rests (forward 0.3 m, left 0.1 m of the travel's direction); a third
    travelling 1.0 m along y gets 1.3 m forward and 0.1 m to its left: |(−0.1, 1.3)|."""
    from gait_biofeedback.core.spatial.provisional import RestOfSwing

    rest = RestOfSwing()
    assert rest.estimate(1, np.zeros(3), np.array([1.0, 0.0, 0.0])) is None  # nothing learnt yet
    rest.learn(1, np.array([1.3, 0.1, 0.0]))
    assert rest.estimate(2, np.array([1.3, 0.1, 0.0]), np.array([2.3, 0.1, 0.0])) is None  # one rest only
    rest.learn(99, np.array([9.0, 9.0, 0.0]))  # another swing's stride: not learnt
    rest.learn(2, np.array([2.6, 0.2, 0.0]))
    assert rest.estimate(3, np.zeros(3), np.array([0.0, 1.0, 0.0])) == pytest.approx(math.hypot(0.1, 1.3))
    assert rest.estimate(4, np.zeros(3), np.array([0.02, 0.0, 0.0])) is None  # 2 cm: no direction


def test_provisional_lengths_are_published_only_while_they_agree_with_the_smoothed_ones():
    """Differences 2, −3, 4 cm: RMS 3.1 cm ≤ 5 cm, trusted after three. A 12 cm miss makes it
    √(173/4) = 6.6 cm: withheld (counted), until five agreeing strides have pushed the miss out."""
    from gait_biofeedback.core.spatial.provisional import RestOfSwing

    rest = RestOfSwing(tolerance=0.05)
    for k, difference in enumerate((0.02, -0.03, 0.04)):
        assert rest.offer(k, 1.0 + difference) is None and rest.withheld == 0  # not yet checked
        rest.check(k, 1.0)
    assert rest.spread == pytest.approx(math.sqrt((4 + 9 + 16) / 3) / 100)
    assert rest.offer(3, 1.12) == 1.12
    rest.check(99, 1.0)  # another swing's stride: no check
    rest.check(3, math.nan)  # no smoothed length: no check
    assert rest.spread == pytest.approx(math.sqrt((4 + 9 + 16) / 3) / 100)
    rest.offer(3, 1.12)
    rest.check(3, 1.0)
    assert rest.spread == pytest.approx(math.sqrt((4 + 9 + 16 + 144) / 4) / 100)
    for k in range(4, 9):
        assert rest.offer(k, 1.0) is None
        rest.check(k, 1.0)
    assert rest.withheld == 5 and rest.spread == 0.0 and rest.offer(9, 1.0) == 1.0


def test_provisional_foot_height_and_angles_are_published_value_by_value_while_they_agree():
    """Heights 1, −1, 2 cm off their smoothed values (RMS 1.4 cm ≤ 2 cm): published from the fourth
    stride; the foot-strike angles 6° off (RMS 6° > 5°) stay NaN, the push-off angles (0°) are
    published, and so are the turning angles (3°, 4°, −3° off: RMS 3.4° ≤ 5°); the toe clearance, never
    smoothed (no lever arm), stays NaN. A 4 cm height miss: √((1 + 1 + 4 + 16) / 4) = 2.3 cm > 2 cm,
    withheld."""
    from gait_biofeedback.core.spatial.provisional import SwingAgreement

    agreement = SwingAgreement()
    deg = math.radians(1.0)
    smoothed = {"max_sensor_height": 0.10, "foot_angle_ic": 20 * deg, "foot_angle_tc": -60 * deg,
                "turning_angle": 30 * deg}

    def estimate(k: int, height_cm: float, turning_deg: float = 30.0) -> ProvisionalStride:
        return ProvisionalStride(k, 1.3, 0.10 + height_cm / 100, 26 * deg, -60 * deg, min_toe_clearance=0.02,
                                 turning_angle=turning_deg * deg)

    for k, (off, turning) in enumerate(((1.0, 33.0), (-1.0, 34.0), (2.0, 27.0))):
        out = agreement.offer(estimate(k, off, turning))
        assert out.stride_length == 1.3
        assert math.isnan(out.max_sensor_height) and math.isnan(out.foot_angle_tc)
        assert math.isnan(out.turning_angle) and math.isnan(out.min_toe_clearance)
        agreement.check(k, smoothed)
    out = agreement.offer(estimate(3, 4.0))
    assert out.max_sensor_height == pytest.approx(0.14) and out.foot_angle_tc == pytest.approx(-60 * deg)
    assert out.turning_angle == pytest.approx(30 * deg)
    assert math.isnan(out.foot_angle_ic) and math.isnan(out.min_toe_clearance)
    agreement.check(99, smoothed)  # another swing's stride: no check
    agreement.offer(estimate(3, 4.0))
    agreement.check(3, smoothed)
    assert math.isnan(agreement.offer(estimate(4, 0.0)).max_sensor_height)


def test_on_the_fast_real_walk_the_provisional_lengths_are_withheld(tmp_path):
    """qmt's 1.55 m/s walk at 100 Hz: the provisional stride lengths differ from the smoothed ones by
    about 10 cm RMS (``benchmarks/spatial.py --cli-only``), so almost none are published; ``analyze``
    says so per foot. The recording ends 0.2 s after a left IC: that stride, held for its smoothed
    values, still goes out (every IC after a foot's first closes a stride). Offline every stride has its
    smoothed values, so that is information (a note), not a warning."""
    from conftest import shared_data

    from gait_biofeedback.analyze import analyze_recording
    from gait_biofeedback.io.importers import import_qmt_fullbody
    from gait_biofeedback.io.imu_bag import write_imu_bag

    recording = import_qmt_fullbody(shared_data("qmt_fullbody", "full_body_example_data.mat"))
    write_imu_bag(tmp_path / "feet", {s: recording.imu[s] for s in ("left_foot", "right_foot")})
    result = analyze_recording(tmp_path / "feet", calibrate_at=[(75.0, "walking")])
    cycles = [m for topic, m, _ in result.messages if topic == "/gait/cycles"]
    assert len(cycles) >= 40
    assert sum(m.spatial_provisional for m in cycles) <= 2
    for side in (0, 1):
        contacts = [m for topic, m, _ in result.messages
                    if topic == "/gait/events" and m.side == side and m.type == m.INITIAL_CONTACT]
        assert len([m for m in cycles if m.side == side]) == len(contacts) - 1
    for side in ("left", "right"):
        assert any(n.startswith(f"{side} foot, live only: ") and "provisional stride lengths withheld" in n
                   for n in result.live_only), result.live_only
    assert not any("live only" in n for n in result.notes), result.notes
    assert not any("withheld" in w for w in result.warnings), result.warnings
