"""Foot trajectories and spatial stride parameters (Suh 2014; issue 16), scored side by side.

Run: ``.venv/bin/python benchmarks/spatial.py`` (about 15 min on this 2-core machine, 4 of it
without gaitmap; the first run also makes gaitmap's venv in ``output/gaitmap-venv``, about 1 min;
``--no-gaitmap`` leaves gaitmap out; ``--pyshoe-only`` prints the first table alone, with its
cross-validation: about 6 min). Every estimate
goes through
the batch entry point ``estimate_foot_trajectory``. It prints three tables.

1. ``pyshoe_vicon``: 28 trials, a shoe IMU at 200 Hz, Vicon shoe positions (Wagstaff et al.).
   - Score, as the dataset's authors do: both trajectories from their first sample, the estimate
     rotated about z so that its position where it is first 0.8 m from the start points as the
     reference does, then the mean over samples of ``sqrt((dx² + dy²) / 2)`` (their "ARMSE", m).
   - The Vicon frame of these files is left-handed in x-y. The authors' filter works in a z-down
     frame and compares x-y directly, which absorbs it. Our ENU trajectory is therefore mirrored
     (y → -y) before the rotation. Without the mirror every method here scores about 10× worse;
     with it the Vicon path is matched to 3 cm RMS on trial 4.
   - Columns:
     - ``suh``: the default, Suh's smoother over the whole trial;
     - ``rts``: the RTS smoother;
     - ``ekf``: the zero-velocity EKF without smoothing;
     - ``no valley``: the default without the valley rule (``valley=False``: the fixed thresholds only);
     - ``no shock``: the default without the accelerometer's shock noise (``acc_shock=1000``);
     - ``shock always``: the shock noise in every swing, also after running's short stances
       (``shock_stance_s=0``, the default before it);
     - ``gaitmap``: gaitmap 2.6's ``RtsKalman``, default parameters;
     - ``oracle``: the file's ``best_error``, the best of five detectors each at its per-trial
       optimal threshold;
     - ``oracle (IMU)``: the best of the detectors that read the IMU alone. The files' ``trial_error``
       is ``[shoe, ared, ared, mbgtd, vicon]`` (the dataset's readme; its threshold search stores
       ARED's error twice and AMVD's not at all); ``vicon`` labels stances from the Vicon positions
       and is the best on 9 trials, so this is the best of the first four;
     - ``suh@oracle-zv``: our filter and smoother (default noise) given the oracle's zero-velocity
       labels: the detector taken out;
     - ``old default``: the default before issue 47 (``adaptive_scale=0``: the fixed rule and the
       valley rule, no gait-scaled test).
   - Means over the 9 running trials (2017-11-27-*, 2017-12-15-18-01/02) and the 19 others, and over
     the two halves in time order (A: the 1st, 3rd, ... trial; B: the 2nd, 4th, ...), on which
     parameters are chosen (A) and confirmed (B).
   - Leave-one-session-out cross-validation of ``adaptive_scale`` (the gait-scaled stance test of
     ``core/spatial/zero_velocity.py``), among ``ADAPTIVE_CANDIDATES`` (0: off, the old default): the
     sessions are the recording dates of the file names (2017-11-22, 2017-11-27, 2017-12-15, 2018-02-09,
     2018-02-22). Per fold, the value whose worst training trial has the least ARMSE ratio to the
     IMU-only oracle is chosen on the other sessions and scored on the held-out one: its mean and
     median ARMSE, its worst trial, the oracle's mean, their ratio and the largest per-trial ratio, and
     the old default on the same trials beside it. The default is the same rule applied to all 28.
2. ``gaitmap_example``: 57 strides with Vicon markers at 100 Hz.
   - Stride length against the heel marker's horizontal displacement over the reference stride:
     the default (Suh over the whole recording), ``no shock``, the live per-stride values (RTS),
     gaitmap's ``RtsKalman`` (its positions at the reference stride's start and end), and the
     provisional value at IC + 50 ms (a prototype, not in the graph): the forward filter's travel
     from the last stance to 25 ms after the mocap IC (the detector's look-ahead), plus the foot's
     mean remaining travel to its next stance over its last 5 strides (in the stride's own frame).
   - The strides split by the heel → toe markers' heading change (straight: under 10°), and the
     correlation of the ``no shock`` errors with gaitmap's: the spread both share is in the data.
   - The foot angles against the heel → toe marker pitch, by the definitions of
     ``core/spatial/strides.py`` applied to the markers.
3. Simulator (``walk``, seed 2, 100 and 200 Hz): stride length, gait speed and the largest sensor
   height against the truth, over every stride but the first and the last. The simulator's gait
   initiation and stop slide the flat foot (forward and back), which no zero-velocity detector can
   see: 22 cm and 5 cm errors there.
4. Through the command line, as a user runs it (``import`` → ``analyze``): gaitmap_example's
   ``gait/cycles`` stride lengths against the heel marker's footprints (where it is slowest in the
   0.4 s after each IC), how many strides have no spatial values, and when the message comes;
   qmt_fullbody's real walk (no truth): how many strides are flagged, the median and largest.
5. ``--lost-samples`` (only that table, about 3 min): the live stream (``FootTrajectoryStream``) on the
   simulator's walk with samples lost, against the same stream on every sample, stride by stride
   (matched by foot-flat stamp): one gap of 1 or 2 samples per stride at a random place, and 1 % and
   3 % lost at random, at 100 and 200 Hz. How many strides get no values, and the stride-length error
   of the others.
6. ``--gyro-limit-grid`` (only that table, about 5 min): could one zero-velocity threshold per
   pyshoe trial, chosen without the Vicon, reach the authors' oracle? Each trial at ``gyro_limit``
   0.15-0.6 rad/s: the mean over the trials of the default's score, of the grid value whose forward
   filter (no smoother) has the least RMS speed at its stance onsets (a stance found in mid-swing
   meets the filter moving), and of the best grid value per trial (chosen with the Vicon).
"""

from __future__ import annotations

import argparse
import copy
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
import scipy.io as sio

from gait_biofeedback.batch import (
    SCENARIOS,
    FootTrajectoryParams,
    FootTrajectoryStream,
    estimate_foot_trajectory,
    import_gaitmap,
    simulate,
)
from gait_biofeedback.core.gait.cycles import TURN_LIMIT

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data"
GAITMAP_VENV = REPO / "output" / "gaitmap-venv"
GAITMAP_VERSION = "2.6.0"
GAITMAP_RATE_HZ = 204.8


def armse(estimate: np.ndarray, reference: np.ndarray, mirror: bool = True, align_m: float = 0.8) -> float:
    """The pyshoe authors' trial score (module docstring), m."""
    est = (estimate - estimate[0]) * np.array([1.0, -1.0 if mirror else 1.0, 1.0])
    ref = reference - reference[0]
    distance = np.linalg.norm(est[:, :2], axis=1)
    k = int(np.argmax(distance >= align_m)) if distance.max() >= align_m else min(300, len(est) - 1)
    angle = np.arctan2(ref[k, 1], ref[k, 0]) - np.arctan2(est[k, 1], est[k, 0])
    c, s = np.cos(angle), np.sin(angle)
    x, y = c * est[:, 0] - s * est[:, 1], s * est[:, 0] + c * est[:, 1]
    return float(np.mean(np.sqrt(((x - ref[:, 0]) ** 2 + (y - ref[:, 1]) ** 2) / 2.0)))


def gaitmap_python() -> Path | None:
    """gaitmap's own venv (made once), or None when it cannot be made."""
    python = GAITMAP_VENV / "bin" / "python"
    if not python.exists():
        print(f"making {GAITMAP_VENV} with gaitmap=={GAITMAP_VERSION} (once) ...", flush=True)
        made = subprocess.run(["python3", "-m", "venv", str(GAITMAP_VENV)])
        if made.returncode == 0:
            made = subprocess.run([str(python), "-m", "pip", "install", "-q", f"gaitmap=={GAITMAP_VERSION}"])
        if made.returncode != 0:
            print("gaitmap could not be installed: its column is left out")
            return None
    return python


def gaitmap_rts(python: Path, gyr: np.ndarray, acc: np.ndarray, rate: float) -> np.ndarray:
    with tempfile.TemporaryDirectory() as tmp:
        given, got = Path(tmp) / "in.npz", Path(tmp) / "out.npz"
        np.savez(given, gyr=gyr, acc=acc, rate=rate)
        script = REPO / "benchmarks" / "_gaitmap_rts.py"
        run = subprocess.run([str(python), str(script), str(given), str(got)], capture_output=True, text=True)
        if run.returncode != 0:
            raise RuntimeError(run.stderr[-500:])
        return np.load(got)["position"]


def _tracked(position: np.ndarray, reference: np.ndarray) -> float:
    ok = np.isfinite(position[:, 0])
    return armse(position[ok], reference[ok])


RUNNING = ("2017-11-27-", "2017-12-15-18-01", "2017-12-15-18-02")  # pyshoe_vicon's running trials
ADAPTIVE_CANDIDATES = (0.0, 0.03, 0.045, 0.065, 0.09, 0.13)  # adaptive_scale, rad/s per m/s²; 0: the old rule


def session(stem: str) -> str:
    """A pyshoe_vicon trial's recording session: the date of its file name."""
    return stem[:10]


def choose_adaptive_scale(errors: dict[float, np.ndarray], oracle: np.ndarray, train: np.ndarray) -> float:
    """The candidate whose worst ``train`` trial has the least ARMSE ratio to the IMU-only oracle."""
    return min(errors, key=lambda c: (float(np.max(errors[c][train] / oracle[train])), c))


def cross_validate(stems: list[str], errors: dict[float, np.ndarray], oracle: np.ndarray) -> None:
    """Leave-one-session-out: per held-out session and overall (module docstring)."""
    sessions = np.array([session(s) for s in stems])
    old = errors[0.0]
    out_of_fold = np.full(len(stems), np.nan)
    print("\n### leave-one-session-out cross-validation of adaptive_scale (rad/s per m/s²)\n")
    print("| held out | trials | chosen | mean | median | worst trial | oracle (IMU) mean | mean / oracle "
          "| max trial / oracle | old default: mean | worst | max trial / oracle |")
    print("|---" * 12 + "|")

    def row(label: str, pick: np.ndarray, values: np.ndarray, chosen: str) -> None:
        worst = int(np.flatnonzero(pick)[np.argmax(values[pick])])
        old_worst = int(np.flatnonzero(pick)[np.argmax(old[pick])])
        mean, ratio = values[pick].mean(), values[pick] / oracle[pick]
        print(f"| {label} | {pick.sum()} | {chosen} | {mean:.3f} | {np.median(values[pick]):.3f} "
              f"| {stems[worst]} {values[worst]:.3f} | {oracle[pick].mean():.3f} | "
              f"{mean / oracle[pick].mean():.2f} | {ratio.max():.2f} | {old[pick].mean():.3f} | "
              f"{stems[old_worst]} {old[old_worst]:.3f} | {np.max(old[pick] / oracle[pick]):.2f} |")

    for held_out in sorted(set(sessions)):
        test = sessions == held_out
        chosen = choose_adaptive_scale(errors, oracle, ~test)
        out_of_fold[test] = errors[chosen][test]
        row(held_out, test, errors[chosen], f"{chosen:g}")
    everything = np.ones(len(stems), bool)
    row("**all, out of fold**", everything, out_of_fold, "per fold")
    final = choose_adaptive_scale(errors, oracle, everything)
    row("all, in sample (the default)", everything, errors[final], f"{final:g}")


def pyshoe(python: Path | None) -> None:
    files = sorted((DATA / "pyshoe_vicon").glob("*.mat"))
    if not files:
        print("pyshoe_vicon: not found, skipped")
        return
    names = ["suh", "rts", "ekf", "no valley", "no shock", "shock always", *(["gaitmap"] if python else []),
             "oracle", "oracle (IMU)", "suh@oracle-zv", "old default"]
    options = {"suh": {}, "rts": {"smoother": "rts"}, "ekf": {"smoother": "none"},
               "no valley": {"valley": False}, "no shock": {"acc_shock": 1000.0},
               "shock always": {"shock_stance_s": 0.0}}
    default_scale = FootTrajectoryParams().adaptive_scale
    candidates: dict[float, list[float]] = {c: [] for c in ADAPTIVE_CANDIDATES}
    print(f"\n## pyshoe_vicon: ARMSE (m) of {len(files)} trials\n")
    print("| trial | " + " | ".join(names) + " | strides |")
    print("|---" * (len(names) + 2) + "|")
    scores: dict[str, list[float]] = {n: [] for n in names}
    running = []
    for path in files:
        d = sio.loadmat(path, squeeze_me=True)
        imu, gt = d["imu"], d["gt"]
        rate = float(1.0 / np.median(np.diff(d["ts"])))
        gyr, acc = imu[:, 3:6], imu[:, 0:3]
        row = {}
        for name, option in options.items():
            result = estimate_foot_trajectory(gyr, acc, rate, **option)
            row[name] = _tracked(result["position"], gt)
            if name == "suh":
                strides = len(result["strides"])
        if python:
            row["gaitmap"] = armse(gaitmap_rts(python, gyr, acc, rate), gt)
        row["oracle"] = float(d["best_error"])
        row["oracle (IMU)"] = float(np.min(np.atleast_1d(d["trial_error"])[:4]))
        row["suh@oracle-zv"] = _oracle_zv(gyr, acc, rate, d[f"zv_{d['best_detector']}_opt"].astype(bool), gt)
        for c in ADAPTIVE_CANDIDATES:
            candidates[c].append(row["suh"] if c == default_scale else _tracked(
                estimate_foot_trajectory(gyr, acc, rate, adaptive_scale=c)["position"], gt))
        row["old default"] = candidates[0.0][-1]
        for n in names:
            scores[n].append(row[n])
        running.append(path.stem.startswith(RUNNING))
        cells = " | ".join(f"{row[n]:.3f}" for n in names)
        print(f"| {path.stem} | {cells} | {strides} |")
    run = np.array(running)
    half_a = np.arange(len(run)) % 2 == 0
    for label, pick in (("mean", np.ones(len(run), bool)), ("median", None), ("mean, 9 running", run),
                        ("mean, 19 others", ~run), ("mean, half A", half_a), ("mean, half B", ~half_a)):
        values = [np.median(scores[n]) if pick is None else np.mean(np.array(scores[n])[pick]) for n in names]
        cells = " | ".join(f"{v:.3f}" for v in values)
        print(f"| **{label}** | {cells} | |")
    ours, oracle = np.array(scores["suh"]), np.array(scores["oracle"])
    print(f"\nsuh within 1.5x of the oracle on {(ours <= 1.5 * oracle).sum()}/{len(ours)} trials, "
          f"better on {(ours <= oracle).sum()}")
    cross_validate([p.stem for p in files], {c: np.array(v) for c, v in candidates.items()},
                   np.array(scores["oracle (IMU)"]))


def _oracle_zv(gyr, acc, rate, zero_velocity, gt) -> float:
    """Our filter and Suh smoother (default noise) with given zero-velocity labels (the detector out)."""
    from gait_biofeedback.batch import FootTrajectoryParams
    from gait_biofeedback.core.spatial.kalman import filter_recording
    from gait_biofeedback.core.spatial.smoother import suh_smooth

    noise = FootTrajectoryParams().noise
    kf = filter_recording(gyr, acc, rate, zero_velocity, noise)
    return armse(suh_smooth(kf.steps, kf.noise)["position"], gt[int(np.argmax(zero_velocity)):])


def _marker_pitch(heel: np.ndarray, toe: np.ndarray) -> np.ndarray:
    """Heel → toe pitch (rad, toes up positive) of marker trajectories (N, 3)."""
    v = toe - heel
    return np.arctan2(v[:, 2], np.linalg.norm(v[:, :2], axis=1))


def _mocap(folder: Path) -> dict[str, np.ndarray]:
    """gaitmap_example's marker trajectories (``<marker>_<axis>``, m, 100 Hz)."""
    import csv

    with (folder / "mocap_sample.csv").open() as handle:
        rows = list(csv.reader(handle))
    names = [f"{m}_{a}" for m, a in zip(rows[0][1:], rows[1][1:], strict=True)]
    return {n: np.array([float(r[i + 1]) for r in rows[2:]]) / 1000.0 for i, n in enumerate(names)}


def _forward_positions(imu, rate: float) -> np.ndarray:
    """The live stream's forward filter position at each sample (no smoothing; NaN before the start)."""
    stream = FootTrajectoryStream(rate, keep_all=True)
    for k in range(len(imu.gyr)):
        stream.update(round(k * 1e9 / rate), imu.gyr[k], imu.acc[k])
    stream.flush()
    index = np.array(stream.index)
    out = np.full((len(imu.gyr), 3), np.nan)
    out[index[index >= 0]] = np.array([s.r for s in stream.kept])[index >= 0]
    return out


PROVISIONAL_LEARN = 5  # strides whose remaining travel (IC -> next stance) is averaged


def gaitmap_example(python: Path | None) -> None:
    folder = DATA / "gaitmap_example"
    if not folder.exists():
        print("gaitmap_example: not found, skipped")
        return
    import csv

    rec = import_gaitmap(folder)
    rate = GAITMAP_RATE_HZ
    mocap = _mocap(folder)
    with (folder / "stride_events_sample.csv").open() as handle:
        ref = list(csv.DictReader(handle))
    keys = ("length", "no shock", "live", "gaitmap", "provisional", "ic", "tc")
    err: dict[str, list[float]] = {k: [] for k in keys}
    straight, matched = [], 0
    for side in ("left", "right"):
        imu = rec.imu[f"{side}_foot"]
        result = estimate_foot_trajectory(imu.gyr, imu.acc, rate)
        strides, live = result["strides"], {s["foot_flat"]: s for s in result["live_strides"]}
        no_shock = estimate_foot_trajectory(imu.gyr, imu.acc, rate, acc_shock=1000.0)["strides"]
        forward = _forward_positions(imu, rate)
        theirs = gaitmap_rts(python, imu.gyr, imu.acc, rate) if python else None
        letter = side[0].upper()
        heel = np.stack([mocap[f"{letter}_FCC_{a}"] for a in "xyz"], axis=1)
        toe = np.stack([mocap[f"{letter}_TOE_{a}"] for a in "xyz"], axis=1)
        pitch = _marker_pitch(heel, toe)
        remainders: list[np.ndarray] = []  # this foot's travel from IC + 25 ms to the next stance
        for r in (r for r in ref if r["foot"] == side):
            start, end, ic = (float(r[k]) for k in ("start", "end", "ic"))

            def same(s, start=start, end=end, ic=ic):
                return s["stance_start"] <= start + 20 and s["foot_off"] >= start - 20 and ic - 40 <= s[
                    "foot_flat"] <= end + 40

            ours = [s for s in strides if same(s)]
            others = [s for s in no_shock if same(s)]
            if len(ours) != 1 or len(others) != 1 or ours[0]["foot_flat"] not in live:
                remainders = []
                continue
            s = ours[0]
            matched += 1
            m0, m1 = round(start * 100 / rate), round(end * 100 / rate)
            true_length = float(np.linalg.norm(heel[m1, :2] - heel[m0, :2]))
            err["length"].append(s["stride_length"] - true_length)
            err["no shock"].append(others[0]["stride_length"] - true_length)
            err["live"].append(live[s["foot_flat"]]["stride_length"] - true_length)
            if theirs is not None:
                a, b = round(start), round(end)
                err["gaitmap"].append(float(np.linalg.norm(theirs[b, :2] - theirs[a, :2])) - true_length)
            # provisional at IC + 50 ms: the forward filter is 25 ms behind (the detector's look-ahead)
            first = forward[s["stance_start"]:s["foot_off"] + 1].mean(axis=0)
            now = forward[round(ic + 0.025 * rate)]
            travel = (now - first)[:2]
            ahead = travel / np.linalg.norm(travel)
            left = np.array([-ahead[1], ahead[0]])
            rest = (forward[s["foot_flat"]:s["end"] + 1].mean(axis=0) - now)[:2]
            if len(remainders) >= 2:
                mean_rest = np.mean(remainders[-PROVISIONAL_LEARN:], axis=0)
                guess = travel + mean_rest[0] * ahead + mean_rest[1] * left
                err["provisional"].append(float(np.linalg.norm(guess)) - true_length)
            remainders.append(np.array([rest @ ahead, rest @ left]))
            heading = [np.arctan2(*(toe[k, 1::-1] - heel[k, 1::-1])) for k in (m0, m1)]
            straight.append(abs(np.angle(np.exp(1j * (heading[1] - heading[0])))) < np.radians(10.0))
            off, flat = round(s["foot_off"] * 100 / rate), round(s["foot_flat"] * 100 / rate)
            mid = (off + flat) // 2
            # the same definitions on the markers: extremes of the swing halves, relative to the stances
            err["tc"].append(s["foot_angle_tc"] - (pitch[off:mid + 1].min() - pitch[off]))
            err["ic"].append(s["foot_angle_ic"] - (pitch[mid:flat + 1].max() - pitch[flat]))
    print(f"\n## gaitmap_example: {matched} of {len(ref)} reference strides matched\n")
    print("| quantity | n | mean error | SD | mean abs error | RMSE |")
    print("|---|---|---|---|---|---|")
    rows = (("length", "stride length", 100.0, "cm"),
            ("no shock", "stride length, acc_shock off", 100.0, "cm"),
            ("live", "stride length, live (RTS per stride)", 100.0, "cm"),
            ("gaitmap", "stride length, gaitmap RtsKalman", 100.0, "cm"),
            ("provisional", "stride length, provisional at IC + 50 ms", 100.0, "cm"),
            ("ic", "foot angle at IC", 180 / np.pi, "°"), ("tc", "foot angle at TC", 180 / np.pi, "°"))
    for key, label, scale, unit in rows:
        if not err[key]:
            continue
        e = np.array(err[key]) * scale
        print(f"| {label} | {len(e)} | {e.mean():+.1f} {unit} | {e.std():.1f} | {np.abs(e).mean():.1f} | "
              f"{np.sqrt(np.mean(e**2)):.1f} |")
    e, turns = np.array(err["length"]) * 100, ~np.array(straight)
    print(f"\nstride length by the markers' heading change: {(~turns).sum()} straight "
          f"{e[~turns].mean():+.1f} ± {e[~turns].std():.1f} cm, {turns.sum()} turning "
          f"{e[turns].mean():+.1f} ± {e[turns].std():.1f} cm")
    if err["gaitmap"]:
        corr = np.corrcoef(err["no shock"], err["gaitmap"])[0, 1]
        print(f"correlation of the stride-length errors, acc_shock off vs gaitmap's RtsKalman: {corr:.2f}")


def simulator() -> None:
    print("\n## simulator walk (seed 2), every stride but the first and the last\n")
    print("| rate | strides | stride length error (mm, mean ± SD) | speed error (m/s, max) "
          "| height error (mm, max) |")
    print("|---|---|---|---|---|")
    for rate in (100.0, 200.0):
        s = simulate(SCENARIOS["walk"](30.0, seed=2, segments=("left_foot",), rate_hz=rate))
        imu, truth = s.imu["left_foot"], s.truth.sensor_position["left_foot"]
        strides = estimate_foot_trajectory(imu.gyr, imu.acc, rate)["strides"][1:-1]
        length, speed, height = [], [], []
        for x in strides:
            first = truth[x["stance_start"]:x["foot_off"] + 1].mean(axis=0)
            second = truth[x["foot_flat"]:x["end"] + 1].mean(axis=0)
            true_length = np.linalg.norm((second - first)[:2])
            length.append(x["stride_length"] - true_length)
            time_s = (x["foot_flat"] - x["stance_start"]) / rate
            speed.append(x["gait_speed"] - true_length / time_s)
            true_height = truth[x["foot_off"]:x["foot_flat"] + 1, 2].max() - first[2]
            height.append(x["max_sensor_height"] - true_height)
        e = np.array(length) * 1000
        print(f"| {rate:g} Hz | {len(strides)} | {e.mean():+.1f} ± {e.std():.1f} | "
              f"{np.nanmax(np.abs(speed)):.3f} | {np.max(np.abs(height)) * 1000:.1f} |")


def _live_strides(imu, keep: np.ndarray) -> dict[int, float]:
    stream = FootTrajectoryStream(imu.rate_hz)
    out = []
    for k in np.flatnonzero(keep):
        out += stream.update(round(imu.t[k] * 1e9), imu.gyr[k], imu.acc[k])
    return {s.foot_flat_ns: s.stride_length for s in out}


def lost_samples() -> None:
    print("\n## lost samples: live strides against the same stream on every sample (simulator walk, 60 s)\n")
    print("| rate | samples lost | strides | without values | error of the others (cm): median | p95 | max |")
    print("|---|---|---|---|---|---|---|")
    rng = np.random.default_rng(1)
    for rate in (100.0, 200.0):
        session = simulate(SCENARIOS["walk"](60.0, seed=2, segments=("left_foot",), rate_hz=rate))
        imu = session.imu["left_foot"]
        n, stride_n = len(imu.t), round(1.11 * rate)
        reference = _live_strides(imu, np.ones(n, bool))
        cases = ([(f"{g} per stride", g, None) for g in (1, 2)]
                 + [(f"{f:.0%} at random", 0, f) for f in (0.01, 0.03)])
        for label, gap, fraction in cases:
            errors, unknown, total = [], 0, 0
            for _ in range(10):
                keep = rng.random(n) > fraction if fraction else np.ones(n, bool)
                for start in (range(5 * round(rate), n - 2 * round(rate), stride_n) if gap else ()):
                    first = start + rng.integers(0, stride_n)
                    keep[first:first + gap] = False
                for flat_ns, length in _live_strides(imu, keep).items():
                    total += 1
                    match = min(reference, key=lambda ns, f=flat_ns: abs(ns - f))
                    if not np.isfinite(length):
                        unknown += 1
                    elif abs(match - flat_ns) < 30_000_000:
                        errors.append(abs(length - reference[match]) * 100)
            e = np.array(errors)
            print(f"| {rate:g} Hz | {label} | {total} | {unknown / total:.0%} | {np.median(e):.2f} | "
                  f"{np.percentile(e, 95):.2f} | {e.max():.2f} |")


def _cli(*args: str) -> None:
    subprocess.run([str(REPO / ".venv" / "bin" / "python"), "-m", "gait_biofeedback.cli", *args], check=True,
                   stdout=subprocess.DEVNULL)


def _cycles(bag: Path) -> tuple[list, list]:
    """(the ``gait/cycles`` messages as published, with log times; the same revised by
    ``gait/stride_space``, the values of record, with the revisions' log times)."""
    from gait_biofeedback.io.bag_reader import BagReader
    from gait_biofeedback.wire.gait import revised_cycles

    records = list(BagReader(bag).messages(["/gait/cycles", "/gait/stride_space"]))
    published = [(copy.deepcopy(msg), log_ns) for topic, msg, log_ns in records if topic == "/gait/cycles"]
    last_log = {(msg.side, msg.stride_index): log_ns for _, msg, log_ns in records}
    revised = revised_cycles((topic, msg) for topic, msg, _ in records)
    return published, [(msg, last_log[(msg.side, msg.stride_index)]) for msg in revised]


def _s(stamp) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def _score_cli(label: str, cycles: list, folder: Path) -> None:
    """One row: ``cycles`` ((message, log ns)) against the heel marker's footprints (where it is
    slowest in the 0.4 s after each IC), gait speed over the mocap IC→IC time."""
    import csv

    mocap = _mocap(folder)
    t_mocap = np.arange(len(next(iter(mocap.values())))) / 100.0
    with (folder / "stride_events_sample.csv").open() as handle:
        reference = list(csv.DictReader(handle))
    mocap_ic = {side: np.array(sorted(float(r["ic"]) for r in reference if r["foot"] == side))
                / GAITMAP_RATE_HZ for side in ("left", "right")}
    errors, speeds, lags, flagged = [], [], [], 0
    for msg, log_ns in cycles:
        if msg.spatial_flag or not np.isfinite(msg.stride_length):
            flagged += 1
            continue
        heel = np.stack([mocap[f"{'LR'[msg.side]}_FCC_{a}"] for a in "xy"], axis=1)

        def footprint(t: float, heel=heel) -> np.ndarray:
            k = np.flatnonzero((t_mocap >= t) & (t_mocap <= t + 0.4))
            return heel[k[np.argmin(np.linalg.norm(np.diff(heel[k], axis=0), axis=1))]]

        t0, t1 = _s(msg.start), _s(msg.header.stamp)
        true_length = float(np.linalg.norm(footprint(t1) - footprint(t0)))
        errors.append(msg.stride_length - true_length)
        lags.append(log_ns * 1e-9 - t1)
        ics = mocap_ic[("left", "right")[msg.side]]
        near = [ics[np.argmin(np.abs(ics - t))] for t in (t0, t1)]
        if all(abs(m - t) < 0.2 for m, t in zip(near, (t0, t1), strict=True)):
            speeds.append(msg.gait_speed / (true_length / (near[1] - near[0])) - 1.0)
    e, v, lag = np.array(errors) * 100, np.array(speeds) * 100, np.array(lags) * 1000
    print(f"| {label} | {len(cycles)} | {flagged} | {e.mean():+.1f} ± {e.std():.1f} cm | "
          f"{np.abs(e).mean():.1f} cm | {v.mean():+.1f} ± {v.std():.1f} % | {np.abs(v).mean():.1f} % | "
          f"{np.median(lag):.0f} ms ({lag.min():.0f}-{lag.max():.0f}) |")


def _against_record(published: list, of_record: list) -> str:
    """How the provisional values among ``published`` differ from their values of record."""
    record = {(m.side, m.stride_index): m.stride_length for m, _ in of_record}
    d = np.array([m.stride_length - record[(m.side, m.stride_index)] for m, _ in published
                  if m.spatial_provisional and np.isfinite(record[(m.side, m.stride_index)])]) * 100
    if not len(d):
        return f"0 of {len(published)} strides provisional"
    return (f"{len(d)} of {len(published)} strides provisional, {d.mean():+.1f} ± {d.std():.1f} cm from "
            f"their values of record (95th percentile of |difference| {np.percentile(np.abs(d), 95):.1f} cm)")


def _swing_against_record(published: list, of_record: list) -> str:
    """How the provisional swing values among ``published`` differ from their values of record."""
    record = {(m.side, m.stride_index): m for m, _ in of_record}
    cells = []
    for name, scale, unit in (("max_foot_height", 100, "cm"), ("foot_angle_ic", np.degrees(1), "°"),
                              ("foot_angle_tc", np.degrees(1), "°"), ("turning_angle", np.degrees(1), "°"),
                              ("lateral_excursion", 100, "cm"), ("min_toe_clearance", 100, "cm")):
        d = np.array([getattr(m, name) - getattr(record[(m.side, m.stride_index)], name) for m, _ in published
                      if m.spatial_provisional]) * scale
        d = d[np.isfinite(d)]
        if len(d):
            cells.append(f"{name} {d.mean():+.1f} ± {d.std():.1f} {unit} (95th percentile of |difference| "
                         f"{np.percentile(np.abs(d), 95):.1f}, n {len(d)})")
    pairs = [(m.turning_angle, record[(m.side, m.stride_index)].turning_angle) for m, _ in published
             if m.spatial_provisional and np.isfinite(m.turning_angle)]
    pairs = [(a, b) for a, b in pairs if np.isfinite(b)]
    if pairs:
        same = sum((abs(a) > TURN_LIMIT) == (abs(b) > TURN_LIMIT) for a, b in pairs)
        turns = sum(abs(b) > TURN_LIMIT for _, b in pairs)
        cells.append(f"turn or straight (20°, no spatial cue in a turn) told as the record tells it: "
                     f"{same} of {len(pairs)} ({turns} turns of record)")
    return "; ".join(cells) or "no provisional swing values"


def through_the_command_line(provisional_after_s: float | None = None) -> None:
    """The user's path: ``import`` → ``analyze`` → the ``gait/cycles`` messages' spatial values, as
    published (provisional ones included) and as of record (``gait/stride_space`` applied), with the
    provisional values' trust check (``provisional_tolerance_m``), and with 1 m instead."""
    print("\n## through the command line (import → analyze → /gait/cycles, /gait/stride_space)\n")
    folder = DATA / "gaitmap_example"
    untested = "    provisional_tolerance_m: 1.0\n"
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        if folder.exists():
            params = f"    use_standing_reference: true\n    rate_hz: {GAITMAP_RATE_HZ}\n"
            if provisional_after_s is not None:
                params += f"    provisional_after_s: {provisional_after_s}\n"
            _cli("import", "gaitmap", str(folder), "-o", str(tmp / "gm"))
            print("| values | strides | without values | stride length: mean ± SD | mean abs | gait speed: "
                  "mean ± SD | mean abs | published after the closing IC: median (range) |")
            print("|---|---|---|---|---|---|---|---|")
            swing = []
            for label, extra in (("", ""), (", tolerance 1 m", untested)):
                (tmp / "params.yaml").write_text("/**/gait_events:\n  ros__parameters:\n" + params + extra)
                _cli("analyze", str(tmp / "gm"), "-o", str(tmp / "gm_out"), "--params",
                     str(tmp / "params.yaml"), "--overwrite")
                published, of_record = _cycles(tmp / "gm_out")
                _score_cli("as published" + label, published, folder)
                provisional = [(m, t) for m, t in published if m.spatial_provisional]
                _score_cli("provisional only" + label, provisional, folder)
                swing.append(f"gaitmap_example{label}, provisional against the values of record: "
                             + _swing_against_record(published, of_record))
            _score_cli("of record (smoothed)", of_record, folder)
            print("\n" + "\n".join(swing))
        qmt = DATA / "qmt_fullbody" / "full_body_example_data.mat"
        if qmt.exists():
            _cli("import", "qmt_fullbody", str(qmt), "-o", str(tmp / "qmt"))
            for label, extra in (("", ""), (", tolerance 1 m", untested)):
                (tmp / "qmt.yaml").write_text("/**/gait_events:\n  ros__parameters:\n"
                                              "    use_standing_reference: true\n" + extra)
                _cli("analyze", str(tmp / "qmt"), "-o", str(tmp / "qmt_out"), "--params",
                     str(tmp / "qmt.yaml"), "--calibrate-at", "75:walking", "--overwrite")
                published, of_record = _cycles(tmp / "qmt_out")
                print(f"qmt_fullbody{label} (no truth): " + _against_record(published, of_record))
                print(f"  provisional swing values: {_swing_against_record(published, of_record)}")
            lengths = np.array([m.stride_length for m, _ in of_record if not m.spatial_flag])
            print(f"qmt_fullbody (no truth): {len(of_record)} strides, {len(of_record) - len(lengths)} "
                  f"flagged without spatial values; stride length median {np.median(lengths):.2f} m, largest "
                  f"{lengths.max():.2f} m")


GYRO_LIMIT_GRID = (0.15, 0.2, 0.3, 0.4, 0.6)  # rad/s; the default is 0.4


def gyro_limit_grid() -> None:
    """Table 6 of the module docstring."""
    files = sorted((DATA / "pyshoe_vicon").glob("*.mat"))
    if not files:
        print("pyshoe_vicon: not found, skipped")
        return
    default, by_onset, best, oracle = [], [], [], []
    for path in files:
        d = sio.loadmat(path, squeeze_me=True)
        gyr, acc = d["imu"][:, 3:6], d["imu"][:, 0:3]
        rate = float(1.0 / np.median(np.diff(d["ts"])))
        scores, onset_speeds = [], []
        for limit in GYRO_LIMIT_GRID:
            scores.append(_tracked(estimate_foot_trajectory(gyr, acc, rate, gyro_limit=limit)["position"],
                                   d["gt"]))
            forward = estimate_foot_trajectory(gyr, acc, rate, gyro_limit=limit, smoother="none")
            zv, v = forward["zero_velocity"], forward["velocity"]
            onsets = np.flatnonzero(zv[1:] & ~zv[:-1])  # the sample before each stance
            speed = np.linalg.norm(v[onsets], axis=1)
            speed = speed[np.isfinite(speed)]
            onset_speeds.append(float(np.sqrt(np.mean(speed ** 2))) if len(speed) else np.inf)
        default.append(scores[GYRO_LIMIT_GRID.index(0.4)])
        by_onset.append(scores[int(np.argmin(onset_speeds))])
        best.append(min(scores))
        oracle.append(float(d["best_error"]))
    print(f"\n## pyshoe_vicon, one gyro_limit per trial from {GYRO_LIMIT_GRID} rad/s: mean ARMSE of "
          f"{len(files)} trials\n")
    print("| default 0.4 | least RMS speed at the stance onsets | best per trial (with the Vicon) | oracle |")
    print("|---|---|---|---|")
    print(f"| {np.mean(default):.3f} m | {np.mean(by_onset):.3f} m | {np.mean(best):.3f} m | "
          f"{np.mean(oracle):.3f} m |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-gaitmap", action="store_true", help="leave gaitmap's RtsKalman out")
    parser.add_argument("--lost-samples", action="store_true", help="only the lost-samples table")
    parser.add_argument("--cli-only", action="store_true", help="only the command-line table")
    parser.add_argument("--gyro-limit-grid", action="store_true", help="only the pyshoe table of one "
                        "zero-velocity threshold per trial (about 5 min)")
    parser.add_argument("--pyshoe-only", action="store_true", help="only the pyshoe_vicon table (with "
                        "--no-gaitmap: about 6 min, with the cross-validation)")
    parser.add_argument("--provisional-after-s", type=float, help="gait_events provisional_after_s for the "
                        "command-line table (default: the parameter's)")
    args = parser.parse_args()
    t0 = time.monotonic()
    if args.lost_samples:
        lost_samples()
        return
    if args.cli_only:
        through_the_command_line(args.provisional_after_s)
        return
    if args.gyro_limit_grid:
        gyro_limit_grid()
        return
    python = None if args.no_gaitmap else gaitmap_python()
    if args.pyshoe_only:
        pyshoe(python)
        return
    through_the_command_line(args.provisional_after_s)
    simulator()
    gaitmap_example(python)
    pyshoe(python)
    print(f"\n({time.monotonic() - t0:.0f} s)")


if __name__ == "__main__":
    main()
