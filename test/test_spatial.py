"""Foot trajectory and spatial stride parameters (Suh 2014, issue 16): the zero-velocity detectors
(stream = batch, hand-made windows), Suh's smoother against the independent RTS pass, stride
length / speed / clearance / turning against the simulator's truth, the live stream against the
offline batch, bad input, and the real pyshoe_vicon trials."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.io as sio
from conftest import shared_data

from gait_biofeedback.batch import (
    SCENARIOS,
    FootTrajectoryParams,
    FootTrajectoryStream,
    estimate_foot_trajectory,
    quaternion,
    simulate,
)
from gait_biofeedback.core.calibration.windows import runs
from gait_biofeedback.core.gait.cycles import GaitCycle
from gait_biofeedback.core.gait.spatial import stride_space
from gait_biofeedback.core.params import ParameterError, from_mapping
from gait_biofeedback.core.spatial.kalman import (
    GRAVITY,
    FootKalman,
    KalmanNoise,
    filter_recording,
    shock_gain,
)
from gait_biofeedback.core.spatial.smoother import RTS_BLOCK, rts_smooth, suh_smooth
from gait_biofeedback.core.spatial.strides import LOST_FLAG, SpatialStride, unknown
from gait_biofeedback.core.spatial.zero_velocity import (
    GaitScale,
    StanceDetector,
    ZeroVelocityDetector,
    detect_zero_velocity,
    gait_scales,
)
from gait_biofeedback.sim.simulator import Phase, SimulationConfig


@pytest.fixture(scope="module")
def walk():
    return simulate(SCENARIOS["walk"](20.0, seed=2, segments=("left_foot",)))


def _still_then_moving(n=200):
    gyr = np.zeros((n, 3))
    acc = np.tile([0.0, 0.0, 9.81], (n, 1))
    gyr[100:150, 1] = 2.0  # the foot swings from sample 100 to 149
    return gyr, acc


@pytest.mark.parametrize("detector", ["suh", "shoe"])
def test_zero_velocity_windows_by_hand(detector):
    """window 0.05 s at 100 Hz: h = 2 samples each side, so the 2 samples next to the swing are
    moving too: stances 0-97 and 152-199 ([start, stop) runs)."""
    gyr, acc = _still_then_moving()
    zv = detect_zero_velocity(gyr, acc, 100.0, window_s=0.05, detector=detector)
    assert runs(zv) == [(0, 98), (152, 200)]


@pytest.mark.parametrize("detector", ["suh", "shoe"])
@pytest.mark.parametrize("rate_hz", [50.0, 100.0, 400.0])
def test_zero_velocity_stream_equals_batch(detector, rate_hz):
    rng = np.random.default_rng(1)
    n = 600
    gyr = rng.normal(0.0, 0.06, (n, 3))
    gyr[200:260] += 1.5
    acc = rng.normal(0.0, 0.05, (n, 3)) + np.array([0.0, 0.0, 9.81])
    acc[400:420] += 4.0
    stream = ZeroVelocityDetector(rate_hz, 0.4, 150.0, 0.05, detector)
    live = [d for g, a in zip(gyr, acc, strict=True) if (d := stream.update(g, a)) is not None]
    live += stream.flush()
    batch = detect_zero_velocity(gyr, acc, rate_hz, 0.4, 150.0, 0.05, detector)
    assert 0.1 < batch.mean() < 0.95
    np.testing.assert_array_equal(live, batch)


def test_gait_scale_by_hand():
    """100 Hz, updates every 50 samples from the past: 0.4 rad/s before the first gait; at sample 50
    the past 50 samples are 40 at |a| = g and 10 at g + 2 m/s², whose 90th percentile (linear,
    position 44.1 of 0-49) is 2 m/s², so 0.09 · 2 = 0.18 rad/s; at sample 100 the 10 are among 100
    (position 89.1 lies between the last 0 and the first 2: 0.2 m/s², no gait), so 0.18 holds; at
    150, 50 samples at g + 40 m/s² make A = 40 m/s², 3.6 rad/s, clipped to 3 rad/s."""
    acc = np.tile([0.0, 0.0, 9.81], (200, 1))
    acc[40:50, 2] += 2.0
    acc[100:150, 2] += 40.0
    scale = gait_scales(acc, 100.0, 0.09)
    np.testing.assert_allclose(scale[:50], 0.4)
    np.testing.assert_allclose(scale[50:150], 0.18)
    np.testing.assert_allclose(scale[150:], 3.0)
    np.testing.assert_allclose(gait_scales(np.tile([0.0, 0.0, 9.81], (120, 1)), 100.0, 0.09), 0.4)
    # over the moving samples only: 10 before sample 150 (under 0.5 s worth: the scale holds), then
    # 10 at 2 and 50 at 40 m/s² (90th percentile at position 53.1 of 0-59: 40 m/s²), clipped
    moving = np.abs(np.linalg.norm(acc, axis=1) - 9.81) > 0.0
    scale = gait_scales(acc, 100.0, 0.09, moving=moving)
    np.testing.assert_allclose(scale[:150], 0.4)
    np.testing.assert_allclose(scale[150:], 3.0)


def test_gait_scale_refuses_a_scale_that_is_not_positive():
    with pytest.raises(ValueError, match="adaptive_scale"):
        GaitScale(100.0, 0.0)
    with pytest.raises(ValueError, match="window_s"):
        GaitScale(100.0, 0.09, window_s=0.2)
    with pytest.raises(ParameterError, match="adaptive_scale"):
        estimate_foot_trajectory(np.zeros((10, 3)), np.zeros((10, 3)), 100.0, adaptive_scale=2.0)


def _gentle_gait(cycles=10):
    """100 Hz, 1 s cycles: still (samples 0-29 of a cycle), rolling at 0.2 rad/s (30-39), swing at
    2 rad/s with |a| = g + 2 m/s² (40-89), rolling (90-99)."""
    gyr = np.zeros((100 * cycles, 3))
    acc = np.tile([0.0, 0.0, 9.81], (100 * cycles, 1))
    for c in range(0, 100 * cycles, 100):
        gyr[c + 30:c + 40, 1] = gyr[c + 90:c + 100, 1] = 0.2
        gyr[c + 40:c + 90, 1] = 2.0
        acc[c + 40:c + 90, 2] += 2.0
    return gyr, acc


def test_the_gait_scaled_test_leaves_the_rolling_foot_out_of_the_stance():
    """The fixed rule (0.4 rad/s, 150 m/s³: 1.5 m/s² per sample, window ±2) takes the rolling as
    still: quiet 91-139 of each cycle pair (sample 90 has the 2 m/s² step), stance 93-137. After the
    first update (sample 50) the SHOE gyro scale is 0.09 · 2 = 0.18 rad/s and its window ±1 sample:
    three rolling samples (3 · 0.04 > 3 · 0.18²) fail, two pass, so the stance is 99-130 (by hand).
    The scale is learnt over the moving samples (40-90 of a cycle) once they are 0.5 s worth: from
    sample 100 on. Before (scale 0.4) the stances are the fixed rule's: 0-37 and 93-130. Stream =
    batch."""
    gyr, acc = _gentle_gait()
    fixed = detect_zero_velocity(gyr, acc, 100.0, 0.4, 150.0, 0.05)
    assert runs(fixed) == [(0, 38)] + [(93 + c, 138 + c) for c in range(0, 900, 100)] + [(993, 1000)]
    zv = detect_zero_velocity(gyr, acc, 100.0, 0.4, 150.0, 0.05, adaptive_scale=0.09)
    assert runs(zv) == [(0, 38), (93, 131)] + [(99 + c, 131 + c) for c in range(100, 900, 100)]
    stream = ZeroVelocityDetector(100.0, 0.4, 150.0, 0.05, adaptive_scale=0.09)
    live = [d for g, a in zip(gyr, acc, strict=True) if (d := stream.update(g, a)) is not None]
    np.testing.assert_array_equal(live + stream.flush(), zv)
    np.testing.assert_array_equal(_stance_stream(gyr, acc, 100.0, adaptive_scale=0.09, valley=True),
                                  detect_zero_velocity(gyr, acc, 100.0, adaptive_scale=0.09, valley=True))


@pytest.mark.parametrize("rate_hz", [50.0, 100.0, 400.0])
def test_gait_scaled_stream_equals_batch_on_noise(rate_hz):
    rng = np.random.default_rng(3)
    n = 1200
    gyr = rng.normal(0.0, 0.02, (n, 3))
    gyr[200:500] += 1.5
    gyr[700:800] += 0.2
    acc = rng.normal(0.0, 0.05, (n, 3)) + np.array([0.0, 0.0, 9.81])
    acc[200:500] += 3.0
    stream = ZeroVelocityDetector(rate_hz, 0.4, 150.0, 0.05, adaptive_scale=0.09)
    live = [d for g, a in zip(gyr, acc, strict=True) if (d := stream.update(g, a)) is not None]
    batch = detect_zero_velocity(gyr, acc, rate_hz, 0.4, 150.0, 0.05, adaptive_scale=0.09)
    assert 0.05 < batch.mean() < detect_zero_velocity(gyr, acc, rate_hz, 0.4, 150.0, 0.05).mean()
    np.testing.assert_array_equal(live + stream.flush(), batch)


def _running(dips=(200, 340, 480, 620, 760), n=900, still=()):
    """200 Hz: the foot always turning at 4 rad/s (running's swing) except short dips (the stance's
    stillest moment: 0.8, 0.5, 0.2, 0.5, 0.8 rad/s centred on each dip) and ``still`` ranges at rest."""
    gyr = np.tile([0.0, 4.0, 0.0], (n, 1))
    acc = np.tile([0.0, 0.0, 9.81], (n, 1))
    for d in dips:
        gyr[d - 2:d + 3, 1] = [0.8, 0.5, 0.2, 0.5, 0.8]
    for a, b in still:
        gyr[a:b] = 0.0
    return gyr, acc


def _stance_stream(gyr, acc, rate_hz, **options):
    detector = StanceDetector(rate_hz, **options)
    live = [d for g, a in zip(gyr, acc, strict=True) for d in detector.update(g, a)]
    return np.array(live + detector.flush())


def test_valley_rule_gives_each_running_cycle_one_stance():
    """No window of the fixed thresholds is quiet, so they find no stance; the valley rule takes the
    stillest sample of each cycle (the statistic over ±1 sample is smallest at the dip's centre) and
    one sample on each side (200 Hz). The stream decides the same samples as the batch."""
    gyr, acc = _running()
    assert not detect_zero_velocity(gyr, acc, 200.0).any()
    zv = detect_zero_velocity(gyr, acc, 200.0, valley=True)
    assert runs(zv) == [(d - 1, d + 2) for d in (200, 340, 480, 620, 760)]
    np.testing.assert_array_equal(_stance_stream(gyr, acc, 200.0, valley=True), zv)


def test_valley_rule_leaves_cycles_with_a_stance_alone():
    """A rest of 0.5 s (samples 540-639, in place of the fourth dip) 0.3 s after the third dip: the
    fixed rule finds it (its 0.05 s window: 545-634), so the third dip, within 0.45 s of it, is no
    stance; the first two and the last (0.6 s after it) are. Stream = batch. In a swing without a
    dip the stream decides each sample as soon as the fixed rule has (5 samples of look-ahead), not
    0.45 s later."""
    fixed_rule = {"gyro_limit": 0.4, "jerk_limit": 150.0, "window_s": 0.05}
    gyr, acc = _running(still=[(540, 640)])
    fixed = detect_zero_velocity(gyr, acc, 200.0, **fixed_rule)
    assert runs(fixed) == [(545, 635)]
    zv = detect_zero_velocity(gyr, acc, 200.0, **fixed_rule, valley=True)
    assert runs(zv) == [(199, 202), (339, 342), (545, 635), (759, 762)]
    np.testing.assert_array_equal(_stance_stream(gyr, acc, 200.0, **fixed_rule, valley=True), zv)
    detector = StanceDetector(200.0, **fixed_rule, valley=True)
    decided = [len(detector.update(g, a)) for g, a in zip(gyr[:120], acc[:120], strict=True)]
    assert sum(decided) == 120 - 5


def test_a_shock_inflates_the_accelerometer_noise():
    """R_a's factor: 1 up to acc_shock off gravity, then 1 + (excess / 2 m/s²)² (hand numbers)."""
    noise = KalmanNoise(acc_shock=30.0)
    assert shock_gain(np.array([0.0, 0.0, GRAVITY + 29.0]), noise) == 1.0
    assert shock_gain(np.array([0.0, GRAVITY + 34.0, 0.0]), noise) == pytest.approx(5.0)
    assert shock_gain(np.array([3.0, 0.0, 4.0]), noise) == pytest.approx(1.0)  # 4.8 below g: no shock
    assert shock_gain(np.array([0.0, 0.0, GRAVITY + 34.0]), KalmanNoise()) == 1.0  # off by default


def _shock_after_stance(stance_samples: int, noise: KalmanNoise) -> float:
    """Q_vv[0, 0] of the interval after a shock sample (34 m/s² over gravity, 100 Hz), in a swing
    that follows a stance of ``stance_samples`` samples (after a first stance and a 0.3 s swing)."""
    rest, shock = np.array([0.0, 0.0, GRAVITY]), np.array([0.0, 0.0, GRAVITY + 34.0])
    kf = FootKalman(noise)
    kf.start(rest, np.zeros(3), rest)
    labels = [True] * 9 + [False] * 30 + [True] * stance_samples + [False]
    for zero_velocity in labels:
        kf.update(np.zeros(3), rest, 0.01, zero_velocity)
    kf.update(np.zeros(3), shock, 0.01, False)  # the shock acts over the next interval
    kf.update(np.zeros(3), rest, 0.01, False)
    return float(kf.steps[-2].q_noise[6, 6])


def test_the_shock_noise_needs_a_stance_long_enough():
    """shock_stance_s (EXT, kalman.py): after a 30 ms stance (running) the shock leaves R_a as it is,
    Q_vv = R_a T = 1e-4 m²/s² to first order (hand number); after 100 ms it is 5 R_a T (gain
    1 + (4 / 2)²); with shock_stance_s 0 also after the short one."""
    noise = KalmanNoise(gyro=1e-12, acc=1e-2, acc_shock=30.0, shock_stance_s=0.05)
    short, long = _shock_after_stance(3, noise), _shock_after_stance(10, noise)
    assert short == pytest.approx(1e-4, rel=0.01)
    assert long == pytest.approx(5e-4, rel=0.01)
    always = KalmanNoise(gyro=1e-12, acc=1e-2, acc_shock=30.0, shock_stance_s=0.0)
    assert _shock_after_stance(3, always) == pytest.approx(5e-4, rel=0.01)


def test_suh_quadratic_program_equals_the_rts_pass(walk):
    """Two independent solutions of one estimation problem: Suh's banded normal equations (Eq 30,
    gait.md §4.5) and the RTS recursion over the 15 states must give the same trajectory."""
    imu = walk.imu["left_foot"]
    zv = detect_zero_velocity(imu.gyr, imu.acc, 100.0, 0.4, 150.0, 0.05)
    assert zv[0]  # the filter starts at sample 0
    kf = filter_recording(imu.gyr, imu.acc, 100.0, zv)
    assert len(kf.steps) > RTS_BLOCK  # the RTS pass crosses a block of stacked gains
    suh, rts = suh_smooth(kf.steps, kf.noise), rts_smooth(kf.steps)
    filtered = np.array([s.r for s in kf.steps])
    assert np.abs(suh["position"] - filtered).max() > 1e-3  # the smoothers do change the trajectory
    np.testing.assert_allclose(suh["position"], rts["position"], atol=1e-6)
    np.testing.assert_allclose(suh["bias"], rts["bias"], atol=1e-8)


def _true_stance(truth, stride, first=True):
    a, b = (stride["stance_start"], stride["foot_off"]) if first else (stride["foot_flat"], stride["end"])
    return truth[a:b + 1].mean(axis=0)


def test_strides_against_the_simulator_truth(walk):
    """Every stride but the first and last (the simulator's gait initiation and stop slide the flat
    foot, which no zero-velocity detector sees: benchmarks/spatial.py): length
    within 15 mm (7 mm worst measured: the default detector's wider thresholds, chosen on real
    shoes, take in the first and last millimetres of each stance roll; Suh's own thresholds give
    1 mm here), speed within 0.015 m/s, height within 1 cm (3 mm measured)."""
    imu, truth = walk.imu["left_foot"], walk.truth.sensor_position["left_foot"]
    result = estimate_foot_trajectory(imu.gyr, imu.acc, 100.0)
    strides = result["strides"][1:-1]
    assert len(strides) >= 12
    for s in strides:
        first, second = _true_stance(truth, s), _true_stance(truth, s, first=False)
        length = np.linalg.norm((second - first)[:2])
        assert s["stride_length"] == pytest.approx(length, abs=0.015)
        cycle = (s["foot_flat"] - s["stance_start"]) / 100.0
        assert s["gait_speed"] == pytest.approx(length / cycle, abs=0.015)
        height = truth[s["foot_off"]:s["foot_flat"] + 1, 2].max() - first[2]
        assert s["max_sensor_height"] == pytest.approx(height, abs=0.01)
        assert abs(s["turning_angle"]) < 0.02 and s["flags"] == ()
    assert result["position"].shape == (len(imu.t), 3)
    assert np.all(result["zero_velocity"][: 100])  # the walk starts with standing


def test_turning_angles_add_up_to_the_turn():
    cfg = SimulationConfig(seed=1, segments=("left_foot",), phases=[
        Phase("stand", 3.0), Phase("walk", 6.0), Phase("turn", 3.0, {"angle": math.pi / 2}),
        Phase("walk", 6.0), Phase("stand", 2.0)])
    imu = simulate(cfg).imu["left_foot"]
    strides = estimate_foot_trajectory(imu.gyr, imu.acc, 100.0)["strides"]
    assert sum(s["turning_angle"] for s in strides) == pytest.approx(math.pi / 2, abs=0.03)


def test_toe_clearance_with_a_lever_arm(walk):
    """The toe's position in the sensor frame, taken from the simulator's truth at one sample, gives
    the minimum toe clearance within 5 mm of the true toe's (same definition on the true trajectory;
    2.5 mm worst measured)."""
    cfg, truth = walk.config, walk.truth
    rf = quaternion.as_matrix(truth.segment_orientation["left_foot"])
    toe = truth.segment_position["left_foot"] + rf[:, :, 0] * cfg.toe_length - rf[:, :, 1] * cfg.ankle_height
    rs = quaternion.as_matrix(truth.sensor_orientation["left_foot"])
    lever = rs[0].T @ (toe[0] - truth.sensor_position["left_foot"][0])
    later = rs[500].T @ (toe[500] - truth.sensor_position["left_foot"][500])
    np.testing.assert_allclose(later, lever, atol=1e-9)
    imu = walk.imu["left_foot"]
    strides = estimate_foot_trajectory(imu.gyr, imu.acc, 100.0, toe_lever_arm_m=tuple(lever))["strides"][1:-1]
    checked = 0
    for s in strides:
        stance = toe[s["stance_start"]:s["foot_off"] + 1, 2].mean()
        swing = toe[s["foot_off"]:s["foot_flat"] + 1, 2] - stance
        high = np.flatnonzero(swing > 0.01)
        before, after = np.diff(swing, prepend=swing[0])[high], np.diff(swing, append=swing[-1])[high]
        rising = high[(before > 0) & (after <= 0)]
        if len(rising) < 2 or math.isnan(s["min_toe_clearance"]):
            continue
        true = swing[rising[0]:rising[-1] + 1].min()
        assert s["min_toe_clearance"] == pytest.approx(true, abs=0.005)
        checked += 1
    assert checked >= 8


def test_live_strides_agree_with_the_offline_ones(walk):
    """Live: RTS over each stride's window at 0.15 s latency; offline: Suh over the whole walk. The
    same strides (same foot-off and foot-flat samples), lengths within 1 cm. Live, a standing stance
    keeps only its last 3 s: the first stride starts there."""
    imu = walk.imu["left_foot"]
    result = estimate_foot_trajectory(imu.gyr, imu.acc, 100.0)
    live, offline = result["live_strides"], result["strides"]
    def identity(strides):
        return [(int(s["foot_off"]), int(s["foot_flat"])) for s in strides]

    assert identity(live) == identity(offline)
    assert offline[0]["stance_start"] == 0 and live[0]["stance_start"] == live[0]["foot_off"] + 1 - 300
    for a, b in zip(live[1:-1], offline[1:-1], strict=True):
        assert a["stride_length"] == pytest.approx(b["stride_length"], abs=0.01)
        assert a["end"] == a["foot_flat"] + 4  # closed after 0.05 s of the next stance


def test_bad_samples_are_skipped_and_a_gap_restarts_the_foot(walk):
    imu = walk.imu["left_foot"]
    stream = FootTrajectoryStream(100.0)
    strides = []
    for k in range(len(imu.t)):
        gyr = np.full(3, np.nan) if k in (700, 701) else imu.gyr[k]
        ns = k * 10_000_000 + (2_000_000_000 if k >= 1200 else 0)  # 2 s with no data at sample 1200
        strides += stream.update(ns, gyr, imu.acc[k])
    assert stream.counts["skipped"] == 2 and stream.counts["restarts"] == 1
    assert any("restarted" in n.text and "gap 2.01 s" in n.text for n in stream.notices.pop())
    assert len(strides) >= 12


def test_lost_samples_are_filled_and_a_stride_that_lost_too_many_has_no_values(walk):
    """Samples lost at 100 Hz (the simulator's walk, the detector's strides 720-831, 941-1053 and the
    stance 1165-1184): one in mid-swing is interpolated and the stride keeps its length (0.3 mm
    measured) with an informational flag; two in a swing give NaN (the next stride: 4.7 mm); a 60 ms
    gap in a stance gives NaN to the stride it is in and to the next; the others are unchanged within
    a few mm."""
    imu = walk.imu["left_foot"]

    def run(lost=frozenset()):
        stream, strides = FootTrajectoryStream(100.0), []
        for k in range(len(imu.t)):
            if k not in lost:
                strides += stream.update(k * 10_000_000, imu.gyr[k], imu.acc[k])
        return stream, {s.foot_flat_ns: s for s in strides}

    _, every = run()
    stream, strides = run({785, 995, 996, *range(1170, 1175)})
    assert stream.counts["interpolated"] == 8 and stream.counts["restarts"] == 0
    assert sorted(strides) == sorted(every)
    one = strides[8_310_000_000]
    assert one.flags == (LOST_FLAG,)
    assert one.stride_length == pytest.approx(every[8_310_000_000].stride_length, abs=0.001)
    assert math.isnan(strides[10_530_000_000].stride_length)
    assert strides[10_530_000_000].flags == ("20 ms of lost samples in the swing: spatial values unknown",)
    for flat_ns in (12_760_000_000, 13_870_000_000):
        assert math.isnan(strides[flat_ns].stride_length) and math.isnan(strides[flat_ns].foot_angle_ic)
        assert strides[flat_ns].flags == ("a 60 ms gap in the data: spatial values unknown",)
    # before the gap: unchanged; after it the filter (gyro_noise 1e-5: it trusts its gyro) takes strides
    # to forget the gap's attitude and bias disturbance: 1.4 mm measured, 1.0 mm eight strides later
    unchanged_mm = {7_200_000_000: 0.1, 9_420_000_000: 0.1, 11_650_000_000: 10, 14_980_000_000: 3,
                    22_920_000_000: 3}
    for flat_ns, mm in unchanged_mm.items():
        assert strides[flat_ns].flags == every[flat_ns].flags
        assert strides[flat_ns].stride_length == pytest.approx(every[flat_ns].stride_length, abs=mm / 1000)


def test_an_interpolated_stride_keeps_its_values_through_the_gait_events():
    cycle = GaitCycle(side="left", index=1, start_ns=0, end_ns=1_000_000_000,
                      terminal_contact_ns=600_000_000, stride_time=1.0, stance_time=0.6, swing_time=0.4,
                      stance_fraction=0.6, swing_fraction=0.4, step_time=0.5, cadence=2.0,
                      double_support_time=0.2, double_support_fraction=0.2, step_time_symmetry_index=0.0,
                      plausible=True)
    stride = SpatialStride(stance_start=0, foot_off=60, foot_flat=100, end=105, stride_length=1.3,
                           stride_time=1.0, gait_speed=1.3, max_sensor_height=0.12,
                           min_toe_clearance=math.nan, foot_angle_ic=0.3, foot_angle_tc=-0.5,
                           turning_angle=0.0, lateral_excursion=0.01, flags=(LOST_FLAG,))
    assert stride_space(cycle, stride).stride_length == 1.3 and stride_space(cycle, stride).flag == ""
    lost = unknown(stride, "20 ms of lost samples in the swing: spatial values unknown")
    assert math.isnan(lost.foot_angle_tc) and lost.foot_off == 60
    assert math.isnan(stride_space(cycle, lost).stride_length)
    assert stride_space(cycle, lost).flag == "20 ms of lost samples in the swing: spatial values unknown"


def test_a_long_swing_gives_no_numbers():
    """3 s without a stance (the foot kept turning) between two standings: the stride is flagged and
    its values are NaN, never seconds of drift."""
    n = 800
    gyr = np.zeros((n, 3))
    acc = np.tile([0.0, 0.0, 9.81], (n, 1))
    gyr[200:500, 0] = 1.0
    result = estimate_foot_trajectory(gyr, acc, 100.0)
    (stride,) = result["live_strides"]
    assert math.isnan(stride["stride_length"]) and "no stance for 3.0 s" in stride["flags"][-1]
    assert math.isnan(result["strides"][0]["gait_speed"])


def test_parameters_are_checked():
    with pytest.raises(ParameterError, match="toe_lever_arm_m"):
        FootTrajectoryParams(toe_lever_arm_m=(0.1, 0.0))
    with pytest.raises(ParameterError, match="gyro_limt"):
        from_mapping(FootTrajectoryParams, {"gyro_limt": 0.3})
    with pytest.raises(ValueError, match="detector"):
        ZeroVelocityDetector(100.0, detector="magic")
    with pytest.raises(ParameterError, match="gyro_limt"):
        estimate_foot_trajectory(np.zeros((10, 3)), np.zeros((10, 3)), 100.0, gyro_limt=0.3)
    with pytest.raises(ParameterError, match="window_s"):
        estimate_foot_trajectory(np.zeros((10, 3)), np.zeros((10, 3)), 100.0, window_s=5.0)


def _pyshoe_score(estimate, vicon):
    """The authors' ARMSE (their x-y frame is left-handed: y mirrored), aligned where the estimate is
    first 0.8 m from its start."""
    e = (estimate - estimate[0])[:, :2] * [1.0, -1.0]
    v = (vicon - vicon[0])[:, :2]
    k = int(np.argmax(np.hypot(e[:, 0], e[:, 1]) >= 0.8))
    turn = np.exp(1j * (np.angle(v[k, 0] + 1j * v[k, 1]) - np.angle(e[k, 0] + 1j * e[k, 1])))
    d = (e[:, 0] + 1j * e[:, 1]) * turn - (v[:, 0] + 1j * v[:, 1])
    return float(np.mean(np.abs(d) / np.sqrt(2.0)))


@pytest.mark.realdata
def test_pyshoe_walking_trials():
    """Real shoe IMU with Vicon (the authors' ARMSE, benchmarks/spatial.py): the first four trials
    measured 0.035, 0.039, 0.055, 0.025 m; each within 1.6x of that, and within 3x of the
    dataset's per-trial oracle detector."""
    folder = shared_data("pyshoe_vicon")
    for path, measured in zip(sorted(folder.glob("*.mat"))[:4], (0.035, 0.039, 0.055, 0.025), strict=True):
        d = sio.loadmat(path, squeeze_me=True)
        p = estimate_foot_trajectory(d["imu"][:, 3:6], d["imu"][:, :3], 200.0)["position"]
        ok = np.isfinite(p[:, 0])
        score = _pyshoe_score(p[ok], d["gt"][ok])
        assert score <= 1.6 * measured and score <= 3 * float(d["best_error"]), (path.stem, score)


@pytest.mark.realdata
def test_pyshoe_running_trial_needs_the_valley_rule():
    """A running trial (stances of 10-70 ms): the fixed thresholds miss most stances (3.8 m ARMSE
    measured); with the valley rule 0.117 m measured (the oracle: 0.064)."""
    path = shared_data("pyshoe_vicon", "2017-11-27-11-11-53.mat")
    d = sio.loadmat(path, squeeze_me=True)
    scores = {}
    for valley in (True, False):
        p = estimate_foot_trajectory(d["imu"][:, 3:6], d["imu"][:, :3], 200.0, valley=valley)["position"]
        ok = np.isfinite(p[:, 0])
        scores[valley] = _pyshoe_score(p[ok], d["gt"][ok])
    assert scores[True] <= 0.2 and scores[False] >= 1.0, scores


@pytest.mark.realdata
def test_pyshoe_slow_steps_need_the_gait_scaled_test():
    """2018-02-09-11-19-39, slow steps whose feet roll at 0.1-0.2 rad/s: the fixed rule alone
    (adaptive_scale 0) measured 0.381 m ARMSE, with the gait-scaled test (the default) 0.11 m (the
    IMU-only oracle: 0.033)."""
    path = shared_data("pyshoe_vicon", "2018-02-09-11-19-39.mat")
    d = sio.loadmat(path, squeeze_me=True)
    scores = {}
    for adaptive_scale in (FootTrajectoryParams().adaptive_scale, 0.0):
        p = estimate_foot_trajectory(d["imu"][:, 3:6], d["imu"][:, :3], 200.0,
                                     adaptive_scale=adaptive_scale)["position"]
        ok = np.isfinite(p[:, 0])
        scores[adaptive_scale] = _pyshoe_score(p[ok], d["gt"][ok])
    assert scores[FootTrajectoryParams().adaptive_scale] <= 0.25 and scores[0.0] >= 0.3, scores


@pytest.mark.realdata
def test_pyshoe_running_trial_without_shock_noise_after_short_stances():
    """shock_stance_s: the running trial 2017-11-27-11-11-53 measured 0.033 m ARMSE with the default
    (0.05 s), 0.118 m with the shock noise in every swing (shock_stance_s 0)."""
    path = shared_data("pyshoe_vicon", "2017-11-27-11-11-53.mat")
    d = sio.loadmat(path, squeeze_me=True)
    scores = {}
    for shock_stance_s in (0.05, 0.0):
        p = estimate_foot_trajectory(d["imu"][:, 3:6], d["imu"][:, :3], 200.0,
                                     shock_stance_s=shock_stance_s)["position"]
        ok = np.isfinite(p[:, 0])
        scores[shock_stance_s] = _pyshoe_score(p[ok], d["gt"][ok])
    assert scores[0.05] <= 0.066 and scores[0.0] >= 0.08, scores


@pytest.mark.realdata
def test_gaitmap_example_stride_lengths_against_the_heel_marker():
    """The 56 mocap strides that match one of ours (benchmarks/spatial.py): the heel marker's horizontal
    displacement between the reference stride's start and end (mid-stances, IMU samples at 204.8 Hz,
    markers at 100 Hz). Measured: mean +0.1 cm, mean |error| 1.3 cm, SD 1.7 cm; without the shock noise
    4.0 and 4.5 cm."""
    import csv

    from gait_biofeedback.io.importers import import_gaitmap

    folder = shared_data("gaitmap_example")
    rec = import_gaitmap(folder)
    with (folder / "mocap_sample.csv").open() as handle:
        rows = list(csv.reader(handle))
    columns = [f"{m}_{a}" for m, a in zip(rows[0][1:], rows[1][1:], strict=True)]
    markers = np.array([[float(x) for x in r[1:]] for r in rows[2:]]) / 1000.0
    with (folder / "stride_events_sample.csv").open() as handle:
        reference = list(csv.DictReader(handle))
    errors = []
    for side in ("left", "right"):
        imu = rec.imu[f"{side}_foot"]
        strides = estimate_foot_trajectory(imu.gyr, imu.acc, 204.8)["strides"]
        heel = markers[:, [columns.index(f"{side[0].upper()}_FCC_{a}") for a in "xy"]]
        for r in (r for r in reference if r["foot"] == side):
            start, end, ic = (float(r[k]) for k in ("start", "end", "ic"))
            ours = [x for x in strides if x["stance_start"] <= start + 20 and x["foot_off"] >= start - 20
                    and ic - 40 <= x["foot_flat"] <= end + 40]
            if len(ours) == 1:
                true = np.linalg.norm(heel[round(end * 100 / 204.8)] - heel[round(start * 100 / 204.8)])
                errors.append(ours[0]["stride_length"] - true)
    e = np.array(errors)
    assert len(e) >= 55
    assert abs(e.mean()) <= 0.01 and np.abs(e).mean() <= 0.02 and e.std() <= 0.03, (e.mean(), e.std())


def test_standing_keeps_a_bounded_window():
    """40 s of standing: the live window stays at the last 3 s (300 samples), not 4000."""
    stream = FootTrajectoryStream(100.0)
    for k in range(4000):
        stream.update(k * 10_000_000, np.zeros(3), np.array([0.0, 0.0, 9.81]))
    assert len(stream._steps) == 300


def test_the_gait_events_node_declares_the_adaptive_zero_velocity_check():
    """The live node (GaitEventsParams) hands adaptive_scale / adaptive_window_s to the foot-trajectory
    stage: 0 switches the check off live as offline."""
    from gait_biofeedback.core.gait.stream import GaitEventsParams
    from gait_biofeedback.core.spatial.stream import FootTrajectoryParams

    assert GaitEventsParams().foot_trajectory.adaptive_scale == FootTrajectoryParams().adaptive_scale > 0
    off = GaitEventsParams(adaptive_scale=0.0, adaptive_window_s=20.0).foot_trajectory
    assert (off.adaptive_scale, off.adaptive_window_s) == (0.0, 20.0)
