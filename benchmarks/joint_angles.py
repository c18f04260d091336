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
3. qmt_fullbody: the full chain on a real 100 s walk (vendor orientations, heading consistency not
   verified; PC8
   calibration from the first standing + walking): knee flexion peak, ranges, left/right symmetry.

Run: ``.venv/bin/python benchmarks/joint_angles.py [--seeds 5]``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import scipy.io as sio

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.calibration import calibrate_session, helical_angle, mean_orientation
from gait_biofeedback.core.calibration_windows import find_standing_then_motion, still_mask
from gait_biofeedback.core.filters import DEFAULT_ALGORITHM, estimate_orientation
from gait_biofeedback.core.joint_angles import JOINT_NAMES, compute_joint_angles
from gait_biofeedback.core.orientation_stream import track_orientation
from gait_biofeedback.core.segments import ImuSeries
from gait_biofeedback.core.simulator import Phase, SimulationConfig, simulate

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
                left = np.mean([r[name] for r in rmses])
                right = np.mean([r["right_" + base] for r in rmses])
                print(f"    {base:26s} {left:6.2f} / {right:6.2f}")


def report_weygers() -> None:
    folder = DATA / "dfjimu_weygers"
    if not folder.exists():
        print(f"\n[dfjimu_weygers] skipped: {folder} not found")
        return
    print("\n[dfjimu_weygers] (Weygers & Kok, IEEE Sensors J. 2020) relative orientation conj(q1)⊗q2 from "
          "the default filter (6D), heading aligned to optical over the first 1 s; RMSE of the angle (deg)")
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
        ok = np.all(np.isfinite(ref[:, :8]), axis=1)
        rel_est = quat.multiply(quat.conjugate(aligned[0]), aligned[1])
        rel_opt = quat.multiply(quat.conjugate(q_opt[0]), q_opt[1])
        err = np.degrees(quat.angle_between(rel_est[ok], rel_opt[ok]))
        print(f"    {path.stem:12s} {len(sd) / rate:6.0f} s  RMSE {np.sqrt(np.mean(err**2)):6.2f}  "
              f"median {np.median(err):6.2f}")


def report_qmt() -> None:
    path = DATA / "qmt_fullbody" / "full_body_example_data.mat"
    if not path.exists():
        print(f"\n[qmt_fullbody] skipped: {path} not found")
        return
    from gait_biofeedback.io.importers import import_qmt_fullbody

    rec = import_qmt_fullbody(path)
    segs = [s for s in LEGS if s in rec.imu]
    data = {s: rec.imu[s] for s in segs}
    ori = {s: quat.normalize(np.asarray(rec.reference["vendor_quat"][s], dtype=float)) for s in segs}
    t = data[segs[0]].t
    print("\n[qmt_fullbody] full chain on a real walk (vendor orientations, common heading NOT verified; "
          "PC8 calibration on the first standing + the first walk, angles over all moving samples)")
    first = {s: ImuSeries(s, d.t[d.t < 20.0], d.acc[d.t < 20.0], d.gyr[d.t < 20.0]) for s, d in data.items()}
    try:
        standing, motion = find_standing_then_motion(first)
    except ValueError as exc:
        print(f"    no calibration: {exc}")
        return
    cal = calibrate_session(first, standing, motion, "walking",
                            orientations={s: q[: len(first[s])] for s, q in ori.items()})
    print(f"    standing {standing[0]:.1f}–{standing[1]:.1f} s, motion {motion[0]:.1f}–{motion[1]:.1f} s; "
          f"{cal.message}")
    for s, r in cal.segments.items():
        print(f"      {s:12s} quality {r.quality:.3f} cycles {r.details.get('cycles')} {r.message}")
    st = (t >= standing[0]) & (t <= standing[1])
    angles = compute_joint_angles(ori, cal, standing=np.flatnonzero(st))
    moving = ~np.ones(len(t), dtype=bool)
    for s in segs:
        moving |= ~still_mask(data[s])
    walk = moving
    print("    angle (deg), 1st/99th pct     left: min  max  range | right: min  max  range | "
          "normal-gait range")
    bands = {"hip_flexion": (35, 55), "knee_flexion": (55, 75), "ankle_dorsiflexion": (20, 40)}
    for base, band in bands.items():
        row = []
        for side in ("left", "right"):
            v = np.degrees(angles[f"{side}_{base}"][walk])
            p1, p99 = np.percentile(v, [1, 99])
            row.append(f"{p1:6.1f} {p99:6.1f} {p99 - p1:6.1f}")
        print(f"    {base:26s} {row[0]} | {row[1]} | {band[0]}–{band[1]}")
    lk, rk = (np.degrees(np.percentile(angles[f"{s}_knee_flexion"][walk], 99)) for s in ("left", "right"))
    print(f"    knee flexion peak (swing, 99th pct): left {lk:.1f}°, right {rk:.1f}°, symmetry index "
          f"{200 * abs(lk - rk) / (lk + rk):.1f} %")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--algorithm", default=None, help="orientation filter (default: the project's)")
    args = parser.parse_args()
    start = time.perf_counter()
    report_simulator(args.seeds, args.algorithm)
    report_weygers()
    report_qmt()
    print(f"\nrun time {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
