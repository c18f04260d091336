"""Benchmark of the sensor-to-segment calibration and the joint angles (issue 4). Prints figures.

1. Simulator: calibration trial (hip flexion or PC8 walking) + quiet standing + a 30 s walk, sensors
   mounted at random rotations, noise and gyro bias; orientations from the project's filters
   (``track_orientation``, the live node's path, with magnetometer). Calibration error = helical
   angle (thesis Eq 19) per segment; joint-angle RMSE per angle over the walk after the standing
   offset removal (gait.md §1.9). Goals: thesis medians (thigh 6.2°, shank 16.5°, foot 11.8°) and
   knee flexion RMSE ≤ 2°.
2. dfjimu_weygers (Weygers & Kok 2020): relative orientation of two sensors from the filters
   (6D, no magnetometer) vs optical truth, RMSE per recording. No magnetometer: each filter's world
   heading is aligned once to the optical one over the first second; the drift after it is counted.
3. qmt_fullbody (qmt examples, MIT): the full chain on a real 100 s walk. The vendor quaternions are
   checked and NOT used (their gravity disagrees with the accelerometers by 68–108° in standing).
   ``report_qmt``: batch steps with the headings aligned at a standing (the former figures);
   ``report_qmt_cli``: the documented CLI path, ``import qmt_fullbody`` → ``analyze --calibrate-at
   75:walking`` and ``--calibrate-at auto``, per-stride plausibility of the published angles.
4. ``report_flips``: 50 random mountings x both protocols, 6D and 9D filter orientations, protocol
   ``auto`` and the wrong one: flips, refusals, worst calibration errors.
5. ``report_magnet``: the ``magnet_near_thigh`` scenario through ``analyze --calibrate-at auto``,
   knee flexion RMSE with the kinematic heading, the filters' heading and without magnetometer.
6. ``report_hips``: a walk with a 180° turn through ``analyze --calibrate-at auto``, 6D and 9D, hip
   and knee angle RMSE with the hips' heading from the segment axes and from the joint centre.

Run: ``.venv/bin/python benchmarks/joint_angles.py [--seeds 5]``.
"""

from __future__ import annotations

import argparse
import itertools
import time
from pathlib import Path

import numpy as np
import scipy.io as sio

from gait_biofeedback.batch import (
    DEFAULT_ALGORITHM,
    JOINT_NAMES,
    SCENARIOS,
    ImuSeries,
    Phase,
    SimulationConfig,
    align_headings,
    calibrate_session,
    compute_joint_angles,
    detect_gait_events,
    estimate_orientation,
    estimate_relative_orientation,
    find_standing_then_motion,
    helical_angle,
    import_qmt_fullbody,
    mean_orientation,
    simulate,
    track_orientation,
    vertical_calibration,
)
from gait_biofeedback.batch import quaternion as quat
from gait_biofeedback.wire.stamps import stamp_to_ns

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
LEGS = ("left_thigh", "left_shank", "left_foot", "right_thigh", "right_shank", "right_foot", "pelvis")
THESIS_MEDIAN = {"thigh": 6.2, "shank": 16.5, "foot": 11.8}


def _session(protocol: str, seed: int):
    calib = (Phase("hip_flexion", 28.0, {"side": "both"}) if protocol == "hip_flexion"
             else Phase("walk", 7.0))
    phases = [Phase("stand", 5.0), calib, Phase("stand", 5.0), Phase("walk", 30.0), Phase("stand", 3.0)]
    cfg = SimulationConfig(phases=phases, seed=seed, segments=LEGS)
    return simulate(cfg), 5.0 + calib.duration


def simulator(protocol: str, seed: int, use_truth: bool,
              algorithm: str | None = None) -> tuple[dict, dict, bool]:
    session, t_cal_end = _session(protocol, seed)
    data, ori = {}, {}
    for seg, series in session.imu.items():
        if use_truth:
            t, q, g = series.t, session.truth.sensor_orientation[seg], series.gyr
        else:
            t, q, g = track_orientation(series, algorithm=algorithm)
        data[seg], ori[seg] = ImuSeries(seg, t, series.acc, g), q
    cut = {s: ImuSeries(s, d.t[d.t < t_cal_end + 2.0], d.acc[d.t < t_cal_end + 2.0],
                        d.gyr[d.t < t_cal_end + 2.0]) for s, d in data.items()}
    standing, motion = find_standing_then_motion(cut)
    cal = calibrate_session(cut, standing, motion, protocol,
                            orientations={s: ori[s][: len(cut[s])] for s in cut})
    cal_err = {s: float(np.degrees(helical_angle(r.rotation, session.truth.mounting[s])))
               for s, r in cal.segments.items()}
    t = session.truth.t
    trial = t >= t_cal_end + 3.0
    stand = slice(0, int(2.0 * session.config.rate_hz))  # the 2 s of standing before the walk
    est = compute_joint_angles({s: q[trial] for s, q in ori.items()}, cal, standing=stand)
    truth = {k: v[trial] - np.mean(v[trial][stand]) for k, v in session.truth.joint_angles.items()}
    rmse = {k: float(np.degrees(np.sqrt(np.mean((est[k] - truth[k]) ** 2)))) for k in est}
    return cal_err, rmse, cal.success


def report_simulator(seeds: int, algorithm: str | None) -> None:
    for protocol in ("hip_flexion", "walking"):
        for use_truth in (True, False):
            errs, rmses, ok = [], [], 0
            for seed in range(seeds):
                e, r, success = simulator(protocol, seed, use_truth, algorithm)
                errs.append(e)
                rmses.append(r)
                ok += success
            source = ("true orientations" if use_truth
                      else f"filter orientations ({algorithm or DEFAULT_ALGORITHM}, mag)")
            print(f"\n[simulator] protocol={protocol}, {source}, {seeds} seeds, "
                  f"calibrations accepted {ok}/{seeds}")
            print("  calibration error, helical angle (deg), median [max] over seeds and sides:")
            for part in ("thigh", "shank", "foot", "pelvis"):
                v = [e[s] for e in errs for s in e if s.endswith(part)]
                goal = (f"(thesis median {THESIS_MEDIAN[part]})" if part in THESIS_MEDIAN
                        else "(no thesis figure)")
                print(f"    {part:7s} {np.median(v):6.2f} [{np.max(v):6.2f}]  {goal}")
            print("  joint-angle RMSE over the 30 s walk, offset removed (deg), mean over seeds, "
                  "left / right:")
            for name in JOINT_NAMES[:9]:
                base = name.removeprefix("left_")
                left = np.mean([r.get(name, np.nan) for r in rmses])
                right = np.mean([r.get("right_" + base, np.nan) for r in rmses])
                print(f"    {base:26s} {left:6.2f} / {right:6.2f}")


def _optical_ok(o: np.ndarray, gyr: np.ndarray, rate: float, limit_deg: float = 5.0) -> np.ndarray:
    """Samples whose optical orientation step agrees with the gyro within ``limit_deg`` (marker glitches
    of up to 178° on a few samples otherwise dominate an RMSE)."""
    step = quat.angle_between(quat.multiply(quat.conjugate(o[:-1]), o[1:]), quat.from_rotvec(gyr[:-1] / rate))
    bad = np.degrees(step) > limit_deg
    ok = np.ones(len(o), dtype=bool)
    ok[:-1] &= ~bad
    ok[1:] &= ~bad
    return ok


def report_weygers() -> None:
    folder = DATA / "dfjimu_weygers"
    if not folder.exists():
        print(f"\n[dfjimu_weygers] skipped: {folder} not found")
        return
    print("\n[dfjimu_weygers] (Weygers & Kok, IEEE Sensors J. 2020) relative orientation conj(q1)⊗q2 vs "
          "optical, RMSE (deg) on the samples whose optical step agrees with the gyro (marker glitches out)."
          "\n  'aligned': default filter 6D, heading aligned to optical over the first 1 s (needs truth); "
          "'kinematic': estimate_relative_orientation (6D + joint-centre heading, no truth). Goal: median "
          "<= 3, worst <= 10 (their MEKF 2.4-6.2)")
    rows = []
    for path in sorted(folder.glob("data_*.mat")):
        d = sio.loadmat(path, struct_as_record=False, squeeze_me=True)["data"]
        rate = float(d.rate)
        sd = np.asarray(d.sensorData, dtype=float)
        ref = np.asarray(d.ref, dtype=float)
        q_opt = [quat.normalize(ref[:, 0:4]), quat.normalize(ref[:, 4:8])]
        est = [estimate_orientation(sd[:, 3:6], sd[:, 0:3], None, rate),
               estimate_orientation(sd[:, 9:12], sd[:, 6:9], None, rate)]
        n0 = int(rate)
        aligned = []
        for qe, qo in zip(est, q_opt, strict=True):
            offset = mean_orientation(quat.multiply(qo[:n0], quat.conjugate(qe[:n0])))
            aligned.append(quat.multiply(offset, qe))
        ok = (np.all(np.isfinite(ref[:, :8]), axis=1) & _optical_ok(q_opt[0], sd[:, 3:6], rate)
              & _optical_ok(q_opt[1], sd[:, 9:12], rate))
        rel_opt = quat.multiply(quat.conjugate(q_opt[0]), q_opt[1])
        kinematic = estimate_relative_orientation(sd[:, 3:6], sd[:, 0:3], sd[:, 9:12], sd[:, 6:9], rate,
                                                  dof=int(path.stem[5]))
        row = []
        for rel in (quat.multiply(quat.conjugate(aligned[0]), aligned[1]), kinematic):
            err = np.degrees(quat.angle_between(rel[ok], rel_opt[ok]))
            row.append(float(np.sqrt(np.mean(err**2))))
        rows.append(row)
        print(f"    {path.stem:12s} {len(sd) / rate:6.0f} s  aligned {row[0]:6.2f}  kinematic {row[1]:6.2f}")
    r = np.array(rows)
    print(f"    median over recordings: aligned {np.median(r[:, 0]):.2f}, "
          f"kinematic {np.median(r[:, 1]):.2f}; worst: aligned {r[:, 0].max():.2f}, "
          f"kinematic {r[:, 1].max():.2f}")


def _heading_deg(q: np.ndarray, v: np.ndarray) -> float:
    w = quat.rotate(q, v)
    return float(np.degrees(np.arctan2(w[1], w[0])))


def _pelvis_vertical(acc: np.ndarray, beta: float) -> np.ndarray:
    """Pelvis r from the vertical calibration (Eq 14) only, turned by ``beta`` about the anatomical y."""
    rows = vertical_calibration(acc)
    r = quat.from_matrix(rows.T)
    return quat.multiply(r, quat.from_axis_angle([0.0, 1.0, 0.0], beta))


def _per_stride(angle: np.ndarray, t: np.ndarray, ics: np.ndarray, lo: float, hi: float):
    """(max, min, value at IC) of ``angle`` per stride IC→next IC inside [lo, hi] s. The IC times are
    sample times: a stride starts at its IC sample (half a sample of slack, so that the float
    rounding of equal times cannot move it to the next sample). NaN samples (an angle not published)
    are left out; a stride left with 10 samples or fewer is skipped."""
    rows = []
    half = 0.5 * float(np.median(np.diff(t)))
    for a, b in itertools.pairwise(ics):
        if a < lo or b > hi or not 0.7 < b - a < 1.6:
            continue
        sel = (t >= a - half) & (t < b - half) & np.isfinite(angle)
        if sel.sum() > 10:
            rows.append((angle[sel].max(), angle[sel].min(), angle[sel][0]))
    return np.degrees(np.array(rows)).reshape(-1, 3)


def report_qmt() -> None:
    path = DATA / "qmt_fullbody" / "full_body_example_data.mat"
    if not path.exists():
        print(f"\n[qmt_fullbody] skipped: {path} not found")
        return
    rec = import_qmt_fullbody(path)
    segs = [s for s in LEGS if s in rec.imu]
    data = {s: rec.imu[s] for s in segs}
    t = data[segs[0]].t
    print("\n[qmt_fullbody] (qmt examples, MIT) full chain on a real walk: 6D filter orientations, world "
          "headings aligned at the standing before the walk, PC8 calibration (start standing + walk)")
    first = {s: ImuSeries(s, d.t[d.t < 20.0], d.acc[d.t < 20.0], d.gyr[d.t < 20.0]) for s, d in data.items()}
    try:
        cal_standing, _ = find_standing_then_motion(first)
        walk_standing, walk = find_standing_then_motion(data, standing_duration=2.5)
    except ValueError as exc:
        print(f"    no calibration: {exc}")
        return
    ori = {s: estimate_orientation(d.gyr, d.acc, None, d.rate_hz, startup_s=5.0) for s, d in data.items()}
    cal = calibrate_session(data, cal_standing, walk, "walking", orientations=ori)
    print(f"    calibration standing {cal_standing[0]:.1f}–{cal_standing[1]:.1f} s, walk {walk[0]:.1f}–"
          f"{walk[1]:.1f} s, alignment/offset standing {walk_standing[0]:.1f}–{walk_standing[1]:.1f} s")
    st_cal = (t >= cal_standing[0]) & (t <= cal_standing[1])
    st = np.flatnonzero((t >= walk_standing[0]) & (t <= walk_standing[1]))
    vendor = {s: quat.normalize(np.asarray(rec.reference["vendor_quat"][s], dtype=float)) for s in segs}
    print("    segment       quality  sign rule                                          heading of "
          "anat. x in standing: vendor / 6D (deg); vendor gravity vs acc (deg)")
    for s, r in cal.segments.items():
        if not r.valid or s == "pelvis":
            print(f"      {s:12s} {r.message}")
            continue
        x_s = quat.rotate(r.rotation, [1.0, 0.0, 0.0])
        up_vendor = quat.rotate_inverse(mean_orientation(vendor[s][st_cal]), [0.0, 0.0, 1.0])
        acc_up = data[s].acc[st_cal].mean(axis=0)
        g_err = np.degrees(np.arccos(np.clip(up_vendor @ acc_up / np.linalg.norm(acc_up), -1, 1)))
        print(f"      {s:12s} {r.quality:6.3f}  {r.details['sign_rule'][:50]:50s} "
              f"{_heading_deg(mean_orientation(vendor[s][st]), x_s):6.0f} / "
              f"{_heading_deg(mean_orientation(ori[s][st]), x_s):6.0f}; {g_err:5.0f}")
    rotations = {s: r.rotation for s, r in cal.segments.items() if r.valid and s != "pelvis"}
    feet = {side: data[f"{side}_foot"] for side in ("left", "right")}
    ics = {side: np.asarray(detect_gait_events(f.gyr, f.acc, f.rate_hz)["ic"]) for side, f in feet.items()}
    lo, hi = walk[0] + 1.0, walk[1] - 1.0
    rows = {"knee_flexion": ("swing peak", 0, (55, 70)), "knee_flexion@IC": ("at IC", 2, (0, 10)),
            "hip_flexion": ("max", 0, (30, 35)), "hip_flexion ": ("min", 1, (-15, -10)),
            "ankle_dorsiflexion": ("max", 0, (10, 15)), "ankle_dorsiflexion ": ("min", 1, (-20, -15))}
    for beta_deg in (0, 90, 180, 270):
        pelvis = _pelvis_vertical(data["pelvis"].acc[st_cal], np.radians(beta_deg))
        rot = dict(rotations, pelvis=pelvis)
        angles = compute_joint_angles(align_headings(ori, rot, st), rot, standing=st)
        if beta_deg == 0:
            print("    per stride, mean ± SD over strides (deg)      left            right       "
                  "|L−R|  normal gait")
            for key, (what, col, band) in rows.items():
                if key.startswith("hip"):
                    continue
                name = key.split("@")[0].strip()
                vals = [_per_stride(angles[f"{side}_{name}"], t, ics[side], lo, hi)[:, col]
                        for side in ("left", "right")]
                print(f"    {key.split('@')[0].strip():20s} {what:10s} {np.mean(vals[0]):6.1f} ± "
                      f"{np.std(vals[0]):4.1f}  {np.mean(vals[1]):6.1f} ± {np.std(vals[1]):4.1f}  "
                      f"{abs(np.mean(vals[0]) - np.mean(vals[1])):5.1f}  {band[0]}..{band[1]}")
            print(f"      strides: left {len(vals[0])}, right {len(vals[1])}")
            print("    hip flexion per stride (pelvis heading in its sensor unknown: turned by β about "
                  "vertical):")
        hip = [_per_stride(angles[f"{side}_hip_flexion"], t, ics[side], lo, hi) for side in ("left", "right")]
        print(f"      β = {beta_deg:3d}°  max {np.mean(hip[0][:, 0]):5.1f} / {np.mean(hip[1][:, 0]):5.1f}   "
              f"min {np.mean(hip[0][:, 1]):6.1f} / {np.mean(hip[1][:, 1]):6.1f}  (left / right; normal "
              "gait max 30..35, min -15..-10)")


def report_qmt_cli(calibrate_at: str = "75:walking") -> None:
    """The qmt walk through the documented CLI path: ``import qmt_fullbody`` → ``analyze --calibrate-at``;
    the published /joint_states and /gait/events are read back from the output bag."""
    import tempfile

    from gait_biofeedback.batch import BagReader
    from gait_biofeedback.cli import main as cli

    path = DATA / "qmt_fullbody" / "full_body_example_data.mat"
    if not path.exists():
        print(f"\n[qmt_fullbody, CLI] skipped: {path} not found")
        return
    with tempfile.TemporaryDirectory() as tmp:
        bag, out = Path(tmp) / "qmt", Path(tmp) / "out"
        cli(["import", "qmt_fullbody", str(path), "-o", str(bag)])
        print(f"\n[qmt_fullbody, CLI] import qmt_fullbody → analyze --calibrate-at {calibrate_at}:")
        cli(["analyze", str(bag), "-o", str(out), "--calibrate-at", calibrate_at])
        stamps, rows, ics = [], [], {0: [], 1: []}
        with BagReader(out) as reader:
            for topic, msg, _ in reader.messages(["/joint_states", "/gait/events"]):
                ns = stamp_to_ns(msg.header.stamp)
                if topic == "/joint_states":
                    stamps.append(ns)
                    rows.append(dict(zip(msg.name, msg.position, strict=True)))
                elif msg.type == 0:
                    ics[msg.side].append(ns)
    if not rows:
        print("    no joint angles published")
        return
    t_ns = np.array(stamps)
    angles = {n: np.array([r.get(n, np.nan) for r in rows]) for n in JOINT_NAMES}
    print("    per side, mean over strides (deg)            goal        left      right")
    checks = [("knee_flexion", 2, "at IC", "-5..15"), ("knee_flexion", 0, "swing peak", "50..75"),
              ("hip_flexion", 0, "max", "~40"), ("hip_flexion", 1, "min", "~-20"),
              ("ankle_dorsiflexion", 0, "max", ""), ("ankle_dorsiflexion", 1, "min", "")]
    for name, col, what, goal in checks:
        vals = []
        for side_i, side in enumerate(("left", "right")):
            strides = _per_stride(angles[f"{side}_{name}"], t_ns * 1e-9, np.array(ics[side_i]) * 1e-9,
                                  -np.inf, np.inf)
            vals.append(f"{np.mean(strides[:, col]):7.1f} ({len(strides)})" if len(strides) else "   none")
        print(f"    {name:19s} {what:11s} {goal:>8s}  {vals[0]:>12s} {vals[1]:>12s}")
    for side in ("left", "right"):
        ir = np.degrees(angles[f"{side}_knee_internal_rotation"])
        ir = ir[np.isfinite(ir)]
        share = 100.0 * np.mean(np.abs(ir) <= 30.0) if len(ir) else float("nan")
        print(f"    {side} knee internal rotation within ±30°: {share:.1f} % of {len(ir)} samples "
              "(goal 95 %)")


def _filtered(session) -> tuple[dict, dict]:
    """The session's series with the filters' orientations (``track_orientation``, the node's path)."""
    data, ori = {}, {}
    for seg, series in session.imu.items():
        t, q, g = track_orientation(series)
        data[seg], ori[seg] = ImuSeries(seg, t, series.acc[: len(t)], g), q
    return data, ori


def report_flips(seeds: int = 50) -> None:
    """Random mountings x both protocols, 6D and 9D filter orientations, ``auto`` protocol and the wrong
    one: flips (a segment > 90° off), refusals, the wrong protocol accepted."""
    print(f"\n[simulator] calibration never flips: {seeds} random mountings x both protocols (seeds 100-"
          f"{99 + seeds}), filter orientations; 'auto' = the protocol the movement shows")
    print("    data         filters  protocol found  flips  refused segments       wrong protocol refused  "
          "worst error (deg): thigh shank foot pelvis chest")
    for scenario, done in (("calibration_hip_flexion", "hip_flexion"), ("calibration_walking", "walking")):
        wrong = "walking" if done == "hip_flexion" else "hip_flexion"
        for mag in (True, False):
            found = flips = refused_wrong = 0
            refused: dict[str, int] = {}
            worst: dict[str, float] = {}
            for seed in range(100, 100 + seeds):
                session = simulate(SCENARIOS[scenario](seed=seed, with_magnetometer=mag))
                data, ori = _filtered(session)
                standing, motion = find_standing_then_motion(data)
                cal = calibrate_session(data, standing, motion, "auto", orientations=ori, common_heading=mag)
                found += cal.protocol == done and cal.looks_like == done
                for seg, res in cal.segments.items():
                    part = seg.split("_")[-1]
                    if not res.valid:
                        refused[part] = refused.get(part, 0) + 1
                        continue
                    err = float(np.degrees(helical_angle(res.rotation, session.truth.mounting[seg])))
                    worst[part] = max(worst.get(part, 0.0), err)
                    flips += err > 90.0
                other = calibrate_session(data, standing, motion, wrong, orientations=ori, common_heading=mag)
                refused_wrong += not other.success and other.looks_like == done
            text = ", ".join(f"{k} {v}" for k, v in refused.items()) or "none"
            parts = ("thigh", "shank", "foot", "pelvis", "chest")
            errors = " ".join(f"{worst.get(p, float('nan')):5.1f}" for p in parts)
            print(f"    {done:12s} {'9D' if mag else '6D':7s}  {found:3d}/{seeds}          {flips:3d}    "
                  f"{text:22s} {refused_wrong:3d}/{seeds}                  {errors}")
    print("    (6D hip flexion: the trunk is refused by design, a still pelvis shows no heading; the message "
          "says to calibrate with the walking protocol)")


def report_magnet(seeds: tuple[int, ...] = (4, 5, 6)) -> None:
    """The magnet_near_thigh scenario through analyze (--calibrate-at auto): knee flexion RMSE."""
    import tempfile

    from gait_biofeedback.batch import analyze_recording, write_simulated_bag

    print("\n[simulator] magnet near the left thigh (scenario magnet_near_thigh, +30 µT at 30-50 s), "
          "analyze --calibrate-at auto, knee flexion RMSE over the 40 s walk (deg), mean over seeds "
          f"{list(seeds)}, left / right. Goal <= 2")
    for mag, heading in ((True, "kinematic"), (True, "filters"), (False, "kinematic")):
        rmse = []
        for seed in seeds:
            session = simulate(SCENARIOS["magnet_near_thigh"](seed=seed, with_magnetometer=mag))
            with tempfile.TemporaryDirectory() as tmp:
                bag = write_simulated_bag(Path(tmp) / "bag", session)
                result = analyze_recording(bag, None, calibrate_at=[(None, "auto")],
                                           params={"joint_angles": {"heading": heading}})
            rmse.append(_knee_rmse(session, result, 20.0, 60.0))
        left, right = np.nanmean(rmse, axis=0)
        label = f"{'9D' if mag else '6D (--no-mag)'}, heading: {heading}"
        print(f"    {label:32s} {left:5.2f} / {right:5.2f}")


def report_hips(seeds: tuple[int, ...] = (4, 5, 6)) -> None:
    """Hip angles through analyze (--calibrate-at auto) on a walk with a 180° turn, both hip headings."""
    import tempfile

    from gait_biofeedback.batch import analyze_recording, write_simulated_bag

    phases = [Phase("stand", 5.0), Phase("walk", 10.0), Phase("stand", 5.0), Phase("walk", 20.0),
              Phase("turn", 4.0, {"angle": np.pi}), Phase("walk", 20.0), Phase("stand", 3.0)]
    names = [f"{side}_{n}" for side in ("left", "right") for n in
             ("hip_flexion", "hip_adduction", "hip_internal_rotation", "knee_flexion")]
    print(f"\n[simulator] hips: walk, 180° turn, walk (analyze --calibrate-at auto), RMSE 20-64 s (deg), "
          f"mean over seeds {list(seeds)}, left / right")
    header = "  ".join(f"{n.removeprefix('left_'):>21s}" for n in names[:4])
    print(f"    {'filters, hip heading':30s} {header}")
    for mag in (False, True):
        for hip_heading in ("segment_axes", "joint_centre"):
            rmse = []
            for seed in seeds:
                session = simulate(SimulationConfig(phases=phases, seed=seed, with_magnetometer=mag))
                with tempfile.TemporaryDirectory() as tmp:
                    bag = write_simulated_bag(Path(tmp) / "bag", session)
                    result = analyze_recording(bag, None, calibrate_at=[(None, "auto")],
                                               params={"joint_angles": {"hip_heading": hip_heading}})
                rmse.append(_joint_rmse(session, result, 20.0, 64.0, names))
            mean = np.nanmean(rmse, axis=0)
            cells = [f"{mean[k]:9.2f} / {mean[k + 4]:9.2f}" for k in range(4)]
            print(f"    {('9D' if mag else '6D') + ', ' + hip_heading:30s} " + "  ".join(cells))


def _knee_rmse(session, result, t0: float, t1: float) -> list[float]:
    return _joint_rmse(session, result, t0, t1, ("left_knee_flexion", "right_knee_flexion"))


def _joint_rmse(session, result, t0: float, t1: float, names) -> list[float]:
    rows: dict[str, list] = {n: [] for n in names}
    rate = session.config.rate_hz
    for topic, msg, _ in result.messages:
        if topic != "/joint_states":
            continue
        k = round((msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9) * rate)
        if t0 <= k / rate <= t1:
            for name, value in zip(msg.name, msg.position, strict=True):
                if name in rows:
                    rows[name].append((k, value))
    out = []
    for name in names:
        if not rows[name]:
            out.append(float("nan"))
            continue
        k, v = np.array(rows[name]).T
        truth = session.truth.joint_angles[name][k.astype(int)]
        out.append(float(np.degrees(np.sqrt(np.mean((v - truth) ** 2)))))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--flip-seeds", type=int, default=50, help="random mountings per protocol")
    parser.add_argument("--algorithm", default=None, help="orientation filter (default: the project's)")
    args = parser.parse_args()
    start = time.perf_counter()
    report_simulator(args.seeds, args.algorithm)
    report_weygers()
    report_qmt()
    report_qmt_cli("75:walking")
    report_qmt_cli("auto")
    report_flips(args.flip_seeds)
    report_magnet()
    report_hips()
    print(f"\nrun time {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
