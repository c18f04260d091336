"""Real-time gait events (thesis ch. 6 Algorithm 1) and the angular-velocity comparator, scored.

Run: ``.venv/bin/python benchmarks/gait_events.py`` (about 10 s). ``--rates``: the real recordings
resampled to 20-400 Hz instead (about 2 min). ``--cli``: also ipol_gait and gaitmap_example through
the user's path, ``import`` → ``analyze --calibrate-at auto`` → ``/gait/events`` (about 6 min; the
streaming detector after the found calibration, not the batch entry point; gaitmap's 0.7 s of
standing taken as a short one). ``--halves`` (about 30 s; issue 47): ipol_gait subjects 1-5 (where the
event stamps' margin was chosen) and 6-9 (confirmed) and gaitmap_example (motion capture, reported),
each with Se/Pr, the median and mean ± SD timing error and each trial's stance and double support
against the reference events'; ``--halves --event-margin 0``: the same with Algorithm 1's extremum
stamps (before issue 47). ``--walk-only``: only ipol_gait with the
standing cut off (the foot calibration's stance-phase fallback; about 1 min); ``--walk-only --cli``: the
same through ``import`` → ``analyze --calibrate-at auto`` (about 4 min). Prints one table:
- gaitmap example (Küderle et al., gaitmap, MIT): 2 foot IMUs at 204.8 Hz, 57 strides with
  motion-capture IC/TC. Scored inside the reference strides (stride start → end per foot: the
  mocap stride list leaves out a few strides, e.g. at turns, and detections there are not errors);
- the project simulator: "walk" and "slow_gait" at 100 and 200 Hz, truth IC/TC, scored from 0.5 s before
  each foot's first truth event to 0.5 s after its last (the simulator labels no event in its 1 s
  walk → stand pose blend, where the trailing foot's heel rises and lowers: see the report);
- qmt full-body example (MIT): no reference; events per stride, cadence, stride time spread.
Both methods run the batch entry point ``detect_gait_events`` on the raw foot IMU (default orientation
filter + foot calibration from the standing at the start). Se / Pr (thesis Eq 53) with a ±500 ms
match window; error = detected event time − reference, mean ± SD in ms over the matched events (the
event time is the extremum sample; the live detection is one sample later: +5 ms at 204.8 Hz).
An SVG of the qmt foot gyro with the detected events is written to ``output/gait_events_qmt.svg``
(untracked; real data, never commit it).
"""

from __future__ import annotations

import time
from collections import Counter
from pathlib import Path

import numpy as np

from gait_biofeedback.batch import (
    INITIAL_CONTACT,
    MATCH_TOLERANCE_S,
    SCENARIOS,
    TERMINAL_CONTACT,
    GaitEventDetector,
    cycles_from_event_times,
    detect_gait_events,
    foot_calibration,
    import_gaitmap,
    import_qmt_fullbody,
    import_recording,
    match_events,
    sagittal_rate,
    seconds_to_ns,
    simulate,
)

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data"
MATCH_S = MATCH_TOLERANCE_S  # thesis §6.2.4 / [T ref 373]
METHODS = ("nazarahari", "angular_velocity")
KINDS = (INITIAL_CONTACT, TERMINAL_CONTACT)


def score(results: list[tuple[str, np.ndarray, np.ndarray, list[tuple[float, float]]]],
          tolerance_s: float = MATCH_S) -> dict:
    """Pooled Se/Pr/error over (label, detected, reference, scored intervals) tuples; detections and
    reference events outside the intervals are not scored."""
    tp = fn = fp = 0
    errors: list[float] = []
    notes: list[str] = []
    for label, detected, reference, intervals in results:
        detected = np.asarray(detected, dtype=float)
        reference = np.asarray(reference, dtype=float)
        # a detection up to the tolerance outside the intervals may match a reference inside (the ipol
        # trial ends at its last heel strike: one stamped 10 ms later is not a miss); unmatched, it is
        # not scored
        matched = match_events(detected[_inside(detected, intervals, tolerance_s)],
                               reference[_inside(reference, intervals)], tolerance_s)
        extra = [t for t in matched.extra if _inside(np.array([t]), intervals)[0]]
        tp, fn, fp = tp + len(matched.errors), fn + len(matched.missed), fp + len(extra)
        errors += matched.errors
        notes += [f"{label}: missed reference at {t:.2f} s" for t in matched.missed]
        notes += [f"{label}: extra detection at {t:.2f} s" for t in extra]
    err = np.array(errors) * 1000.0
    return {"n": tp + fn, "se": 100.0 * tp / max(tp + fn, 1), "pr": 100.0 * tp / max(tp + fp, 1),
            "median": float(np.median(err)) if len(err) else np.nan,
            "mean": float(err.mean()) if len(err) else np.nan,
            "sd": float(err.std(ddof=1)) if len(err) > 1 else np.nan, "notes": notes}


def _inside(times: np.ndarray, intervals: list[tuple[float, float]], margin_s: float = 0.0) -> np.ndarray:
    """Which ``times`` lie in one of the ``intervals`` widened by ``margin_s`` on both sides."""
    inside = np.zeros(len(times), dtype=bool)
    for a, b in intervals:
        inside |= (times >= a - margin_s) & (times <= b + margin_s)
    return inside


def gaitmap_rows() -> list[tuple[str, str, dict]]:
    folder = DATA / "gaitmap_example"
    if not folder.is_dir():
        print(f"(skipped gaitmap: {folder} not found)")
        return []
    rec = import_gaitmap(folder)
    ref = rec.reference["events"]
    rate = rec.imu["left_foot"].rate_hz
    rows = []
    for method in METHODS:
        per_kind: dict[str, list] = {k: [] for k in KINDS}
        for side in ("left", "right"):
            series = rec.imu[f"{side}_foot"]
            events = detect_gait_events(series.gyr, series.acc, rate, method=method)
            intervals = list(zip(ref[side]["start"], ref[side]["end"], strict=True))
            for kind in KINDS:
                per_kind[kind].append((f"{side} {kind.upper()}", np.array(events[kind]) + series.t[0],
                                       ref[side][kind], intervals))
        rows.append((f"gaitmap 204.8 Hz ({len(ref['left']['ic']) + len(ref['right']['ic'])} strides)", method,
                     {k: score(per_kind[k]) for k in KINDS}))
    return rows


IPOL_MATCH_S = 0.3  # the data set's own scoring window (its README)
IPOL_RATE_HZ = 100.0  # the sensors' rate (the stamps have holes: lost packets)


def ipol_rows() -> tuple[list[tuple[str, str, dict]], list[str]]:
    """ipol_gait (Voisard et al. 2023, Xsens MTw feet, 100 Hz, development subjects 1-9): every trial
    through ``import ipol_gait``'s importer and ``detect_gait_events``; scored inside the trial
    boundaries with ±300 ms. Returns the rows and the refusals (foot, message)."""
    folder = DATA / "ipol_gait"
    if not folder.is_dir():
        print(f"(skipped ipol_gait: {folder} not found)")
        return [], []
    trials = sorted(folder.glob("*.json"), key=lambda p: tuple(int(x) for x in p.stem.split("-")))
    rows, refusals = [], []
    for method in METHODS:
        per_kind: dict[str, list] = {k: [] for k in KINDS}
        feet = 0
        for path in trials:
            rec = import_recording("ipol_gait", path)
            for side in ("left", "right"):
                series = rec.imu[f"{side}_foot"]
                feet += 1
                try:
                    events = detect_gait_events(series.gyr, series.acc, IPOL_RATE_HZ, method=method,
                                                t=series.t)
                except ValueError as exc:
                    refusals.append(f"{method} {path.stem} {side}: {exc}")
                    events = {k: [] for k in KINDS}
                for kind in KINDS:
                    per_kind[kind].append((f"{path.stem} {side} {kind.upper()}", np.array(events[kind]),
                                           rec.reference["events"][side][kind], [rec.reference["trial"]]))
        rows.append((f"ipol_gait ({len(trials)} trials, {feet} feet)", method,
                     {k: score(per_kind[k], IPOL_MATCH_S) for k in KINDS}))
    return rows, refusals


def _ipol_halves(title: str) -> list[tuple[tuple[str, ...], list[Path]]]:
    """The ipol_gait trials of subjects 1-5 (chosen on) and 6-9 (confirmed), after printing ``title``;
    none, saying so, without the data."""
    folder = DATA / "ipol_gait"
    if not folder.is_dir():
        print(f"(skipped: {folder} not found)")
        return []
    print(title)
    halves = (("1", "2", "3", "4", "5"), ("6", "7", "8", "9"))
    return [(half, sorted(p for p in folder.glob("*.json") if p.stem.split("-")[0] in half))
            for half in halves]


def walk_only() -> None:
    """ipol_gait with each trial's standing cut off (0.5 s after it): the batch foot calibration's
    fallback on the foot-flat moments (``core/calibration/walk.py``) against the standing calibration,
    and Algorithm 1's Se/Pr from 0.5 s into the cut, per half (subjects 1-5 chosen on, 6-9 confirmed)."""
    from gait_biofeedback.core.calibration.foot import standing_run

    for half, trials in _ipol_halves("ipol_gait, the walk only (standing cut off): feet refused, calibration "
                                     "vs the standing one, events (±300 ms)"):
        diffs, refused, feet = [], 0, 0
        per_kind: dict[str, list] = {k: [] for k in KINDS}
        for path in trials:
            rec = import_recording("ipol_gait", path)
            for side in ("left", "right"):
                s = rec.imu[f"{side}_foot"]
                feet += 1
                standing = foot_calibration(s.gyr, s.acc, s.rate_hz, f"{side}_foot")
                k = standing_run(s.gyr, s.acc, s.rate_hz)[1] + round(0.5 * s.rate_hz)
                try:
                    walk = foot_calibration(s.gyr[k:], s.acc[k:], s.rate_hz, f"{side}_foot")
                    events = detect_gait_events(s.gyr[k:], s.acc[k:], IPOL_RATE_HZ, t=s.t[k:])
                    diffs.append(np.degrees(2 * np.arccos(min(1.0, abs(float(standing @ walk))))))
                except ValueError:
                    refused += 1
                    events = {kind: [] for kind in KINDS}
                scored = [(max(rec.reference["trial"][0], s.t[k] + 0.5), rec.reference["trial"][1])]
                for kind in KINDS:
                    per_kind[kind].append((f"{path.stem} {side}", np.array(events[kind]),
                                           rec.reference["events"][side][kind], scored))
        d = np.array(diffs)
        cells = " ".join(f"{kind.upper()} Se {r['se']:.1f} Pr {r['pr']:.1f}"
                         for kind in KINDS for r in [score(per_kind[kind], IPOL_MATCH_S)])
        print(f"  subjects {half[0]}-{half[-1]}: {refused} of {feet} feet refused; calibration vs standing "
              f"median {np.median(d):.1f}°, max {d.max():.1f}°; {cells}")


def _merged(intervals: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Touching or overlapping intervals joined (gaitmap's reference strides, each ending where the
    next begins, become its walking bouts)."""
    out: list[list[float]] = []
    for a, b in sorted(intervals):
        if out and a <= out[-1][1] + 1e-6:
            out[-1][1] = max(out[-1][1], b)
        else:
            out.append([a, b])
    return [(a, b) for a, b in out]


def _phase_fractions(events: dict, intervals: list[tuple[float, float]],
                     rate_hz: float) -> tuple[float, float]:
    """Mean stance and double-support fraction of the plausible strides of both feet lying wholly in
    ``intervals`` (``events``: side → kind → times, s); NaN when there are none."""
    strides = [c for c in cycles_from_event_times(events, rate_hz)
               if c.plausible and any(a <= c.start and c.end <= b for a, b in intervals)]
    stance = [c.stance_fraction for c in strides]
    double = [c.double_support_fraction for c in strides if np.isfinite(c.double_support_fraction)]
    return (float(np.mean(stance)) if stance else np.nan, float(np.mean(double)) if double else np.nan)


def _halves_sets() -> list[tuple[str, list[tuple[str, object, dict, list[tuple[float, float]], float]]]]:
    """(name, trials) of ipol_gait subjects 1-5 (chosen on), 6-9 (confirmed) and gaitmap_example (motion
    capture, never chosen on); a trial: (label, recording, reference events, scored intervals per side,
    match tolerance s)."""
    sets = []
    folder = DATA / "ipol_gait"
    if folder.is_dir():
        for name, subjects in (("ipol 1-5 (chosen on)", "12345"), ("ipol 6-9 (confirmed)", "6789")):
            paths = sorted((p for p in folder.glob("*.json") if p.stem.split("-")[0] in subjects),
                           key=lambda p: tuple(int(x) for x in p.stem.split("-")))
            trials = []
            for path in paths:
                rec = import_recording("ipol_gait", path)
                span = [rec.reference["trial"]]
                trials.append((path.stem, rec, rec.reference["events"], {"left": span, "right": span},
                               IPOL_MATCH_S))
            sets.append((name, trials))
    else:
        print(f"(skipped ipol_gait: {folder} not found)")
    folder = DATA / "gaitmap_example"
    if folder.is_dir():
        rec = import_gaitmap(folder)
        ref = rec.reference["events"]
        strides = {side: list(zip(ref[side]["start"], ref[side]["end"], strict=True))
                   for side in ("left", "right")}
        sets.append(("gaitmap (mocap, reported)", [("gaitmap", rec, ref, strides, MATCH_S)]))
    return sets


def halves(options: dict) -> None:
    """Issue 47: Algorithm 1's events (``detect_gait_events`` with ``options``) per half of ipol_gait and
    on gaitmap_example: Se/Pr, the timing error's median and mean ± SD, and each trial's stance and
    double support (both feet's plausible strides in the scored span) against the same from the
    reference events, in points: median, worst and how many trials lie within 2 points."""
    print(f"Gait events per half (detector options {options or 'default'}); error = detected - reference")
    print(f"{'data':27} {'kind':4} {'n':>5} {'Se %':>6} {'Pr %':>6} {'median ms':>9} {'mean ± SD ms':>15}")
    phase_lines = []
    for name, trials in _halves_sets():
        per_kind: dict[str, list] = {k: [] for k in KINDS}
        errors: dict[str, list[float]] = {"stance": [], "double support": []}
        refused = []
        for label, rec, ref, intervals, _ in trials:
            detected = {}
            for side in ("left", "right"):
                series = rec.imu[f"{side}_foot"]
                try:
                    events = detect_gait_events(series.gyr, series.acc, series.rate_hz, t=series.t, **options)
                except ValueError as exc:
                    refused.append(f"{label} {side}: {exc}")
                    events = {k: [] for k in KINDS}
                detected[side] = events
                for kind in KINDS:
                    per_kind[kind].append((f"{label} {side}", np.array(events[kind]), ref[side][kind],
                                           intervals[side]))
            rate = rec.imu["left_foot"].rate_hz
            spans = _merged(intervals["left"] + intervals["right"])
            ours = _phase_fractions(detected, spans, rate)
            theirs = _phase_fractions({s: {k: ref[s][k] for k in KINDS} for s in ("left", "right")}, spans,
                                      rate)
            errors["stance"].append(100 * (ours[0] - theirs[0]))
            errors["double support"].append(100 * (ours[1] - theirs[1]))
        for kind in KINDS:
            r = score(per_kind[kind], trials[0][4])
            print(f"{name:27} {kind.upper():4} {r['n']:5d} {r['se']:6.1f} {r['pr']:6.1f} {r['median']:+9.1f} "
                  f"{r['mean']:+7.1f} ± {r['sd']:5.1f}")
        for phase, values in errors.items():
            v = np.array(values)
            ok = v[np.isfinite(v)]
            worst = ok[np.argmax(np.abs(ok))]
            phase_lines.append(f"{name:27} {phase:15} {len(v):6d} {np.median(ok):+7.1f} {worst:+7.1f} "
                               f"{np.sum(np.abs(ok) <= 2.0):5d} of {len(v)}")
        for line in refused:
            print(f"  refused: {line}")
    print("\nPer trial: ours - the reference events' (points of the stride)")
    print(f"{'data':27} {'phase':15} {'trials':>6} {'median':>7} {'worst':>7} {'within 2 points':>15}")
    print("\n".join(phase_lines))


def _cli(*args: str):
    import subprocess

    return subprocess.run([str(REPO / ".venv" / "bin" / "python"), "-m", "gait_biofeedback.cli", *args],
                          capture_output=True, text=True, check=False)


def _recorded_events(bag: Path) -> dict[str, dict[str, np.ndarray]]:
    """side → kind → stamps (s) of the ``/gait/events`` of an ``analyze`` output (none when it has none)."""
    from gait_biofeedback.io.bag_reader import BagReader

    out = {side: {k: [] for k in KINDS} for side in ("left", "right")}
    if (bag / "metadata.yaml").exists():
        for _, m, _ in BagReader(bag).messages(["/gait/events"]):
            kind = INITIAL_CONTACT if m.type == m.INITIAL_CONTACT else TERMINAL_CONTACT
            out[("left", "right")[m.side]][kind].append(m.header.stamp.sec + m.header.stamp.nanosec * 1e-9)
    return {side: {k: np.array(v) for k, v in kinds.items()} for side, kinds in out.items()}


def cli_rows() -> list[tuple[str, str, dict]]:
    """The user's path (``import`` → ``analyze --calibrate-at auto`` → ``/gait/events``) on ipol_gait
    and gaitmap_example, scored as the batch rows (the live event is stamped at its sample)."""
    import subprocess
    import tempfile

    sets = []
    folder = DATA / "ipol_gait"
    if folder.is_dir():
        trials = sorted(folder.glob("*.json"), key=lambda p: tuple(int(x) for x in p.stem.split("-")))
        sets.append((f"ipol_gait CLI ({len(trials)} trials)", "ipol_gait", trials, IPOL_MATCH_S))
    if (DATA / "gaitmap_example").is_dir():
        sets.append(("gaitmap CLI", "gaitmap", [DATA / "gaitmap_example"], MATCH_S))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, kind_of_file, paths, tolerance in sets:
            per_kind: dict[str, list] = {k: [] for k in KINDS}
            failed = []
            for path in paths:
                rec = import_recording(kind_of_file, path)
                bag, out = Path(tmp) / "in", Path(tmp) / "out"
                _cli("import", kind_of_file, str(path), "-o", str(bag))
                done = _cli("analyze", str(bag), "-o", str(out), "--calibrate-at", "auto", "--overwrite")
                if done.returncode:
                    failed.append(f"{path.name}: exit {done.returncode}: {done.stderr.strip()[-200:]}")
                events = _recorded_events(out)
                ref = rec.reference["events"]
                for side in ("left", "right"):
                    scored = ([rec.reference["trial"]] if "trial" in rec.reference
                              else list(zip(ref[side]["start"], ref[side]["end"], strict=True)))
                    for kind in KINDS:
                        reference = np.asarray(ref[side][kind], dtype=float)
                        per_kind[kind].append((f"{path.stem} {side} {kind.upper()}", events[side][kind],
                                               reference, scored))
                for directory in (bag, out):
                    subprocess.run(["rm", "-rf", str(directory)], check=True)
            rows.append((name, "nazarahari", {k: score(per_kind[k], tolerance) for k in KINDS}))
            for line in failed:
                print(f"  {name}: {line}")
    return rows


def _cut_trial(path: Path, folder: Path, first_counter: int) -> None:
    """A copy of the ipol trial ``path`` in ``folder`` without its packets before ``first_counter``
    (the data set's own text format, so the user's ``import ipol_gait`` reads it)."""
    import gzip
    import shutil

    shutil.copy(path, folder / path.name)
    for suffix in ("lf", "rf", "lb"):
        with gzip.open(path.with_name(f"{path.stem}_{suffix}.txt.gz"), "rt") as f:
            lines = f.readlines()
        counter = np.array([float(line.split("\t", 1)[0]) for line in lines[2:]])
        unwrapped = np.concatenate([[0], np.cumsum(np.mod(np.diff(counter), 65536))])
        with gzip.open(folder / f"{path.stem}_{suffix}.txt.gz", "wt") as f:
            f.writelines(lines[:2] + [line for line, c in zip(lines[2:], unwrapped, strict=True)
                                      if c >= first_counter])


def walk_only_cli() -> None:
    """ipol_gait with each trial's standing cut off, through the user's path: the trial's text files
    without their packets before the cut (0.5 s after the longer of the feet's standings, at a packet
    every sensor has), ``import ipol_gait`` → ``analyze --calibrate-at auto`` (no standing: the feet
    calibrate from the walk, ``core/calibration/walk.py``) → ``/gait/events``, scored as
    :func:`walk_only` (from 0.5 s into the cut)."""
    import tempfile

    from gait_biofeedback.core.calibration.foot import standing_run

    for half, trials in _ipol_halves("ipol_gait, the walk only, through import → analyze --calibrate-at "
                                     "auto: trials without foot events, events (±300 ms)"):
        per_kind: dict[str, list] = {k: [] for k in KINDS}
        failed, silent_feet = [], []
        for path in trials:
            rec = import_recording("ipol_gait", path)
            cut = max(rec.imu[f"{side}_foot"].t[standing_run(rec.imu[f"{side}_foot"].gyr,
                                                             rec.imu[f"{side}_foot"].acc, IPOL_RATE_HZ)[1]]
                      for side in ("left", "right")) + 0.5
            counters = [set(np.round(s.t * IPOL_RATE_HZ).astype(int)) for s in rec.imu.values()]
            first = min(c for c in set.intersection(*counters) if c >= cut * IPOL_RATE_HZ)
            with tempfile.TemporaryDirectory() as tmp:
                _cut_trial(path, Path(tmp), first)
                bag, out = Path(tmp) / "in", Path(tmp) / "out"
                _cli("import", "ipol_gait", str(Path(tmp) / path.name), "-o", str(bag))
                done = _cli("analyze", str(bag), "-o", str(out), "--calibrate-at", "auto")
                events = _recorded_events(out)
            shift = first / IPOL_RATE_HZ
            if done.returncode or not any(len(v) for kinds in events.values() for v in kinds.values()):
                failed.append(f"{path.stem}: exit {done.returncode}: {done.stderr.strip()[-300:]}")
            for side in ("left", "right"):
                if not any(len(v) for v in events[side].values()):
                    silent_feet.append(f"{path.stem} {side}")
                ref = rec.reference["events"][side]
                scored = [(max(rec.reference["trial"][0] - shift, 0.5), rec.reference["trial"][1] - shift)]
                for kind in KINDS:
                    per_kind[kind].append((f"{path.stem} {side}", events[side][kind], ref[kind] - shift,
                                           scored))
        cells = " ".join(f"{kind.upper()} Se {r['se']:.1f} Pr {r['pr']:.1f} error {r['mean']:+.1f} ± "
                         f"{r['sd']:.1f} ms" for kind in KINDS for r in [score(per_kind[kind], IPOL_MATCH_S)])
        print(f"  subjects {half[0]}-{half[-1]}: {len(failed)} of {len(trials)} trials without events, "
              f"{len(silent_feet)} of {2 * len(trials)} feet ({', '.join(silent_feet) or 'none'}); {cells}")
        for line in failed:
            print(f"    {line}")
        notes = score(per_kind[INITIAL_CONTACT], IPOL_MATCH_S)["notes"]
        missed = Counter(note.split(":")[0] for note in notes if "missed" in note)
        print("    ICs missed per foot: " + ", ".join(f"{foot} {n}" for foot, n in missed.most_common()))


def simulator_rows() -> list[tuple[str, str, dict]]:
    rows = []
    for scenario in ("walk", "slow_gait"):
        for rate in (100.0, 200.0):
            config = SCENARIOS[scenario](rate_hz=rate)
            config.segments = ("left_foot", "right_foot")
            session = simulate(config)
            for method in METHODS:
                per_kind: dict[str, list] = {k: [] for k in KINDS}
                for side in ("left", "right"):
                    series = session.imu[f"{side}_foot"]
                    events = detect_gait_events(series.gyr, series.acc, rate, method=method)
                    truth = {INITIAL_CONTACT: session.truth.initial_contacts[side],
                             TERMINAL_CONTACT: session.truth.terminal_contacts[side]}
                    span = np.concatenate(list(truth.values()))
                    intervals = [(span.min() - MATCH_S, span.max() + MATCH_S)]
                    for kind in KINDS:
                        label = f"{side} {kind.upper()}"
                        per_kind[kind].append((label, events[kind], truth[kind], intervals))
                rows.append((f"sim {scenario} {rate:g} Hz", method, {k: score(per_kind[k]) for k in KINDS}))
    return rows


def qmt_report() -> None:
    path = DATA / "qmt_fullbody" / "full_body_example_data.mat"
    if not path.is_file():
        print(f"(skipped qmt: {path} not found)")
        return
    rec = import_qmt_fullbody(path)
    rate = rec.imu["left_foot"].rate_hz
    print("\nqmt full-body walk (100 Hz, no reference): plausibility, thesis algorithm. The recording has "
          "leg movements\nat 5-12 s and 39-50 s before the walk; 'bout' = the longest run of plausible "
          "strides")
    print(f"{'foot':6} {'IC':>4} {'TC':>4} {'strides':>8} {'flagged':>8} {'bout':>12} {'TC/stride':>10} "
          f"{'stride s':>12} {'cadence steps/min':>18} {'stance %':>9}")
    traces = {}
    for side in ("left", "right"):
        series = rec.imu[f"{side}_foot"]
        traces[side] = (series, detect_gait_events(series.gyr, series.acc, rate))
    cycles = cycles_from_event_times({side: events for side, (_, events) in traces.items()}, rate)
    for side in ("left", "right"):
        events = traces[side][1]
        mine = [c for c in cycles if c.side == side]
        bout = _longest_plausible_run(mine)
        stride = np.array([c.stride_time for c in bout])
        tcs = np.array(events["tc"])
        tc_per = np.mean([np.sum((tcs > c.start) & (tcs < c.end)) for c in bout])
        span = f"{bout[0].start:.0f}-{bout[-1].end:.0f} s"
        print(f"{side:6} {len(events['ic']):4d} {len(tcs):4d} {len(mine):8d} "
              f"{sum(not c.plausible for c in mine):8d} {span:>12} {tc_per:10.2f} "
              f"{stride.mean():5.2f} ± {stride.std():4.2f} {120.0 / stride.mean():18.1f} "
              f"{100 * np.mean([c.stance_fraction for c in bout]):9.1f}")
    si = [c.step_time_symmetry_index for c in cycles
          if c.plausible and np.isfinite(c.step_time_symmetry_index)]
    if si:
        print(f"step-time symmetry index (last stride): {100 * si[-1]:+.1f} %")
    _write_svg(traces, REPO / "output" / "gait_events_qmt.svg")


def _longest_plausible_run(cycles: list) -> list:
    best: list = []
    run: list = []
    for c in cycles:
        run = [*run, c] if c.plausible else []
        best = run if len(run) > len(best) else best
    return best


def _write_svg(traces: dict, path: Path, t0: float = 54.0, t1: float = 74.0) -> None:
    """Both feet's sagittal gyro (calibrated mediolateral axis) with IC (blue) / TC (red) marks."""
    width, height, lane = 1600, 440, 200
    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}">',
             '<rect width="100%" height="100%" fill="white"/>']
    for row, (side, (series, events)) in enumerate(traces.items()):
        rate = series.rate_hz
        omega = sagittal_rate(series.gyr, foot_calibration(series.gyr, series.acc, rate))
        t = series.t - series.t[0]
        sel = (t >= t0) & (t <= t1)
        y0 = 20 + row * (lane + 20) + lane / 2
        scale = (lane / 2) / max(1e-6, np.abs(omega[sel]).max())

        def x(tt: float) -> float:
            return (tt - t0) / (t1 - t0) * (width - 20) + 10

        points = " ".join(f"{x(a):.1f},{y0 - b * scale:.1f}" for a, b in zip(t[sel], omega[sel], strict=True))
        parts.append(f'<text x="10" y="{y0 - lane / 2 + 12}" font-size="12">{side} foot: sagittal '
                     'gyro (rad/s), IC blue, TC red</text>')
        parts.append(f'<line x1="10" x2="{width - 10}" y1="{y0}" y2="{y0}" stroke="#ccc"/>')
        parts.append(f'<polyline fill="none" stroke="black" stroke-width="1" points="{points}"/>')
        for kind, colour in ((INITIAL_CONTACT, "blue"), (TERMINAL_CONTACT, "red")):
            for te in events[kind]:
                if t0 <= te <= t1:
                    parts.append(f'<line x1="{x(te):.1f}" x2="{x(te):.1f}" y1="{y0 - lane / 2}" '
                                 f'y2="{y0 + lane / 2}" stroke="{colour}"/>')
    parts.append("</svg>")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(parts))
    print(f"plot: {path} ({t0:g}-{t1:g} s)")


def _cost_us() -> float:
    config = SCENARIOS["walk"]()
    config.segments = ("left_foot",)
    session = simulate(config)
    q = session.truth.sensor_orientation["left_foot"].tolist()
    stamps = seconds_to_ns(session.truth.t).tolist()
    detector = GaitEventDetector(rate_hz=100.0, mounting=session.truth.mounting["left_foot"])
    start = time.perf_counter()
    for k in range(len(q)):
        detector.update(stamps[k], q[k])
    return (time.perf_counter() - start) / len(q) * 1e6


RATES_HZ = (20.0, 50.0, 100.0, 200.0, 400.0)


def rate_rows() -> None:
    """Issue 15 item 5: the same real recordings resampled to 20-400 Hz (``_resample``), Algorithm 1
    through ``detect_gait_events`` at each rate; the same scoring as the main table."""
    from _resample import resample

    sets = []
    folder = DATA / "gaitmap_example"
    if folder.is_dir():
        rec = import_gaitmap(folder)
        ref = rec.reference["events"]
        feet = [(side, rec.imu[f"{side}_foot"], ref[side],
                 list(zip(ref[side]["start"], ref[side]["end"], strict=True)))
                for side in ("left", "right")]
        sets.append(("gaitmap (204.8 Hz)", rec.imu["left_foot"].rate_hz, feet, MATCH_S))
    folder = DATA / "ipol_gait"
    if folder.is_dir():
        feet = []
        for path in sorted(folder.glob("*.json"), key=lambda p: tuple(int(x) for x in p.stem.split("-"))):
            rec = import_recording("ipol_gait", path)
            feet += [(f"{path.stem} {side}", rec.imu[f"{side}_foot"], rec.reference["events"][side],
                      [rec.reference["trial"]]) for side in ("left", "right")]
        sets.append(("ipol_gait (100 Hz)", IPOL_RATE_HZ, feet, IPOL_MATCH_S))
    print("\nGait events at other rates (real recordings resampled; Algorithm 1): Se / Pr %, error ms")
    print(f"{'data':20} {'rate Hz':>7} {'IC Se':>6} {'IC Pr':>6} {'IC error ms':>14} {'TC Se':>6} "
          f"{'TC Pr':>6} {'TC error ms':>14} refused")
    for name, native, feet, tolerance in sets:
        for rate in RATES_HZ:
            per_kind: dict[str, list] = {k: [] for k in KINDS}
            refused = 0
            for label, series, reference, intervals in feet:
                t, both = resample(series.t, np.hstack([series.gyr, series.acc]), native, rate)
                try:
                    events = detect_gait_events(both[:, :3], both[:, 3:], rate, t=t)
                except ValueError:
                    refused += 1
                    events = {k: [] for k in KINDS}
                for kind in KINDS:
                    per_kind[kind].append((f"{label} {kind}", np.array(events[kind]), reference[kind],
                                           intervals))
            cells = []
            for kind in KINDS:
                r = score(per_kind[kind], tolerance)
                cells.append(f"{r['se']:6.1f} {r['pr']:6.1f} {r['mean']:6.1f} ± {r['sd']:5.1f}")
            print(f"{name:20} {rate:7.0f} " + " ".join(cells) + f" {refused}")


def main() -> None:
    import sys

    if "--rates" in sys.argv:
        rate_rows()
        return
    if "--halves" in sys.argv:
        options = {}
        for flag in ("--event-margin", "--heel-strike-shift-max-s", "--toe-off-shift-max-s"):
            if flag in sys.argv:
                options[flag[2:].replace("-", "_")] = float(sys.argv[sys.argv.index(flag) + 1])
        halves(options)
        return
    if "--walk-only" in sys.argv:
        walk_only_cli() if "--cli" in sys.argv else walk_only()
        return
    start = time.perf_counter()
    ipol, refusals = ipol_rows()
    rows = gaitmap_rows() + ipol + simulator_rows() + (cli_rows() if "--cli" in sys.argv else [])
    print("Gait events: Se/Pr % (±500 ms, thesis Eq 53), error = detected − reference, ms (mean ± SD)")
    print(f"{'data':28} {'method':17} {'n IC':>5} {'IC Se':>6} {'IC Pr':>6} {'IC error ms':>14} "
          f"{'n TC':>5} {'TC Se':>6} {'TC Pr':>6} {'TC error ms':>14}")
    notes: list[str] = []
    for data, method, result in rows:
        cells = []
        for kind in KINDS:
            r = result[kind]
            cells.append(f"{r['n']:5d} {r['se']:6.1f} {r['pr']:6.1f} {r['mean']:6.1f} ± {r['sd']:5.1f}")
        print(f"{data:28} {method:17} " + " ".join(cells))
        notes += [f"  {data}, {method}: {n}" for kind in KINDS for n in result[kind]["notes"]]
    print(f"ipol_gait: {len(refusals)} feet refused (scored as all events missed), Se/Pr within "
          f"±{IPOL_MATCH_S * 1000:.0f} ms" + "".join(f"\n  {r}" for r in refusals))
    if notes:
        print(f"unmatched events ({len(notes)}, first 40):")
        print("\n".join(notes[:40]))
    qmt_report()
    print(f"\nstreaming detector cost: {_cost_us():.1f} µs per sample (pure Python, one foot)")
    print(f"run time {time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    main()
