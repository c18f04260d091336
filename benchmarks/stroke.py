"""The stroke quantities (issue 49, docs/guide/stroke.md) against ground truth.

Run: ``.venv/bin/python benchmarks/stroke.py --seeds 3 4`` (about 25 s of CPU in all on this
machine, gaitmap_example and qmt_fullbody included).

1. The simulated hemiparetic walker (``simulate --scenario hemiparetic --duration 30``, paretic left),
   through ``analyze`` (calibration on the walk at 12 s) and the report's evaluator, against the
   simulator's own truth (``sim/stride_truth.py``), stride by stride (matched by side and closing IC
   within 50 ms): n, mean ± SD and largest error per quantity and side; then the paretic ratios of
   the last stride against the true ratio of the same strides' means.
2. gaitmap_example (Vicon foot markers, 204.8 Hz foot IMUs; ``../shared/data/README.md``): each
   reference stride's foot strike angle (the foot trajectory's, as ``foot_strike_angle``) against the
   heel → toe marker pitch (the same definition on the markers: the swing's largest pitch in its
   second half relative to the next stance), and its swing foot clearance (the sensor's highest rise)
   beside the heel and toe markers' highest rises above their stance (the sensor's own point has no
   marker). No recording here has hip markers.
3. qmt_fullbody (a real healthy walk with 16 IMUs, no reference: plausibility only), through ``import``
   and ``analyze`` as ``benchmarks/spatial.py`` runs it (walking calibration at 75 s): each per-side
   quantity's median and range over the used strides, beside the healthy bands of config/targets.yaml
   (about 60 s more; ``--no-qmt`` leaves it out).
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import io
import math
import tempfile
from pathlib import Path

import numpy as np

from gait_biofeedback.batch import estimate_foot_trajectory, import_gaitmap
from gait_biofeedback.cli import main as cli
from gait_biofeedback.core.biofeedback.evaluator import default_targets_path, load_targets
from gait_biofeedback.report.analysis import analyse_session
from gait_biofeedback.report.extract import read_session
from gait_biofeedback.sim.simulator import hemiparetic, simulate
from gait_biofeedback.sim.stride_truth import stride_truth

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data"
GAITMAP_RATE_HZ = 204.8
PER_STRIDE = (("trailing_limb_angle", "°"), ("propulsion", "°"), ("knee_hyperextension_stance", "°"),
              ("foot_strike_angle", "°"), ("swing_foot_clearance", "cm"), ("step_length", "cm"))
SCALE = {"°": 180.0 / math.pi, "cm": 100.0}


def _run(*argv: str) -> None:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = cli(list(argv))
    if rc != 0:
        raise RuntimeError(f"gait-biofeedback {' '.join(argv)}: {err.getvalue()[-2000:]}")


def simulated(seed: int, duration: float = 30.0) -> tuple[dict, dict]:
    """(errors per (quantity, side), {ratio: (measured, true)}) of one simulated hemiparetic walk."""
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        _run("simulate", "--scenario", "hemiparetic", "--duration", str(duration), "--seed", str(seed),
             "-o", str(root / "raw"))
        _run("analyze", str(root / "raw"), "-o", str(root / "analyzed"), "--calibrate-at", "12:walking")
        targets = load_targets(default_targets_path(), "left")
        analysis = analyse_session(read_session(root / "analyzed"), targets)
    truth = stride_truth(simulate(hemiparetic(duration=duration, seed=seed)))
    errors: dict[tuple[str, str], list[float]] = {}
    last = None
    for row in analysis.used:
        same = [tr for tr in truth if tr["side"] == row["side"] and abs(tr["t_end"] - row["end_s"]) < 0.05]
        if len(same) != 1:
            continue
        last = (row, same[0])
        for name, _ in PER_STRIDE:
            if math.isfinite(row.get(name, math.nan)):
                errors.setdefault((name, row["side"]), []).append(row[name] - same[0][name])
    ratios = {}
    if last is not None:
        row, tr_last = last
        before = [tr for tr in truth if tr["t_end"] <= tr_last["t_end"] + 1e-6]
        for ratio, name in (("step_length_asymmetry_paretic", "step_length"),
                            ("stance_time_asymmetry_paretic", "stance_time")):
            side = {s: [tr[name] for tr in before if tr["side"] == s][-10:] for s in ("left", "right")}
            ratios[ratio] = (row.get(ratio, math.nan), float(np.mean(side["left"]) / np.mean(side["right"])))
    return errors, ratios


def simulator_table(seeds: list[int]) -> None:
    errors: dict[tuple[str, str], list[float]] = {}
    ratios: list[tuple[int, str, float, float]] = []
    for seed in seeds:
        e, r = simulated(seed)
        for key, values in e.items():
            errors.setdefault(key, []).extend(values)
        ratios.extend((seed, name, measured, true) for name, (measured, true) in r.items())
    print(f"\n## Simulated hemiparetic walker (paretic left), seeds {seeds}: estimate - truth\n")
    print("| quantity | side | n | mean ± SD | largest |")
    print("|---|---|---|---|---|")
    for name, unit in PER_STRIDE:
        for side in ("left", "right"):
            e = np.array(errors.get((name, side), [])) * SCALE[unit]
            if len(e):
                print(f"| {name} | {side}{' (paretic)' if side == 'left' else ''} | {len(e)} | "
                      f"{e.mean():+.2f} ± {e.std():.2f} {unit} | {np.abs(e).max():.2f} {unit} |")
    print("\n| ratio (last stride's window) | seed | measured | true |")
    print("|---|---|---|---|")
    for seed, name, measured, true in ratios:
        print(f"| {name} | {seed} | {measured:.3f} | {true:.3f} |")


def _marker_pitch(heel: np.ndarray, toe: np.ndarray) -> np.ndarray:
    v = toe - heel
    return np.arctan2(v[:, 2], np.linalg.norm(v[:, :2], axis=1))


def gaitmap_table() -> None:
    folder = DATA / "gaitmap_example"
    if not folder.exists():
        print("\ngaitmap_example: not found in ../shared/data, skipped")
        return
    with (folder / "mocap_sample.csv").open() as handle:
        rows = list(csv.reader(handle))
    names = [f"{m}_{a}" for m, a in zip(rows[0][1:], rows[1][1:], strict=True)]
    mocap = {n: np.array([float(r[i + 1]) for r in rows[2:]]) / 1000.0 for i, n in enumerate(names)}
    with (folder / "stride_events_sample.csv").open() as handle:
        ref = list(csv.DictReader(handle))
    rec = import_gaitmap(folder)
    strike, ours, heel_rise, toe_rise = [], [], [], []
    for side in ("left", "right"):
        imu = rec.imu[f"{side}_foot"]
        strides = estimate_foot_trajectory(imu.gyr, imu.acc, GAITMAP_RATE_HZ)["strides"]
        letter = side[0].upper()
        heel = np.stack([mocap[f"{letter}_FCC_{a}"] for a in "xyz"], axis=1)
        toe = np.stack([mocap[f"{letter}_TOE_{a}"] for a in "xyz"], axis=1)
        pitch = _marker_pitch(heel, toe)
        for r in (r for r in ref if r["foot"] == side):
            start, end, ic = (float(r[k]) for k in ("start", "end", "ic"))
            same = [s for s in strides if s["stance_start"] <= start + 20 and s["foot_off"] >= start - 20
                    and ic - 40 <= s["foot_flat"] <= end + 40]
            if len(same) != 1:
                continue
            s = same[0]
            off, flat = (round(s[k] * 100 / GAITMAP_RATE_HZ) for k in ("foot_off", "foot_flat"))
            first = round(s["stance_start"] * 100 / GAITMAP_RATE_HZ)
            mid = (off + flat) // 2
            strike.append(s["foot_angle_ic"] - (pitch[mid:flat + 1].max() - pitch[flat]))
            ours.append(s["max_sensor_height"])
            heel_rise.append(heel[off:flat + 1, 2].max() - heel[first:off + 1, 2].mean())
            toe_rise.append(toe[off:flat + 1, 2].max() - toe[first:off + 1, 2].mean())
    e = np.degrees(strike)
    print(f"\n## gaitmap_example (Vicon foot markers), {len(e)} strides\n")
    print(f"foot_strike_angle - heel→toe marker pitch: {e.mean():+.1f} ± {e.std():.1f}°, largest "
          f"{np.abs(e).max():.1f}°")
    o, h, t = (100 * np.array(x) for x in (ours, heel_rise, toe_rise))
    print(f"swing_foot_clearance (sensor) {o.mean():.1f} ± {o.std():.1f} cm; the heel marker's highest rise "
          f"{h.mean():.1f} ± {h.std():.1f} cm, the toe's {t.mean():.1f} ± {t.std():.1f} cm; correlation of "
          f"the sensor's with the heel's over strides {np.corrcoef(o, h)[0, 1]:.2f}, with the toe's "
          f"{np.corrcoef(o, t)[0, 1]:.2f}")


def qmt_table() -> None:
    qmt = DATA / "qmt_fullbody" / "full_body_example_data.mat"
    if not qmt.exists():
        print("\nqmt_fullbody: not found in ../shared/data, skipped")
        return
    targets = load_targets(default_targets_path())
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        _run("import", "qmt_fullbody", str(qmt), "-o", str(root / "qmt"))
        (root / "qmt.yaml").write_text("/**/gait_events:\n  ros__parameters:\n"
                                       "    use_standing_reference: true\n")
        _run("analyze", str(root / "qmt"), "-o", str(root / "out"), "--params", str(root / "qmt.yaml"),
             "--calibrate-at", "75:walking")
        analysis = analyse_session(read_session(root / "out"), targets)
    print(f"\n## qmt_fullbody (real healthy walk, no reference): {len(analysis.used)} strides used\n")
    print("| quantity | left: median (range), n | right | healthy band (targets.yaml) |")
    print("|---|---|---|---|")
    for name, unit in PER_STRIDE[:-1]:
        cells = []
        for side in ("left", "right"):
            v = np.array([r[name] for r in analysis.used if r["side"] == side
                          and math.isfinite(r.get(name, math.nan))]) * SCALE[unit]
            cells.append(f"{np.median(v):.1f} ({v.min():.1f} to {v.max():.1f}), {len(v)}" if len(v) else "–")
        band = targets.band(name, "left")
        print(f"| {name} ({unit}) | {cells[0]} | {cells[1]} | {band.low * SCALE[unit]:.1f} to "
              f"{band.high * SCALE[unit]:.1f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[3])
    parser.add_argument("--no-gaitmap", action="store_true")
    parser.add_argument("--no-qmt", action="store_true")
    args = parser.parse_args()
    simulator_table(args.seeds)
    if not args.no_gaitmap:
        gaitmap_table()
    if not args.no_qmt:
        qmt_table()


if __name__ == "__main__":
    main()
