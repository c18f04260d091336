"""Chest activity monitor (gait_biofeedback.core.activity.monitor) against real and simulated data.

Run: ``.venv/bin/python benchmarks/activity.py`` (about 1 min; ``--rates``: only the HAPT table, with
the phone resampled to 20, 50, 100 and 200 Hz; ``--cli``: only the UCI table with nothing handed and
the HAPT table, each recording through ``import`` → ``analyze``, about 5 min). Prints tables for
- UCI "Activity Recognition from a Single Chest-Mounted Accelerometer" (Casale, Pujol, Radeva 2011;
  CC BY 4.0): per-window posture / locomotion accuracy, confusion matrix, sit→stand detection, split
  into development subjects 1–7 (all thresholds chosen there) and 8–15, held out until the rules of
  2026-12-06 (see SPLIT_NOTE), next to the goals;
- UCI "Activity recognition with healthy older people using a batteryless wearable sensor" (Torres,
  Ranasinghe, Shi, Sample 2013; CC BY 4.0): lying / sitting / upright accuracy;
- the project simulator ("activity" and "stairs" scenarios): transition timing and
  step-count error;
- the per-sample cost of the streaming monitor.
"""

from __future__ import annotations

import glob
import itertools
import shutil
import time
import warnings
from pathlib import Path

import numpy as np

from gait_biofeedback.batch import (
    QMT_FULLBODY_RATE_HZ,
    SCENARIOS,
    ActivityMonitor,
    UnitMismatchWarning,
    classify_activity,
    import_qmt_fullbody,
    quaternion,
    seconds_to_ns,
    simulate,
)

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data"
UCI_RATE = 52.0
WINDOW_S = 5.0
# UCI raw counts: a 12-bit ADC (values 0…4095 seen); the zero-g offset is taken as mid-scale 2048.
# (The dataset note's "≈3650 counts per g" is the norm *including* that offset; without it the
# static norm is 290–495 counts/g per subject and walking has the expected ≈0.25 g vertical SD.)
UCI_OFFSET = 2048.0
CLASSES = ("sitting", "standing", "walking", "stairs")
# Development split: every threshold chosen on UCI data (gait_biofeedback/core/activity.py, "chosen on
# the UCI development subjects") was chosen on subjects 1–7 only; 8–15 were held out and never tuned on.
# All 15 are development data of issue 15 (its held-out subjects are not in ../shared/data).
DEV = tuple(range(1, 8))
HELD_OUT = tuple(range(8, 16))
SPLIT_NOTE = ("h = held out from the thresholds; the three rules without a tuned number of 2026-12-06 (a "
              "quiet reference must show a wearer's breathing, a chest alone starts seated, standing after a "
              "weak sit→stand needs an 8-step walk within a minute) were made looking at subjects 6, 7, 8, "
              "10, 11 and 15")
GOALS = {"posture": 0.95, "walk_vs_stairs": 0.90}  # issue 6


def _truth_class(label: int) -> str | None:
    return {1: "sitting", 3: "standing", 7: "standing", 4: "walking", 6: "walking", 5: "stairs"}.get(label)


def _predicted_class(posture: str, locomotion: str) -> str:
    if locomotion == "level":
        return "walking"
    if locomotion in ("upstairs", "downstairs"):
        return "stairs"
    return posture if posture in ("sitting", "standing") else "sitting"


def _majority(values: np.ndarray) -> str:
    names, counts = np.unique(values, return_counts=True)
    return str(names[np.argmax(counts)])


def _runs(labels: np.ndarray) -> list[tuple[int, int, int]]:
    change = np.flatnonzero(np.diff(labels)) + 1
    starts, ends = np.r_[0, change], np.r_[change, len(labels)]
    return [(int(labels[a]), int(a), int(b)) for a, b in zip(starts, ends, strict=True)]


def uci(handed: bool, cli: bool = False) -> None:
    """``handed``: the monitor is given the reference window and the initial posture from the labels;
    otherwise it is given nothing (automatic reference, initial posture auto: the chest starts seated).
    ``cli`` (nothing handed only): each subject through ``import csv`` → ``analyze`` (:func:`_uci_cli`)."""
    folder = DATA / "uci_chest_casale"
    if not folder.is_dir():
        print(f"[skip] {folder} missing")
        return
    print("\n== UCI chest (Casale et al.), 15 subjects, 52 Hz, 5 s windows inside one label"
          + (", through import -> analyze" if cli else "") + " ==")
    work = None
    if cli:
        import tempfile

        work = Path(tempfile.mkdtemp())
    if handed:
        print("HANDED FROM THE LABELS: reference = first 5 s of the first 'standing' block; initial "
              "posture = sitting (protocol)")
    else:
        print("nothing handed: automatic upright reference (core/activity/reference.py), initial posture "
              "auto (monitor.initial_posture_for: a chest alone starts seated until a walk)")
    confusion = np.zeros((4, 4), int)
    rows = []
    for subject in range(1, 16):
        raw = np.loadtxt(folder / f"{subject}.csv.gz", delimiter=",")
        labels = raw[:, 4].astype(int)
        acc = raw[:, 1:4] - UCI_OFFSET
        runs = _runs(labels)
        stand = next(r for r in runs if r[0] == 3)
        given = {"reference": (stand[1] + int(1 * UCI_RATE), stand[1] + int(6 * UCI_RATE)),
                 "initial_posture": "sitting"} if handed else {}
        if work is not None:
            out = _uci_cli(acc, work)
        else:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UnitMismatchWarning)  # raw counts, rescaled to 1 g
                out = classify_activity(acc, UCI_RATE, units="g", **given)
        win = int(WINDOW_S * UCI_RATE)
        sub = np.zeros((4, 4), int)
        for label, a, b in runs:
            truth = _truth_class(label)
            if truth is None:
                continue
            for k in range(a, b - win + 1, win):
                posture = _majority(out["posture"][k : k + win])
                loco = _majority(out["locomotion"][k : k + win])
                pred = _predicted_class(posture, loco)
                sub[CLASSES.index(truth), CLASSES.index(pred)] += 1
        confusion += sub
        # sit→stand between the end of sitting and the first walk after it (see _stand_up_window)
        found = total = 0
        for (prev, _, _), (label, a, _) in itertools.pairwise(runs):
            if label == 2 and prev == 1:
                total += 1
                lo, hi = _stand_up_window(a / UCI_RATE, out["steps"])
                found += any(k == "sit_to_stand" and lo <= t <= hi for t, k in out["transitions"])
        rows.append((subject, sub, found, total, len(out["transitions"]), out))
    if work is not None:
        shutil.rmtree(work)
    print(f"{'subj':>5} {'posture':>8} {'sit':>6} {'stand':>6} {'walk det':>8} {'lvl/stairs':>10} "
          f"{'SiSt@2':>6} {'#PT':>4} {'cadence':>8}")
    for subject, sub, found, total, n_pt, out in rows:
        p = _scores(sub)
        tag = "d" if subject in DEV else "h"
        print(f"{subject:>4}{tag} {p['posture']:>8.1%} {p['sit']:>6.1%} {p['stand']:>6.1%} "
              f"{p['loco_det']:>8.1%} {p['walk_vs_stairs']:>10.1%} {found:>3}/{total:<2} {n_pt:>4} "
              f"{_cadence(out):>8.0f}")
    print("d = development subject (thresholds chosen on these), " + SPLIT_NOTE)
    print(f"\n{'split':>9} {'posture pooled':>14} {'mean/subj':>9} {'goal':>5} | "
          f"{'walk-vs-stairs pooled':>21} {'mean/subj':>9} {'goal':>5} | {'SiSt found':>10} {'false PT':>8}")
    for name, subjects in (("all", DEV + HELD_OUT), ("dev 1-7", DEV), ("held 8-15", HELD_OUT)):
        chosen = [r for r in rows if r[0] in subjects]
        pooled = _scores(sum(r[1] for r in chosen))
        per = [_scores(r[1]) for r in chosen]
        found = sum(r[2] for r in chosen)
        total = sum(r[3] for r in chosen)
        false_pt = sum(r[4] - r[2] for r in chosen)
        print(f"{name:>9} {pooled['posture']:>14.1%} {np.nanmean([q['posture'] for q in per]):>9.1%} "
              f"{GOALS['posture']:>5.0%} | {pooled['walk_vs_stairs']:>21.1%} "
              f"{np.nanmean([q['walk_vs_stairs'] for q in per]):>9.1%} {GOALS['walk_vs_stairs']:>5.0%} | "
              f"{found:>6}/{total:<3} {false_pt:>8}")
    print("walk-vs-stairs next to what labels alone allow (pooled detected locomotion windows):")
    for name, subjects in (("all", DEV + HELD_OUT), ("dev 1-7", DEV), ("held 8-15", HELD_OUT)):
        pooled = _scores(sum(r[1] for r in rows if r[0] in subjects))
        print(f"{name:>9} accuracy {pooled['walk_vs_stairs']:.1%}, "
              f"'always level' {pooled['always_level']:.1%}, "
              f"balanced accuracy {pooled['balanced']:.1%} (chance 50 %)")
    print("false PT = detected transitions other than the one sit→stand per subject (UCI has no other "
          "posture change inside labelled data)")
    print("confusion (rows truth, cols predicted; windows):")
    print("           " + " ".join(f"{c:>9}" for c in CLASSES))
    for i, c in enumerate(CLASSES):
        print(f"{c:>10} " + " ".join(f"{v:>9d}" for v in confusion[i]))
    print("posture = sitting vs upright (standing, walking, stairs) per window; walk det = locomotion "
          "windows labelled as any locomotion; lvl/stairs = level-vs-stairs among locomotion windows "
          "detected as locomotion; SiSt@2 = sit_to_stand between 20 s before the 'mixed' label and the "
          "first walk after it; cadence = steps/min over walking-labelled samples.")


def _stand_up_window(t_mixed: float, steps: list[float]) -> tuple[float, float]:
    """Where the sit→stand must lie: from 20 s before the 'mixed' label to the first step of the
    first walking bout (≥ 8 steps) after that, + 2 s.

    The 'mixed' label starts up to 130 s before the subject actually stands up (the trunk stays
    reclined and still, e.g. subject 2: θ 43° for 56 s after the label, then 43° → 5° and walking),
    so a window around the label start would miss real stand-ups.
    """
    steps_after = np.array([s for s in steps if s >= t_mixed - 20.0])
    bouts = np.split(steps_after, np.flatnonzero(np.diff(steps_after) > 1.3) + 1) if steps_after.size else []
    first = next((b[0] for b in bouts if len(b) >= 8), t_mixed + 20.0)
    return t_mixed - 20.0, float(first) + 2.0


def _scores(m: np.ndarray) -> dict[str, float]:
    sit, stand, walk, stairs = range(4)
    upright_rows = [stand, walk, stairs]
    correct_posture = m[sit, sit] + sum(m[r, c] for r in upright_rows for c in upright_rows)
    total = m.sum()
    loco = m[[walk, stairs]]
    detected = loco[:, [walk, stairs]]

    def ratio(a: float, b: float) -> float:
        return a / b if b else float("nan")

    return {
        "posture": ratio(correct_posture, total),
        "sit": ratio(m[sit, sit], m[sit].sum()),
        "stand": ratio(m[upright_rows][:, upright_rows].sum(), m[upright_rows].sum()),
        "loco_det": ratio(detected.sum(), loco.sum()),
        "walk_vs_stairs": ratio(detected[0, 0] + detected[1, 1], detected.sum()),
        "always_level": ratio(detected[0].sum(), detected.sum()),
        "balanced": 0.5 * ratio(detected[0, 0], detected[0].sum())
        + 0.5 * ratio(detected[1, 1], detected[1].sum()),
    }


def _cadence(out: dict) -> float:
    walking = out["locomotion"] != "none"
    seconds = walking.sum() / UCI_RATE
    return 60.0 * len(out["steps"]) / seconds if seconds else float("nan")


HAPT_RATE = 50.0
HAPT_TRANSITIONS = {7: "stand_to_sit", 8: "sit_to_stand", 9: "sit_to_lie", 10: "lie_to_sit",
                    11: "stand_to_lie", 12: "lie_to_stand"}
HAPT_GOALS = {"lying vs upright": 0.97, "walking vs static": 0.97, "sitting vs standing": 0.90,
              "level vs stairs": 0.85, "upstairs vs downstairs": None, "stairs walking detected": None,
              "transitions found": 0.90}  # issue 15


UCI_MAPPING = "units: {acc: g}\nchest: {acc: [acc-x, acc-y, acc-z]}\n"


def _through_cli(path: str, mapping: str | None, rate_hz: float, n: int, work: Path) -> dict:
    """One recording the user's way: ``import csv`` (a mapping, ``--rate``; None: the built-in ``hapt``
    importer) → ``analyze`` with the kit's defaults (no params file) → ``/activity/state`` as
    per-sample arrays (each state in force from the sample it describes), the transitions it reports
    and its steps (when its count rose: the state's stamp)."""
    import subprocess

    from gait_biofeedback.io.bag_reader import BagReader
    from gait_biofeedback.wire.activity import TRANSITION_NAMES, add_transition, state_of

    cli = [str(REPO / ".venv" / "bin" / "python"), "-m", "gait_biofeedback.cli"]
    if mapping is None:
        how = ["hapt", path]
    else:
        (work / "map.yaml").write_text(mapping)
        how = ["csv", path, "--mapping", str(work / "map.yaml"), "--rate", str(rate_hz)]
    subprocess.run([*cli, "import", *how, "-o", str(work / "in")], check=True, capture_output=True)
    subprocess.run([*cli, "analyze", str(work / "in"), "-o", str(work / "out"), "--overwrite"],
                   check=True, capture_output=True)
    messages = [m for _, m, _ in BagReader(work / "out").messages(["/activity/state"])]
    subprocess.run(["rm", "-rf", str(work / "in"), str(work / "out")], check=True)
    states, marks = [state_of(m) for m in messages], []
    for m in messages:
        add_transition(marks, m)
    stamps = np.array([s["stamp_ns"] for s in states], dtype=np.int64)
    k = np.searchsorted(stamps, seconds_to_ns(np.arange(n) / rate_hz), side="right") - 1
    posture = np.array([s["posture"] for s in states] + ["unknown"])[k]
    locomotion = np.array([s["locomotion"] for s in states] + ["none"])[k]
    transitions = [(stamp_ns / 1e9, TRANSITION_NAMES[code]) for stamp_ns, code in marks]
    counts = np.array([0] + [s["step_count"] for s in states])
    rises = zip(stamps.tolist(), np.diff(counts).tolist(), strict=True)
    steps = [t / 1e9 for t, rise in rises for _ in range(max(rise, 0))]
    return {"posture": posture, "locomotion": locomotion, "transitions": transitions, "steps": steps,
            "reference": [(0, "")]}


def _uci_cli(acc_counts: np.ndarray, work: Path) -> dict:
    """A UCI subject through ``import csv`` → ``analyze`` with the default parameters (nothing handed):
    the counts written in g about mid-scale (400 counts/g; the monitor rescales to its static norm)."""
    path = work / "chest.csv"
    np.savetxt(path, acc_counts / 400.0, delimiter=",", header="acc-x,acc-y,acc-z", comments="", fmt="%.5f")
    out = _through_cli(str(path), UCI_MAPPING, UCI_RATE, len(acc_counts), work)
    path.unlink()
    return out


def hapt(rate_hz: float = HAPT_RATE, no_gyro: bool = False, cli: bool = False) -> None:
    """UCI HAPT waist phone (Reyes-Ortiz et al.; CC BY 4.0), users 16-30: per-sample scores, transitions.
    ``rate_hz`` other than the phone's 50 Hz: the IMU resampled (``_resample``), each label taken from
    the original sample nearest in time (issue 15 item 5). ``no_gyro``: the accelerometer alone.
    ``cli``: through ``import`` → ``analyze`` (:func:`_through_cli`) instead of ``classify_activity``."""
    files = sorted(glob.glob(str(DATA / "hapt_waist" / "user*_run*.csv.gz")))
    if not files:
        print("[skip] hapt_waist missing")
        return
    print(f"\n== HAPT waist phone (Reyes-Ortiz et al.), {len(files)} recordings of users 16-30, "
          f"{rate_hz:g} Hz{'' if rate_hz == HAPT_RATE else ' (resampled from 50 Hz)'}, "
          f"{'accelerometer only' if no_gyro else 'accelerometer and gyro'}, placement=pelvis, nothing "
          "handed (automatic reference, initial posture auto: standing at the pelvis)"
          + (", through import -> analyze" if cli else "") + " ==")
    if cli:
        import tempfile

        work = Path(tempfile.mkdtemp())
    hits = {name: [0, 0] for name in HAPT_GOALS if name != "transitions found"}
    per_kind = {kind: [0, 0] for kind in HAPT_TRANSITIONS.values()}
    false, hours, replaced = 0, 0.0, 0
    for path in files:
        raw = np.loadtxt(path, delimiter=",", skiprows=1)
        label = raw[:, 7].astype(int)
        imu = raw[:, :6]
        if rate_hz != HAPT_RATE:
            from _resample import resample

            t0 = np.arange(len(raw)) / HAPT_RATE
            t, imu = resample(t0, imu, HAPT_RATE, rate_hz)
            label = label[np.minimum(np.round(t * HAPT_RATE).astype(int), len(label) - 1)]
        if cli:
            out = _through_cli(path, None, HAPT_RATE, len(label), work)
        else:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UnitMismatchWarning)
                out = classify_activity(imu[:, :3], rate_hz, units="g", placement="pelvis",
                                        gyro=None if no_gyro else imu[:, 3:])
        posture, moving = out["posture"], out["locomotion"] != "none"
        stairs = np.isin(out["locomotion"], ["upstairs", "downstairs"])
        activity = np.isin(label, [1, 2, 3, 4, 5, 6])
        cases = {
            "lying vs upright": (activity, (posture == "lying") == (label == 6)),
            "walking vs static": (activity, moving == np.isin(label, [1, 2, 3])),
            "sitting vs standing": (np.isin(label, [4, 5]),
                                    posture == np.where(label == 4, "sitting", "standing")),
            "level vs stairs": (np.isin(label, [1, 2, 3]) & moving, stairs == np.isin(label, [2, 3])),
            "upstairs vs downstairs": (np.isin(label, [2, 3]) & stairs,
                                       out["locomotion"] == np.where(label == 2, "upstairs", "downstairs")),
            "stairs walking detected": (np.isin(label, [2, 3]), moving),
        }
        for name, (mask, right) in cases.items():
            hits[name][0] += int(np.sum(right[mask]))
            hits[name][1] += int(mask.sum())
        used: set[int] = set()
        for code, a, b in _runs(label):
            kind = HAPT_TRANSITIONS.get(code)
            if kind is None:
                continue
            near = [i for i, (t, k) in enumerate(out["transitions"])
                    if k == kind and a / rate_hz - 2.0 <= t <= b / rate_hz + 2.0]
            per_kind[kind][0] += bool(near)
            per_kind[kind][1] += 1
            used.update(near)
        false += len(out["transitions"]) - len(used)
        hours += len(label) / rate_hz / 3600.0
        replaced += out["reference"][-1][1] == "walking"
    if cli:
        shutil.rmtree(work)
    print(f"{'score (per labelled sample)':>28} {'value':>7} {'goal':>5}")
    for name, (right, total) in hits.items():
        goal = HAPT_GOALS[name]
        print(f"{name:>28} {right / total:>7.1%} {'' if goal is None else f'{goal:.0%}':>5}")
    found = sum(v[0] for v in per_kind.values())
    total = sum(v[1] for v in per_kind.values())
    print(f"{'transitions found (±2 s)':>28} {found / total:>7.1%} {HAPT_GOALS['transitions found']:>5.0%}  "
          f"({found}/{total}; " + ", ".join(f"{k} {v[0]}/{v[1]}" for k, v in per_kind.items()) + ")")
    print(f"{'false transitions':>28} {false / hours:>7.1f} /h ({false} in {hours:.1f} h)")
    print(f"upright reference replaced by a walking bout in {replaced} of {len(files)} recordings (the "
          "quiet one was more than 15° from it)")
    print("a sample is scored against its video label (transitions and unlabelled samples excluded); level "
          "vs stairs among walking samples detected as walking, up vs down among stairs samples detected as "
          "stairs; a transition is found when one of its kind lies within 2 s of its labelled interval, "
          "every other detected transition is false")


def older() -> None:
    files = sorted(glob.glob(str(DATA / "older_chest_rfid" / "S*_Dataset" / "d*")))
    if not files:
        print("[skip] older_chest_rfid missing")
        return
    rate = 20.0
    print(f"\n== older adults, sternum (Torres et al.), {len(files)} trials, reads resampled to "
          f"{rate:.0f} Hz (zero-order hold), sensor axes already frontal/vertical/lateral (align=False) ==")
    names = ("lying", "sitting", "upright")
    confusion = np.zeros((3, 3), int)
    per_trial = []
    for path in files:
        raw = np.loadtxt(path, delimiter=",")
        t_read, acc, label = raw[:, 0], raw[:, 1:4], raw[:, 8].astype(int)
        grid = np.arange(0.0, t_read[-1] + 1.0 / rate, 1.0 / rate)
        idx = np.clip(np.searchsorted(t_read, grid, side="right") - 1, 0, len(t_read) - 1)
        if len(grid) < 3 * rate * 2:
            continue
        first = {1: "sitting", 2: "sitting", 3: "lying", 4: "standing"}[label[0]]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UnitMismatchWarning)
            out = classify_activity(acc[idx], rate, units="g", align=False, reference=(0, len(grid)),
                                    initial_posture=first)
        at_read = np.clip(np.round(t_read * rate).astype(int), 0, len(grid) - 1)
        pred = out["posture"][at_read].copy()
        pred[pred == "standing"] = "upright"
        truth = np.array([{1: "sitting", 2: "sitting", 3: "lying", 4: "upright"}[v] for v in label])
        m = np.zeros((3, 3), int)
        for i, a in enumerate(names):
            for j, b in enumerate(names):
                m[i, j] = np.sum((truth == a) & (pred == b))
        confusion += m
        per_trial.append((np.trace(m) / m.sum(), (m[0, 0] + m[1:, 1:].sum()) / m.sum()))
    acc3 = np.trace(confusion) / confusion.sum()
    lying = (confusion[0, 0] + confusion[1:, 1:].sum()) / confusion.sum()
    print(f"reads: {confusion.sum()}; 3-class accuracy {acc3:.1%} (mean over trials "
          f"{np.mean([a for a, _ in per_trial]):.1%}); lying-vs-not accuracy {lying:.1%} "
          f"(mean over trials {np.mean([b for _, b in per_trial]):.1%})")
    print("           " + " ".join(f"{c:>9}" for c in names))
    for i, c in enumerate(names):
        print(f"{c:>10} " + " ".join(f"{v:>9d}" for v in confusion[i]))
    print("Initial posture = the first label (a starting state is needed: sitting and upright differ only "
          "by transitions). At ~2 Hz reads neither steps nor ΔY can be measured, so sitting vs upright "
          "rests on the lying transitions and the initial state: only lying-vs-not is a fair figure here.")


def qmt() -> None:
    """qmt full-body walk (real, level ground): chest steps against the feet's swing phases."""
    path = DATA / "qmt_fullbody" / "full_body_example_data.mat"
    if not path.is_file():
        print(f"[skip] {path} missing")
        return
    from scipy.signal import find_peaks

    rec = import_qmt_fullbody(path)
    rate = QMT_FULLBODY_RATE_HZ
    out = classify_activity(rec.imu["chest"].acc, rate)
    walk_start = 50.0  # the walk starts at ~55 s; before it: calibration moves, a bow, standing
    swings = 0
    for foot in ("left_foot", "right_foot"):
        peaks, _ = find_peaks(np.linalg.norm(rec.imu[foot].gyr, axis=1), height=4.0, distance=int(0.6 * rate))
        swings += int(np.sum(peaks / rate > walk_start))
    steps = int(np.sum(np.array(out["steps"]) > walk_start))
    walking = out["locomotion"][int(walk_start * rate):]
    walking = walking[walking != "none"]
    print(f"\n== qmt full-body walk (real, level, {len(out['posture']) / rate:.0f} s) ==")
    error = 100 * (steps - swings) / swings
    print(f"steps from the chest {steps}, swing phases of the feet {swings} ({error:+.1f} %); walking "
          f"samples labelled level {np.mean(walking == 'level'):.1%}; transitions {len(out['transitions'])}")
    thighs = {seg: rec.imu[seg].acc for seg in ("left_thigh", "right_thigh")}
    with_thighs = classify_activity(rec.imu["chest"].acc, rate, thighs=thighs)
    seated = np.flatnonzero(with_thighs["posture"] == "sitting") / rate
    span = f"{seated[0]:.1f}-{seated[-1]:.1f} s" if seated.size else "none"
    print(f"with the thighs (thigh.py): sitting {span} ({seated.size / rate:.1f} s), transitions "
          + ", ".join(f"{k} {t:.1f} s" for t, k in with_thighs["transitions"])
          + "; the thighs' inclination reads 70-83° from 10 to 40 s (the chest alone: no sitting)")


def simulator() -> None:
    session = simulate(SCENARIOS["activity"]())
    chest = session.imu["chest"]
    rate = session.config.rate_hz
    truth = session.truth
    out = classify_activity(chest.acc, rate)
    print(f"\n== simulator 'activity' scenario ({len(chest.t) / rate:.0f} s, {rate:.0f} Hz) ==")
    t0 = chest.t[0]
    errors, missed = [], 0
    for t_true, kind in truth.transitions:
        cands = [t + t0 - t_true for t, k in out["transitions"] if k == kind and abs(t + t0 - t_true) < 2.0]
        if cands:
            errors.append(min(cands, key=abs))
        else:
            missed += 1
    extra = len(out["transitions"]) - (len(truth.transitions) - missed)
    print(f"transitions: {len(truth.transitions)} true, {missed} missed, {extra} extra; timing error "
          f"mean {np.mean(np.abs(errors)) if errors else float('nan'):.2f} s, max "
          f"{np.max(np.abs(errors)) if errors else float('nan'):.2f} s")
    n_true, n_est = len(truth.steps), len(out["steps"])
    print(f"steps: {n_true} true, {n_est} detected, error {100.0 * (n_est - n_true) / max(n_true, 1):+.1f} %")
    posture_ok = np.mean(out["posture"] == truth.posture[: len(out["posture"])])
    print(f"posture per-sample agreement {posture_ok:.1%}")
    thighs = {seg: session.imu[seg].acc for seg in ("left_thigh", "right_thigh")}
    with_thighs = classify_activity(chest.acc, rate, thighs=thighs)
    errors = [min((t + t0 - t_true for t, k in with_thighs["transitions"] if k == kind), key=abs,
                  default=np.nan) for t_true, kind in truth.transitions]
    posture_ok = np.mean(with_thighs["posture"] == truth.posture[: len(with_thighs["posture"])])
    print(f"with the thighs: {len(with_thighs['transitions'])} transitions, timing error max "
          f"{np.nanmax(np.abs(errors)):.2f} s (the thighs cross their middle level before / after the "
          f"phase's middle, the truth's instant), posture agreement {posture_ok:.1%}")

    stairs = simulate(SCENARIOS["stairs"]())
    forward = quaternion.rotate(stairs.truth.mounting["chest"], np.array([1.0, 0.0, 0.0]))
    print(f"\n== simulator 'stairs' scenario ({len(stairs.truth.t) / rate:.0f} s): share of samples labelled "
          "as the truth, per true locomotion ==")
    for name, axis in (("calibrated forward_axis", forward), ("sensor x (default)", None)):
        got = classify_activity(stairs.imu["chest"].acc, rate, forward_axis=axis)["locomotion"]
        true = stairs.truth.locomotion
        shares = {k: np.mean(got[true == k] == k) for k in ("level", "upstairs", "downstairs")}
        print(f"{name:>24}: " + ", ".join(f"{k} {v:.0%}" for k, v in shares.items()))


def cost() -> None:
    rate = 100.0
    rng = np.random.default_rng(0)
    n = 20000
    t = np.arange(n) / rate
    acc = np.column_stack([0.3 * np.sin(2 * np.pi * 0.9 * t), 9.81 + 2.5 * np.sin(2 * np.pi * 1.8 * t),
                           0.2 * np.sin(2 * np.pi * 0.9 * t)]) + 0.05 * rng.standard_normal((n, 3))
    samples = acc.tolist()
    monitor = ActivityMonitor(rate)
    update = monitor.update
    stamps = seconds_to_ns(np.arange(len(samples)) / rate).tolist()
    start = time.perf_counter()
    for k in range(n):
        update(stamps[k], samples[k])
    per_sample = (time.perf_counter() - start) / n
    print(f"\n== streaming cost: {per_sample * 1e6:.1f} µs per sample (100 Hz walking signal, {n} samples, "
          f"{len(monitor.steps)} steps) ==")


def main() -> None:
    import sys

    if "--cli" in sys.argv:  # the user's path on the chest and the waist phone
        uci(handed=False, cli=True)
        hapt(cli=True)
        return
    if "--rates" in sys.argv:  # issue 15 item 5: the waist phone at other rates
        for rate in (20.0, 50.0, 100.0, 200.0):
            hapt(rate)
        return
    start = time.perf_counter()
    cost()
    uci(handed=True)
    uci(handed=False)
    hapt()
    hapt(no_gyro=True)
    older()
    qmt()
    simulator()
    print(f"\ntotal run time {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
