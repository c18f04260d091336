"""Orientation filters on synthetic data with exact ground truth (no simulator dependency)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import shared_data

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.orientation.filters import (
    ALGORITHMS,
    DEFAULT_ALGORITHM,
    attitude_from_vectors,
    calibrate_from_rest,
    estimate_orientation,
    quiet_samples,
)
from gait_biofeedback.core.orientation.filters import _full_state as fs
from gait_biofeedback.core.orientation.filters import _inertial_kernel as ik
from gait_biofeedback.core.orientation.filters.config import filter_params
from gait_biofeedback.core.orientation.filters.inertial_cf import InertialCF
from gait_biofeedback.core.orientation.filters.nazarahari_rekf import NazarahariREKF

RATE = 100.0
G_WORLD = np.array([0.0, 0.0, 9.81])
M_WORLD = np.array([0.0, 20e-6, -40e-6])  # tesla, north = +y, dip downwards
ALL = sorted(ALGORITHMS)
LKF_WEAK = pytest.mark.xfail(
    strict=True, reason="nazarahari_lkf: slow/unstable bias coupling (known weakness)"
)
WITH_ONLINE_BIAS = {
    "inertial_cf": {},  # rest detection: the low-passed gyro at rest is the bias
    "madgwick": {"zeta": 0.02},
    "mahony": {"ki": 0.05},
    "nazarahari_rekf": {"sigma_bw": 1e-3, "p0_bias": 1e-4},
    "nazarahari_lkf": {"sigma_bw": 1e-3, "p0_bias": 1e-4},
    "roetenberg_ikf": {"gyro_drift_noise": 1e-8},
}
GATING = {"mag_reject_norm": 0.05, "mag_reject_dip": math.radians(3.0)}
# about twice what each filter reaches (deg; measured: guo_fkf 0.044, inertial_cf 0.24, madgwick 0.71,
# mahony 0.58, nazarahari_lkf 0.33, nazarahari_rekf 0.45, roetenberg_ikf 0.30, yi_cf 0.061,
# zihajehzadeh_ckf 0.34 RMS)
ROTATING_RMS_DEG = {"guo_fkf": 0.09, "roetenberg_ikf": 0.6, "inertial_cf": 0.5,
                    "madgwick": 1.4, "mahony": 1.2, "nazarahari_lkf": 0.7,
                    "nazarahari_rekf": 0.9, "yi_cf": 0.15, "zihajehzadeh_ckf": 0.7}
# max heading error during / after a 10 s magnet (deg; measured guo_fkf 0.074 / 0.081, roetenberg_ikf
# 0.15 / 0.14, inertial_cf 0.14 / 0.14, madgwick
# 0.53 / 0.80, mahony 0.077 / 0.48, nazarahari_lkf 0.11 / 0.71, nazarahari_rekf 0.22 / 0.21, yi_cf
# 0.10 / 0.064, zihajehzadeh_ckf 0.77 / 0.76)
DISTURBED_HEADING_DEG = {"guo_fkf": (0.15, 0.16), "roetenberg_ikf": (0.3, 0.28), "inertial_cf": (0.3, 0.3),
                         "madgwick": (1.1, 1.6), "mahony": (0.15, 1.0),
                         "nazarahari_lkf": (0.22, 1.4), "nazarahari_rekf": (0.44, 0.43), "yi_cf": (0.2, 0.13),
                         "zihajehzadeh_ckf": (1.5, 1.5)}


def synth(seconds: float, rotating: bool, bias=(0.0, 0.0, 0.0), seed: int = 0, q0=None, noise: float = 1.0):
    """Exact gyro (+bias, noise), acc = Rᵀg, mag = Rᵀm (noise) and the true orientation."""
    rng = np.random.default_rng(seed)
    n = int(seconds * RATE)
    t = np.arange(n) / RATE
    if rotating:
        w = np.stack([1.0 * np.sin(0.5 * t), 0.8 * np.sin(0.7 * t + 1.0), 1.2 * np.sin(0.3 * t + 2.0)], 1)
    else:
        w = np.zeros((n, 3))
    q = np.empty((n, 4))
    q[0] = quat.from_euler_zyx(0.7, 0.2, -0.3) if q0 is None else q0
    for k in range(1, n):
        q[k] = quat.integrate_gyro(q[k - 1], w[k], 1.0 / RATE)
    gyr = w + np.asarray(bias) + noise * rng.normal(0.0, 0.005, (n, 3))
    acc = quat.rotate_inverse(q, G_WORLD) + noise * rng.normal(0.0, 0.02, (n, 3))
    mag = quat.rotate_inverse(q, M_WORLD) + noise * rng.normal(0.0, 0.05e-6, (n, 3))
    return gyr, acc, mag, q


def heading_inclination(q_est, q_true):
    e = quat.canonical(quat.multiply(q_est, quat.conjugate(q_true)))
    head = np.abs((2.0 * np.arctan2(e[..., 3], e[..., 0]) + np.pi) % (2 * np.pi) - np.pi)
    incl = 2.0 * np.arccos(np.clip(np.hypot(e[..., 0], e[..., 3]), 0.0, 1.0))
    return np.degrees(head), np.degrees(incl)


def run(name, gyr, acc, mag, **params):
    """The algorithm with its class defaults (the thresholds here were measured with them; the gains
    tuned on BROAD are for real sensors, see test_batch_runs_the_nodes_gains)."""
    return estimate_orientation(gyr, acc, mag, RATE, name, tuned=False, **params)


@pytest.mark.parametrize(
    "name", [pytest.param(n, marks=LKF_WEAK) if n == "nazarahari_lkf" else n for n in ALL]
)
def test_static_converges_from_wrong_start(name):
    gyr, acc, mag, q = synth(60.0, rotating=False)
    f = ALGORITHMS[name](RATE)
    f.initialize(acc[0], mag[0])  # sets the reference norms and the world field
    f.reset(quat.from_euler_zyx(0.2, 0.15, -0.1))  # ~40° away from the truth
    for k in range(len(gyr)):
        out = f.update(gyr[k], acc[k], mag[k])
    # from ~40° off; the full-state EKF/LKF converge slowly from large errors (small P₀, known weakness)
    assert np.degrees(quat.angle_between(out, q[-1])) < (5.0 if name.startswith("nazarahari") else 2.0)


@pytest.mark.parametrize("name", ALL)
def test_static_at_any_attitude_stays_put(name):
    """Initialised from the vectors at arbitrary attitudes (large yaw, pitch and roll, as sensors are
    strapped on a leg), a still sensor must not drift away. Caught a sign slip in inertial_cf's
    world-frame inclination correction that showed only when the attitude had a large yaw part."""
    rng = np.random.default_rng(7)
    for q0 in quat.normalize(rng.normal(size=(6, 4))):
        gyr, acc, mag, q = synth(5.0, rotating=False, q0=q0)
        est = run(name, gyr, acc, mag)
        err = np.degrees(quat.angle_between(est, q))
        assert err.max() < 2.0, f"{name}: {err.max():.1f} deg from q0={np.round(q0, 2)}"


@pytest.mark.parametrize("name", ALL)
def test_rotating_tracks_truth(name):
    gyr, acc, mag, q = synth(30.0, rotating=True)
    est = run(name, gyr, acc, mag)
    err = np.degrees(quat.angle_between(est, q))
    assert err[0] < 1.5  # initial attitude from the vectors (TRIAD)
    rms = np.sqrt(np.mean(err**2))
    assert rms < ROTATING_RMS_DEG[name], f"{name}: {rms:.3f} deg RMS"


@pytest.mark.parametrize("name", ALL)
def test_six_d_mode_keeps_inclination(name):
    gyr, acc, _, q = synth(30.0, rotating=True)
    est = run(name, gyr, acc, None)
    _, incl = heading_inclination(est, q)
    assert np.sqrt(np.mean(incl**2)) < 2.0


@pytest.mark.parametrize(
    "name",
    [pytest.param(n, marks=LKF_WEAK) if n == "nazarahari_lkf" else n for n in sorted(WITH_ONLINE_BIAS)],
)
def test_online_gyro_bias_recovered(name):
    bias = np.array([0.02, -0.015, 0.01])
    gyr, acc, mag, q = synth(60.0, rotating=False, bias=bias, seed=1)
    f = ALGORITHMS[name](RATE, **WITH_ONLINE_BIAS[name])
    for k in range(len(gyr)):
        out = f.update(gyr[k], acc[k], mag[k])
    est_bias = f.state()["gyro_bias"]
    assert np.abs(est_bias - bias).max() < 0.004, est_bias
    assert np.degrees(quat.angle_between(out, q[-1])) < 2.0


def test_startup_step_recovers_static_bias_norms_and_attitude():
    bias = np.array([0.02, -0.015, 0.01])
    gyr, acc, mag, q = synth(5.0, rotating=False, bias=bias, seed=2)
    cal = calibrate_from_rest(gyr, acc, mag)
    assert np.abs(cal.gyro_bias - bias).max() < 1e-3
    assert cal.acc_norm == pytest.approx(9.81, rel=1e-3)
    assert cal.mag_norm == pytest.approx(np.linalg.norm(M_WORLD), rel=1e-3)
    assert np.degrees(quat.angle_between(cal.q0, q[0])) < 0.5
    # without a magnetometer: same tilt, yaw 0
    cal6 = calibrate_from_rest(gyr, acc)
    yaw, pitch, roll = quat.to_euler_zyx(cal6.q0)
    assert yaw == pytest.approx(0.0, abs=1e-9)
    assert (pitch, roll) == pytest.approx((0.2, -0.3), abs=5e-3)
    with pytest.raises(ValueError):
        calibrate_from_rest(np.full((3, 3), np.nan), acc[:3])


@pytest.mark.parametrize("name", ["yi_cf", "zihajehzadeh_ckf"])
def test_bias_free_filters_use_startup_bias(name):
    bias = np.array([0.03, -0.02, 0.02])
    gyr, acc, mag, q = synth(40.0, rotating=True, bias=bias, seed=3)
    rest = np.tile(gyr[:1] * 0 + bias, (300, 1)) + np.random.default_rng(4).normal(0, 0.005, (300, 3))
    g = np.vstack([rest, gyr])
    a = np.vstack([np.tile(acc[0], (300, 1)), acc])
    m = np.vstack([np.tile(mag[0], (300, 1)), mag])
    est = estimate_orientation(g, a, m, RATE, name, startup_s=3.0)[300:]
    assert np.sqrt(np.mean(np.degrees(quat.angle_between(est, q)) ** 2)) < 3.0


def test_quiet_samples_finds_motion_onset():
    gyr, acc, _, _ = synth(10.0, rotating=False)
    gyr[400:] += 1.0
    assert quiet_samples(gyr, acc, RATE, max_s=10.0) == 400
    assert quiet_samples(gyr, acc, RATE, max_s=2.0) == 200
    # a real sensor's static bias (issue 15: 5 °/s) is not motion: judged about the window's median
    biased = gyr + np.radians([3.0, -3.0, 2.0])  # 4.7 °/s
    assert quiet_samples(biased, acc, RATE, max_s=10.0) == 400
    # a rate over MAX_STARTUP_BIAS (8.6 °/s) is a sensor turning, not a bias
    turning = gyr + np.radians([0.0, 0.0, 10.0])
    assert quiet_samples(turning, acc, RATE, max_s=10.0) == 0


def test_attitude_from_vectors_matches_truth_batch():
    q = quat.from_euler_zyx(
        np.array([0.0, 1.0, -2.5]), np.array([0.1, -0.4, 1.2]), np.array([0.3, 2.0, -1.0])
    )
    est = attitude_from_vectors(quat.rotate_inverse(q, G_WORLD), quat.rotate_inverse(q, M_WORLD))
    assert np.degrees(quat.angle_between(est, q)).max() < 1e-6


@pytest.mark.parametrize("name", ALL)
def test_magnetic_disturbance_rejected(name):
    gyr, acc, mag, q = synth(30.0, rotating=True, seed=5)
    disturbed = mag.copy()
    sl = slice(500, 1500)  # 10 s next to a magnet fixed in the world: 60 % of the field, sideways
    disturbed[sl] += quat.rotate_inverse(q[sl], np.array([0.6 * 44.7e-6, 0.0, 0.0]))
    est = run(name, gyr, acc, disturbed, **GATING)
    head, _ = heading_inclination(est, q)
    during, after = DISTURBED_HEADING_DEG[name]
    assert head[sl].max() < during, f"{name}: {head[sl].max():.3f} deg while disturbed"
    assert head[1500:].max() < after, f"{name}: {head[1500:].max():.3f} deg after"


@pytest.mark.parametrize("name", ALL)
def test_batch_equals_streaming(name):
    gyr, acc, mag, _ = synth(5.0, rotating=True, seed=6)
    batch = run(name, gyr, acc, mag)
    f = ALGORITHMS[name](RATE)
    stream = np.array([f.update(gyr[k], acc[k], mag[k]) for k in range(len(gyr))])
    np.testing.assert_array_equal(batch, stream)


@pytest.mark.parametrize("name", ALL)
def test_nan_sample_keeps_last_good_state(name):
    gyr, acc, mag, _ = synth(3.0, rotating=True, seed=7)
    ref = ALGORITHMS[name](RATE)
    f = ALGORITHMS[name](RATE)
    for k in range(len(gyr)):
        expected = ref.update(gyr[k], acc[k], mag[k])
        if k == 150:
            held = f.update([np.nan, 0.0, 0.0], acc[k], mag[k])
            np.testing.assert_array_equal(held, f.q)
            f.update(gyr[k], [0.0, np.inf, 1.0], mag[k])
        got = f.update(gyr[k], acc[k], mag[k])
        np.testing.assert_array_equal(got, expected)
    assert f.state()["skipped_samples"] == 2


def test_nan_before_first_valid_sample_gives_nan_rows():
    gyr, acc, mag, _ = synth(1.0, rotating=False)
    acc[:10] = np.nan
    est = estimate_orientation(gyr, acc, mag, RATE, DEFAULT_ALGORITHM)
    assert np.isnan(est[:10]).all() and np.isfinite(est[10:]).all()


def test_bad_inputs_raise():
    with pytest.raises(ValueError):
        ALGORITHMS[DEFAULT_ALGORITHM](0.0)
    with pytest.raises(TypeError):
        ALGORITHMS["madgwick"](RATE, not_a_parameter=1.0)
    with pytest.raises(ValueError):
        estimate_orientation(np.zeros((5, 3)), np.zeros((5, 3)), None, RATE, "no_such_filter")
    with pytest.raises(ValueError):
        estimate_orientation(np.zeros((5, 3)), np.zeros((4, 3)), None, RATE)


def test_state_reports_disturbance_and_rest():
    gyr, acc, mag, _ = synth(2.0, rotating=False)
    f = ALGORITHMS["mahony"](RATE, **GATING)
    for k in range(100):
        f.update(gyr[k], acc[k], mag[k])
    assert f.state()["rest"] and not f.state()["mag_disturbed"]
    f.update(gyr[100], acc[100], mag[100] * 1.5)
    assert f.state()["mag_disturbed"]


def _num_jac(fun, x, eps=1e-7):
    return np.stack([(fun(x + eps * e) - fun(x - eps * e)) / (2 * eps) for e in np.eye(len(x))], 1)


def test_full_state_jacobians_match_finite_differences():
    q = quat.normalize(np.array([0.8, 0.1, -0.3, 0.5]))
    m = np.array([0.2, 0.4, -0.9])
    np.testing.assert_allclose(fs.jacobian_acc(q), _num_jac(fs.predicted_acc, q), atol=1e-6)
    np.testing.assert_allclose(
        fs.jacobian_mag(q, m), _num_jac(lambda v: fs.predicted_mag(v, m), q), atol=1e-6
    )
    w, ts = np.array([1.0, -2.0, 0.5]), 0.01
    _, dq_db = fs.transition(q, w, ts)
    np.testing.assert_allclose(
        dq_db, _num_jac(lambda b: fs.transition(q, w - b, ts)[0] @ q, np.zeros(3)), atol=1e-9
    )


def test_robust_covariance_tends_to_ekf_for_large_gamma():
    rng = np.random.default_rng(8)
    a = rng.normal(size=(13, 13))
    P = a @ a.T * 1e-3 + np.eye(13) * 1e-4
    H = rng.normal(size=(6, 13))
    r = np.full(6, 0.01)
    ekf = P - P @ H.T @ np.linalg.solve(H @ P @ H.T + np.diag(r), H @ P)
    robust = NazarahariREKF._robust_covariance(P, H, r, 1e6)
    np.testing.assert_allclose(robust, ekf, atol=1e-12)
    # finite γ inflates the posterior covariance (worst-case bound)
    assert np.trace(NazarahariREKF._robust_covariance(P, H, r, 0.5)) > np.trace(ekf)


def test_yi_cf_literal_stability_rule_follows_fqa():
    gyr, acc, mag, q = synth(10.0, rotating=True, seed=9, noise=0.0)
    est = run("yi_cf", gyr, acc, mag, propagate_from="fqa", A=0.0, B=1.0)
    assert np.degrees(quat.angle_between(est, q)).max() < 0.5  # k = 1: pure FQA, exact without noise


@pytest.mark.realdata
def test_default_algorithm_accuracy_floor_on_broad():
    path = shared_data("broad", "05_undisturbed_slow_rotation_with_breaks_B.mat")
    import scipy.io

    d = scipy.io.loadmat(path, squeeze_me=True)
    est = estimate_orientation(
        d["imu_gyr"], d["imu_acc"], d["imu_mag"], float(d["sampling_rate"]), startup_s=5.0
    )
    ok = d["movement"].astype(bool) & np.isfinite(d["opt_quat"]).all(1)
    err = np.degrees(quat.angle_between(est[ok], d["opt_quat"][ok]))
    rms = np.sqrt(np.mean(err**2))
    assert rms < 2.0, f"{rms:.2f} deg RMS"  # measured 0.98


# ------------------------------------------------------------------ inertial_cf (the default)
def test_default_is_inertial_cf():
    assert DEFAULT_ALGORITHM == "inertial_cf"


def shipped_inertial_cf(**params) -> InertialCF:
    """InertialCF with the shipped tuned values (as the node and the batch functions run it)."""
    return InertialCF(RATE, **filter_params("inertial_cf", params=params))


def test_inertial_cf_numba_and_python_give_the_same_numbers():
    pytest.importorskip("numba")
    gyr, acc, mag, _ = synth(20.0, rotating=True, seed=11)
    disturbed = mag.copy()
    disturbed[600:1200] *= 1.4  # exercise the rejection branch too
    fast = run("inertial_cf", gyr, acc, disturbed)
    slow = run("inertial_cf", gyr, acc, disturbed, use_numba=False)
    assert InertialCF(RATE).numba and not InertialCF(RATE, use_numba=False).numba
    np.testing.assert_allclose(fast, slow, rtol=0.0, atol=1e-12)


def test_inertial_cf_update_tuple_matches_update():
    gyr, acc, mag, _ = synth(3.0, rotating=True, seed=12)
    a, b = InertialCF(RATE), InertialCF(RATE)
    for k in range(len(gyr)):
        qa = a.update(gyr[k], acc[k], mag[k])
        qb = b.update_tuple(tuple(gyr[k]), tuple(acc[k]), tuple(mag[k]))
        assert isinstance(qb, tuple) and len(qb) == 4
        np.testing.assert_array_equal(qa, np.array(qb, dtype=float))
    np.testing.assert_array_equal(a.gyro_bias(), a.state()["gyro_bias"])


def test_inertial_cf_bias_learned_at_rest_then_used_in_motion():
    bias = np.array([0.01, -0.02, 0.015])
    still, acc_s, _, q_s = synth(10.0, rotating=False, bias=bias, seed=13)
    gyr, acc, _, q = synth(30.0, rotating=True, bias=bias, seed=14, q0=q_s[-1])
    f = shipped_inertial_cf()  # no start-up step: the bias is found by rest detection alone
    for k in range(len(still)):
        f.update(still[k], acc_s[k], None)
    assert f.state()["rest"]
    np.testing.assert_allclose(f.gyro_bias(), bias, atol=1.5e-3)
    est = np.array([f.update(gyr[k], acc[k], None) for k in range(len(gyr))])  # 6D: gyro heading
    e = quat.canonical(quat.multiply(est, quat.conjugate(q)))
    head = np.degrees(2.0 * np.arctan2(e[:, 3], e[:, 0]))
    assert np.abs(head - head[0]).max() < 1.5  # 30 s with 0.027 rad/s uncorrected would be ~46°
    assert not f.state()["rest"]


def test_inertial_cf_accelerometer_averaged_in_inertial_frame():
    """A 2 Hz, 3 m/s² sideways shake barely tilts the estimate (low-pass in the inertial frame)."""
    gyr, acc, mag, q = synth(20.0, rotating=True, seed=15, noise=0.0)
    t = np.arange(len(gyr)) / RATE
    shake_world = np.stack([3.0 * np.sin(2 * np.pi * 2.0 * t), np.zeros_like(t), np.zeros_like(t)], 1)
    acc_shaken = acc + quat.rotate_inverse(q, shake_world)
    _, incl = heading_inclination(estimate_orientation(gyr, acc_shaken, mag, RATE, "inertial_cf"), q)
    _, incl_madgwick = heading_inclination(run("madgwick", gyr, acc_shaken, mag), q)
    assert incl.max() < 0.5
    assert incl.max() < incl_madgwick.max()


def test_inertial_cf_magnet_never_tilts_and_new_field_becomes_reference():
    gyr, acc, mag, q = synth(60.0, rotating=False, seed=16)
    extra = np.array([15e-6, 0.0, 10e-6])
    mag[1000:] += quat.rotate_inverse(q[1000:], extra)  # a new constant world field from 10 s on
    f = shipped_inertial_cf(mag_new_time=20.0)
    flags, outs = [], []
    for k in range(len(gyr)):
        outs.append(f.update(gyr[k], acc[k], mag[k]))
        flags.append(f.state()["mag_disturbed"])
    head, incl = heading_inclination(np.array(outs), q)
    assert not any(flags[:1000]) and all(flags[1010:2900])  # rejected for mag_new_time …
    assert head[:3000].max() < 1.0 and incl.max() < 0.5  # … so the heading holds, the tilt never moves
    assert not any(flags[3100:])  # then the constant new field is the reference again
    assert f.state()["mag_reference"][0] == pytest.approx(
        np.linalg.norm(M_WORLD + extra) / np.linalg.norm(M_WORLD), rel=0.02)


M_NORM, M_DIP = float(np.linalg.norm(M_WORLD)), math.atan2(40.0, 20.0)  # synth's field: 44.7 µT, 63.4°


def _world_field(scale: float, heading_deg: float, dip: float) -> np.ndarray:
    """A world field of ``scale`` × ‖M_WORLD‖, its horizontal part ``heading_deg`` east of north, its
    dip ``dip`` rad below the horizon."""
    h = math.radians(heading_deg)
    horizontal = math.cos(dip)
    return scale * M_NORM * np.array([math.sin(h) * horizontal, math.cos(h) * horizontal, -math.sin(dip)])


@pytest.mark.parametrize(("scale", "dip_change_deg"), [(1.0, 25.0), (1.4, 0.0)], ids=["dip", "norm"])
def test_inertial_cf_rejects_a_dip_change_alone_and_a_norm_change_alone(scale: float, dip_change_deg: float):
    """10 s of a field turned 40° in heading whose dip alone changes (25°, threshold 10°) or whose norm
    alone changes (+40 %, threshold 12.3 %): either is a disturbance, so the heading holds."""
    gyr, acc, mag, q = synth(25.0, rotating=False, seed=21)
    sl = slice(500, 1500)
    disturbed = _world_field(scale, 40.0, M_DIP - math.radians(dip_change_deg))
    mag[sl] += quat.rotate_inverse(q[sl], disturbed - M_WORLD)
    f = shipped_inertial_cf()
    est, flags = [], []
    for k in range(len(gyr)):
        est.append(f.update(gyr[k], acc[k], mag[k]))
        flags.append(f.state()["mag_disturbed"])
    head, _ = heading_inclination(np.array(est), q)
    assert all(flags[500:1500]) and not any(flags[:500]) and not any(flags[1600:])
    # measured 0.29 / 0.19 deg (a 40° error, if accepted, would reach 25° in the 10 s)
    assert head[sl].max() < 0.6, f"{head[sl].max():.2f} deg while rejected"
    assert head[1500:].max() < 0.4, f"{head[1500:].max():.2f} deg after"


def test_inertial_cf_rejection_timeout_then_fast_catch_up():
    """A constant 40°-off field (norm +40 %) from 5 s to 20 s, mag_max_reject = 4 s (no new reference):
    the heading holds until 9 s, then follows the disturbed field with tau_mag; when the true field is
    back, the magnetometer stays in use (still the timeout) and, undisturbed for mag_accept_time, the
    heading catches up with tau_mag_fast for fast_time, then tau_mag again. The expected error is that
    piecewise first-order response to the hand-made 40° step (documented defaults)."""
    p = filter_params("inertial_cf")  # the shipped tuned values
    tau, tau_fast = p["tau_mag"], p["tau_mag_fast"]
    gyr, acc, mag, q = synth(30.0, rotating=False, seed=22)
    sl = slice(500, 2000)
    mag[sl] += quat.rotate_inverse(q[sl], _world_field(1.4, 40.0, M_DIP) - M_WORLD)
    est = estimate_orientation(gyr, acc, mag, RATE, "inertial_cf", mag_max_reject=4.0, mag_new_time=1000.0)
    head, _ = heading_inclination(est, q)
    t = np.arange(len(head)) / RATE
    t_on, t_off = 5.0 + 4.0, 20.0
    t_accept = t_off + p["mag_accept_time"]
    t_slow = t_accept + p["fast_time"]
    e_off = 40.0 * (1.0 - math.exp(-(t_off - t_on) / tau))
    e_accept = e_off * math.exp(-(t_accept - t_off) / tau)
    e_slow = e_accept * math.exp(-(t_slow - t_accept) / tau_fast)
    model = np.select([t < t_on, t < t_off, t < t_accept, t < t_slow],
                      [0.0 * t, 40.0 * (1.0 - np.exp(-(t - t_on) / tau)), e_off * np.exp(-(t - t_off) / tau),
                       e_accept * np.exp(-(t - t_accept) / tau_fast)], e_slow * np.exp(-(t - t_slow) / tau))
    assert model[1999] == pytest.approx(27.2, abs=0.05) and model[2400] < 1.7  # 40°·(1 − e^(−11/9.67))
    dev = np.abs(head - model)
    assert dev.max() < 0.5, f"{dev.max():.2f} deg from the expected response at t = {t[np.argmax(dev)]:.2f} s"


@pytest.mark.parametrize("name", ["inertial_cf", "guo_fkf", "madgwick"])
def test_batch_runs_the_nodes_gains(name):
    """estimate_orientation, the node's tracker and analyze give an algorithm the same parameters: the
    shipped tuned ones over the class's defaults (issue 46); explicit ones still override."""
    from gait_biofeedback.core.orientation.filters.config import load_tuned
    from gait_biofeedback.core.orientation.stream import SegmentOrientationTracker

    tuned = load_tuned()[name]
    assert tuned and filter_params(name) == {**ALGORITHMS[name].DEFAULTS, **tuned}
    assert SegmentOrientationTracker("left_shank", algorithm=name).params == filter_params(name, "left_shank")
    assert filter_params(name, tuned=False) == ALGORITHMS[name].DEFAULTS
    first = next(k for k, v in tuned.items() if isinstance(v, float))
    assert filter_params(name, params={first: 0.5})[first] == 0.5
    gyr, acc, mag, _ = synth(3.0, rotating=True, seed=5)
    np.testing.assert_array_equal(estimate_orientation(gyr, acc, mag, RATE, name),
                                  run(name, gyr, acc, mag, **tuned))


def test_inertial_cf_rest_thresholds_reach_the_kernel():
    """rest_gyr / rest_acc are also base-class keywords: given, they are the kernel's (they were not)."""
    f = InertialCF(RATE, rest_gyr=0.01, rest_acc=0.02)
    assert (f.params["rest_gyr"], f.params["rest_acc"]) == (0.01, 0.02)
    assert (f._p[ik.P_REST_GYR], f._p[ik.P_REST_ACC]) == (0.01, 0.02)
    assert InertialCF(RATE).params["rest_gyr"] == InertialCF.DEFAULTS["rest_gyr"]


@pytest.mark.parametrize("name", ALL)
def test_gyro_bias_accessor_matches_state(name):
    gyr, acc, mag, _ = synth(2.0, rotating=True, seed=17)
    f = ALGORITHMS[name](RATE, **WITH_ONLINE_BIAS.get(name, {}))
    for k in range(len(gyr)):
        f.update(gyr[k], acc[k], mag[k])
    np.testing.assert_array_equal(f.gyro_bias(), f.state()["gyro_bias"])


def test_inertial_cf_rejects_bad_parameters():
    with pytest.raises(ValueError):
        InertialCF(RATE, tau_acc=-1.0)


def test_importing_filters_does_not_import_numba():
    import subprocess
    import sys

    code = "import sys, gait_biofeedback.core.orientation.filters; print('numba' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=Path(__file__).resolve().parents[1])
    assert out.stdout.strip() == "False"
