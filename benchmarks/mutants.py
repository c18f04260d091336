"""Mutation testing, from scratch: do the fast tests notice small deliberate bugs?

Each mutant is one exact source edit of the kind a careless change makes (a flipped comparison, a
moved threshold, a dropped condition, swapped variables). For each one the repository's files
(``git ls-files``: tracked plus untracked-not-ignored, as they are in the working tree) are copied into
a temporary directory, the edit is applied there (the snippet must occur exactly once, otherwise the
mutant is an ``error``), and the mutant's test files run in the copy::

    timeout -s KILL <limit> python -m pytest -q -x -p no:cacheprovider <tests>

with ``cwd`` and ``PYTHONPATH`` = the copy (the venv's editable install of the checkout comes after
``PYTHONPATH`` on ``sys.path``; each copy checks that it imports its own package) and a fresh numba
cache inside the copy (``NUMBA_CACHE_DIR``), so the mutated ``_inertial_kernel.step`` is what is
compiled and run. A failing test run = ``killed``, a passing one = ``SURVIVED``; a run that cannot
start, times out or collects nothing = ``error``. ``../shared`` is linked next to the copies, so the
tests that read ``../shared/data`` behave as in the checkout. Each set of test files first runs on an
unmutated copy (the baseline): if that fails (e.g. a half-finished edit in the working tree), no
mutant is run, since a kill would mean nothing.

Usage (from the repository root)::

    .venv/bin/python benchmarks/mutants.py              # all mutants, 2 in parallel
    .venv/bin/python benchmarks/mutants.py --list
    .venv/bin/python benchmarks/mutants.py --only ev-ic-trend,cyc-ds-fraction -j 1
    .venv/bin/python benchmarks/mutants.py --canary     # an obviously broken mutant must be killed

Exit status: 0 when every mutant was killed, 1 when any survived, 2 on errors only.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import NamedTuple

REPO = Path(__file__).resolve().parents[1]
TIMEOUT_S = 300

EVENTS = "gait_biofeedback/core/gait/events.py"
CYCLES = "gait_biofeedback/core/gait/cycles.py"
JSTREAM = "gait_biofeedback/core/joints/stream.py"
ANGLES = "gait_biofeedback/core/joints/angles.py"
CAL = "gait_biofeedback/core/calibration/sensor_to_segment.py"
KERNEL = "gait_biofeedback/core/orientation/filters/_inertial_kernel.py"
STARTUP = "gait_biofeedback/core/orientation/filters/startup.py"
WALKING = "gait_biofeedback/core/activity/walking.py"
MODALITY = "gait_biofeedback/core/activity/modality.py"
POSTURE = "gait_biofeedback/core/activity/posture.py"
LYING = "gait_biofeedback/core/activity/lying.py"
SIT_STAND = "gait_biofeedback/core/activity/sit_stand.py"
UPRIGHT = "gait_biofeedback/core/activity/reference.py"
EVAL = "gait_biofeedback/core/biofeedback/evaluator.py"
GAIN = "gait_biofeedback/core/orientation/gain_regulation.py"

T_EVENTS, T_CAL, T_FILT = "test/test_gait_events.py", "test/test_calibration.py", "test/test_filters.py"
T_ANGLES, T_CONV = "test/test_joint_angles.py", "test/test_joint_angles_convention.py"
T_ACT, T_BF, T_GAIN = "test/test_activity.py", "test/test_biofeedback.py", "test/test_gain_regulation.py"


class Mutant(NamedTuple):
    id: str
    path: str  # relative to the repository root
    original: str  # exact snippet, must occur once
    replacement: str
    tests: tuple[str, ...]  # pytest arguments (files or node ids)
    description: str


_MAX_TREND = ("            if v > buf[j - 1]:\n                trend += 1\n"
              "        return trend >= self.min_trend")
_MIN_TREND = _MAX_TREND.replace("v > buf", "v < buf")
_IC_TEST = "elif k - self._k_ic > self.refractory and s > self.threshold and prev > s"
_FAST_AFTER_REJECTION = ("if s[MREJ_T] >= p[P_MAG_ACCEPT_TIME]:  # after a real rejection: catch up quickly\n"
                         "                    s[FAST_T] = p[P_FAST_TIME]")
_IE_SIGN = "s_fe, s_mirror, s_mirror"

MUTANTS: tuple[Mutant, ...] = (
    # --- gait events, thesis Algorithm 1
    Mutant("ev-ic-trend", EVENTS, _MAX_TREND, _MAX_TREND + " - 1", (T_EVENTS,),
           "IC maximum: 80 % trend rule weakened by one difference"),
    Mutant("ev-ic-trend-drop", EVENTS, _MAX_TREND, _MAX_TREND.replace("trend >= self.min_trend", "True"),
           (T_EVENTS,), "IC maximum: 80 % trend rule dropped"),
    Mutant("ev-tc-trend", EVENTS, _MIN_TREND, _MIN_TREND + " - 1", (T_EVENTS,),
           "TC minimum: 80 % trend rule weakened by one difference"),
    Mutant("ev-ic-threshold-flip", EVENTS, _IC_TEST,
           _IC_TEST.replace("s > self.threshold", "s < self.threshold"), (T_EVENTS,),
           "IC threshold test s > -0.2 flipped to <"),
    Mutant("ev-ic-threshold-drop", EVENTS, _IC_TEST, _IC_TEST.replace(" and s > self.threshold", ""),
           (T_EVENTS,), "IC threshold test dropped (any maximum after a TC is an IC)"),
    Mutant("ev-refractory", EVENTS, "if k - self._k_tc > self.refractory",
           "if k - self._k_tc >= self.refractory", (T_EVENTS,), "TC refractory period: > N_refr became >="),
    # --- stride parameters
    Mutant("cyc-plausible-sym", CYCLES, "if plausible and math.isfinite(step):", "if math.isfinite(step):",
           (T_EVENTS,), "implausible strides enter the symmetry window"),
    Mutant("cyc-ds-fraction", CYCLES, "double_support_fraction=double / stride",
           "double_support_fraction=double / stance", (T_EVENTS,),
           "double support fraction of stance, not stride"),
    Mutant("cyc-tc-count", CYCLES, "if len(own_tcs) != 1:", "if len(own_tcs) > 1:", (T_EVENTS,),
           "a stride without its own TC counts as plausible"),
    Mutant("cyc-step-other", CYCLES, "step = end - other_ics[-1]", "step = end - other_ics[0]", (T_EVENTS,),
           "step time from the first, not the last, other-foot IC inside the stride"),
    # --- joint angles
    Mutant("js-still-count", JSTREAM, "and len(samples) == len(wanted)", "", (T_ANGLES,),
           "standing offset: an instant with a missing segment counts as still"),
    Mutant("js-still-flip", "gait_biofeedback/core/joints/_heading_kernel.py",
           "not _norm(s[k][4], s[k][5], s[k][6]) < still_gyro",
           "not _norm(s[k][4], s[k][5], s[k][6]) > still_gyro",
           (T_ANGLES,),
           "standing offset: still gate flipped (< → >)"),
    Mutant("ja-knee-sign", ANGLES, 's_fe = -1.0 if joint == "knee" else 1.0', "s_fe = 1.0",
           (T_CONV, T_ANGLES),
           "knee flexion sign not inverted"),
    Mutant("ja-ie-mirror", ANGLES, _IE_SIGN, "s_fe, s_mirror, 1.0", (T_CONV, T_ANGLES),
           "internal rotation not mirrored on the left"),
    Mutant("ja-aa-swap", ANGLES, "np.arcsin(np.clip(m[..., 2, 1]", "np.arcsin(np.clip(m[..., 1, 2]",
           (T_CONV, T_ANGLES), "adduction from the transposed matrix element"),
    # --- sensor-to-segment calibration: every refusal gate, sign and count rules
    Mutant("cal-explained", CAL, "MIN_EXPLAINED_VARIANCE = 0.6", "MIN_EXPLAINED_VARIANCE = 0.5", (T_CAL,),
           "explained-variance gate never fires (0.5 is its minimum)"),
    Mutant("cal-thigh-heading", CAL, "MAX_THIGH_HEADING_DISAGREEMENT = np.radians(30.0)",
           "MAX_THIGH_HEADING_DISAGREEMENT = np.radians(180.0)", (T_CAL,),
           "trunk: thigh heading disagreement gate never fires"),
    Mutant("cal-gyro-rms", CAL, "MAX_STANDING_GYRO_RMS = 0.08  #", "MAX_STANDING_GYRO_RMS = 0.8  #", (T_CAL,),
           "standing gyro RMS limit 10x too loose"),
    Mutant("cal-acc-rms", CAL, "MAX_STANDING_ACC_RMS = 0.5  #", "MAX_STANDING_ACC_RMS = 5.0  #", (T_CAL,),
           "standing accelerometer RMS limit 10x too loose"),
    Mutant("cal-gravity", CAL, "if abs(g - GRAVITY) > 1.5:", "if abs(g - GRAVITY) > 15.0:", (T_CAL,),
           "accelerometer-reads-not-9.8 gate never fires"),
    Mutant("cal-vertical", CAL, "if np.linalg.norm(x_sensor) < 0.3:", "if np.linalg.norm(x_sensor) < 0.0:",
           (T_CAL,), "trunk: orientation/accelerometer vertical disagreement never refused"),
    Mutant("cal-apart", CAL, "if np.linalg.norm(x) < 0.3:", "if np.linalg.norm(x) < 0.0:", (T_CAL,),
           "trunk: forward directions that cancel out averaged anyway"),
    Mutant("cal-min-cycles", CAL, "if cycles < need:", "if cycles < need - 1:", (T_CAL,),
           "one movement cycle fewer than required is accepted"),
    Mutant("cal-corr-sign", CAL, "(1.0 if corr >= 0 else -1.0)", "(1.0 if corr < 0 else -1.0)", (T_CAL,),
           "sign rule: correlation with the reference inverted"),
    Mutant("cal-foot-sign", CAL, "deeper_down = -p1 - p99", "deeper_down = p1 + p99", (T_CAL,),
           "foot pitch-shape sign rule inverted"),
    # --- inertial_cf magnetometer logic and the start-up step
    Mutant("icf-dip", KERNEL, "\n                     or abs(dip - s[MREF_DIP]) > p[P_MAG_DIP_TH])", ")",
           (T_FILT,), "disturbance check ignores the dip angle"),
    Mutant("icf-norm", KERNEL, "disturbed = (abs(nm - s[MREF_N]) > p[P_MAG_NORM_TH] * s[MREF_N]\n"
           "                     or abs", "disturbed = (abs", (T_FILT,),
           "disturbance check ignores the field norm"),
    Mutant("icf-fast-set", KERNEL, _FAST_AFTER_REJECTION, _FAST_AFTER_REJECTION.split("\n")[0] + "\n"
           "                    pass", (T_FILT,), "no fast heading catch-up after a real rejection"),
    Mutant("icf-tau-fast", KERNEL, "tau = p[P_TAU_MAG_FAST]", "tau = p[P_TAU_MAG]", (T_FILT,),
           "fast catch-up uses the slow heading time constant"),
    Mutant("icf-timeout", KERNEL, "if not correct and s[MREJ_T] >= p[P_MAG_MAX_REJECT]:",
           "if not correct and s[MREJ_T] >= 2.0 * p[P_MAG_MAX_REJECT]:", (T_FILT,),
           "rejection timeout twice as long as configured"),
    Mutant("startup-triad", STARTUP, "east = np.cross(np.asarray(mag, dtype=float), up)",
           "east = np.cross(up, np.asarray(mag, dtype=float))", (T_FILT,), "TRIAD east axis reversed"),
    Mutant("startup-quiet", STARTUP, "if moving.any() else n", "if moving.any() else 0", (T_FILT,),
           "a window quiet to its end counts as no quiet sample"),
    # --- chest activity monitor
    Mutant("act-upright", WALKING, "UPRIGHT_WALKING_RAD = math.radians(30.0)",
           "UPRIGHT_WALKING_RAD = math.radians(60.0)", (T_ACT,),
           "steps counted with the trunk leaning up to 60°"),
    Mutant("act-wearer-ratio", MODALITY, "STAIRS_WEARER_RATIO = 1.3  #", "STAIRS_WEARER_RATIO = 1.0  #",
           (T_ACT,), "the wearer's stairs threshold: ratio 1.3 → 1.0"),
    Mutant("act-wearer-quantile", MODALITY, "usual = ordered[int(DISPLACEMENT_QUANTILE * len(ordered))]",
           "usual = ordered[-1]", (T_ACT,), "the wearer's usual walking from the maximum, not the 10th pct"),
    Mutant("act-referred", MODALITY, "return sigma_d * min(1.0, STAIRS_REFERENCE_RAD_S / omega)",
           "return sigma_d", (T_ACT,), "the displacement not referred to 1.6 Hz (brisk walking is stairs)"),
    Mutant("act-worn", UPRIGHT, "return low / band >= WORN_RATIO * self._white",
           "return low / band >= 0.3 * WORN_RATIO * self._white", (T_ACT,),
           "the gyro's white noise passes for a wearer"),
    Mutant("act-start-rule", POSTURE, "self.start_unconfirmed = initial_posture == \"standing\" and",
           "self.start_unconfirmed = False and", (T_ACT,), "an upright start is standing without a walk"),
    Mutant("act-merge-moving", POSTURE, "MERGE_MOVING_S = 10.0  #", "MERGE_MOVING_S = 5.0  #", (T_ACT,),
           "getting up with a pause on the bed's edge is two events"),
    Mutant("ev-late-tc-edge", EVENTS, "if best is None or best[0] == first or not",
           "if best is None or not", (T_EVENTS,), "a foot that only rose gives a late toe-off"),
    Mutant("act-up-lean", MODALITY, "if known >= LEVEL_LEAN_MIN_N:", "if known >= 10**6:", (T_ACT,),
           "up vs down never from the lean beyond level walking"),
    Mutant("act-lying-hysteresis", LYING, "LYING_HYSTERESIS_RAD = math.radians(10.0)",
           "LYING_HYSTERESIS_RAD = math.radians(0.0)", (T_ACT,), "no lie-to-sit hysteresis"),
    Mutant("act-strong", SIT_STAND, "STRONG_THIGH_FRACTION = 0.7", "STRONG_THIGH_FRACTION = 0.5", (T_ACT,),
           "strong sit-to-stand height gate = the thesis gate"),
    Mutant("act-min-peaks", WALKING, "elif len(self.run) >= MIN_SUCCESSIVE_PEAKS:",
           "elif len(self.run) >= MIN_SUCCESSIVE_PEAKS - 1:", (T_ACT,), "walking confirmed after 2 peaks"),
    # --- biofeedback and gain regulation
    Mutant("bf-severity", EVAL, "SEVERITY_MILD if abs(error) < band.width",
           "SEVERITY_MILD if abs(error) < 0.5 * band.width", (T_BF,), "severe from half a band width"),
    Mutant("bf-pitch", EVAL, "2.0 ** (self.octaves * max(-1.0, min(1.0, e)))",
           "2.0 ** (-self.octaves * max(-1.0, min(1.0, e)))", (T_BF,),
           "audio pitch falls with a positive error"),
    Mutant("gr-switch", GAIN, "        if signal < t:\n", "        if signal <= t:\n", (T_GAIN,),
           "per-sensor switch: a signal at the threshold stays on the lower level"),
    Mutant("gr-both-quiet", GAIN, "if dev_acc < sa and (dev_mag", "if dev_acc < sa or (dev_mag", (T_GAIN,),
           "two-level gain: one quiet sensor is enough"),
)

CANARY = Mutant("canary", EVENTS, "        buf = self._s\n        buf.append(s)",
                "        return None\n        buf = self._s", (T_EVENTS,), "detector never returns an event")


def tracked_files() -> list[str]:
    out = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=REPO,
                         check=True, capture_output=True).stdout.decode()
    return sorted({f for f in out.split("\0") if f and (REPO / f).is_file()})


def make_copy(files: list[str], dest: Path) -> None:
    for rel in files:
        target = dest / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(REPO / rel, target)


def apply(mutant: Mutant, root: Path) -> None:
    """Apply the edit in the copy; ValueError unless the snippet occurs exactly once."""
    path = root / mutant.path
    text = path.read_text()
    count = text.count(mutant.original)
    if count != 1:
        raise ValueError(f"{mutant.id}: snippet found {count} times in {mutant.path}")
    path.write_text(text.replace(mutant.original, mutant.replacement))


def run_one(mutant: Mutant, files: list[str], workdir: Path) -> tuple[str, float, str]:
    """(status, seconds, detail) of one mutant: killed | SURVIVED | error."""
    start = time.monotonic()
    root = workdir / mutant.id
    try:
        make_copy(files, root)
        if mutant.path:  # the baseline has no edit
            apply(mutant, root)
        env = dict(os.environ, PYTHONPATH=str(root), NUMBA_CACHE_DIR=str(root / ".numba_cache"))
        env.pop("GAIT_BIOFEEDBACK_NO_NUMBA", None)
        probe = "import gait_biofeedback; print(gait_biofeedback.__file__)"
        check = subprocess.run([sys.executable, "-c", probe], cwd=root, env=env, capture_output=True,
                               text=True, timeout=60)
        if not check.stdout.strip().startswith(str(root)):
            return "error", time.monotonic() - start, f"imports {check.stdout.strip() or check.stderr[-200:]}"
        cmd = ["timeout", "-s", "KILL", str(TIMEOUT_S), sys.executable, "-m", "pytest", "-q", "-x",
               "-p", "no:cacheprovider", *mutant.tests]
        proc = subprocess.run(cmd, cwd=root, env=env, capture_output=True, text=True)
    except (OSError, ValueError, subprocess.SubprocessError) as exc:
        return "error", time.monotonic() - start, str(exc)
    finally:
        shutil.rmtree(root, ignore_errors=True)
    seconds = time.monotonic() - start
    lines = proc.stdout.strip().splitlines()
    failed = [ln.split(" - ")[0].removeprefix("FAILED ") for ln in lines if ln.startswith("FAILED ")]
    if proc.returncode == 0:
        return "SURVIVED", seconds, lines[-1] if lines else ""
    if proc.returncode == 1 and failed:
        return "killed", seconds, failed[0]
    why = "timeout" if proc.returncode in (-9, 137) else f"pytest exit {proc.returncode}"
    return "error", seconds, f"{why}: {(lines or [proc.stderr.strip()[-200:]])[-1]}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", help="comma-separated mutant ids")
    parser.add_argument("--list", action="store_true", help="list the mutants and exit")
    parser.add_argument("--canary", action="store_true", help="run only an obviously broken mutant")
    parser.add_argument("-j", type=int, default=2, help="mutants run in parallel (default 2)")
    args = parser.parse_args(argv)
    mutants = list(MUTANTS)
    if args.canary:
        mutants = [CANARY]
    elif args.only:
        wanted = args.only.split(",")
        unknown = set(wanted) - {m.id for m in MUTANTS}
        if unknown:
            parser.error(f"unknown mutant ids: {', '.join(sorted(unknown))}")
        mutants = [m for m in MUTANTS if m.id in wanted]
    if args.list:
        for m in mutants:
            print(f"{m.id:22} {m.path.removeprefix('gait_biofeedback/'):42} {m.description}")
        return 0
    files = tracked_files()
    results: dict[str, tuple[str, float, str]] = {}
    with tempfile.TemporaryDirectory(prefix="mutants-") as tmp:
        workdir = Path(tmp)
        if (REPO.parent / "shared").is_dir():
            (workdir / "shared").symlink_to(REPO.parent / "shared")
        with ThreadPoolExecutor(max_workers=max(1, args.j)) as pool:
            test_sets = dict.fromkeys(m.tests for m in mutants)
            baselines = [Mutant(f"baseline-{i}", "", "", "", tests, "unmutated copy")
                         for i, tests in enumerate(test_sets)]
            for b, (status, _seconds, detail) in zip(
                    baselines, pool.map(lambda b: run_one(b, files, workdir), baselines), strict=True):
                if status != "SURVIVED":
                    print(f"baseline fails ({' '.join(b.tests)}): {status} {detail}; no mutant run")
                    return 2
            print(f"baselines pass ({len(baselines)} test sets)", flush=True)
            futures = {m.id: pool.submit(run_one, m, files, workdir) for m in mutants}
            for m in mutants:
                results[m.id] = status, seconds, detail = futures[m.id].result()
                print(f"{m.id:22} {status:8} {seconds:5.1f} s  {m.description}\n{'':31}{detail}", flush=True)
    statuses = [r[0] for r in results.values()]
    killed, survived = statuses.count("killed"), statuses.count("SURVIVED")
    errors = len(statuses) - killed - survived
    extra = f", {errors} errors" if errors else ""
    print(f"{len(statuses)} mutants, {killed} killed, {survived} survived{extra}")
    return 1 if survived else (2 if errors else 0)


if __name__ == "__main__":
    sys.exit(main())
