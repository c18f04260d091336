"""Sensor faults through the offline graph: ``.venv/bin/python benchmarks/faults.py [--seed 1]``

The simulator's demo session (calibrated at 36 s, hip flexion), clean and with each fault of issue 13
alone and all four together (:mod:`gait_biofeedback.sim.faults`): every sensor silent 2 s at 60 s,
two left-shank samples out of order at 70 s, the right-foot accelerometer at 1e6 m/s² on 3 samples
at 75 s, one left-thigh stamp 0.5 s early at 80 s. Each row runs ``analyze`` (the live graph's core
objects) and prints:

- samples lost (raw IMU samples the orientation stage did not turn into orientations);
- knee and ankle flexion RMSE against the truth over the session (deg, left/right);
- the worst flexion error from each fault to 1 s after it (deg; the re-acquired samples in it are
  marked and give no feedback), and more than 1 s after every fault, against the clean run's worst;
- the time after each fault's end until every flexion angle stays within 2° of the clean run (s, the
  longest over the row's faults);
- gait-event sensitivity (IC), plausible strides overlapping a dropout of a foot sensor (a stride is
  timed by the feet: while only a shank is off it stays plausible, and its knee gets no cue because
  the knee angles are missing), chest steps;
- then, per row, what ``/diagnostics`` said (the orientation statuses ``analyze`` writes, as the
  node does) from each fault to 3 s after it.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from gait_biofeedback.batch import (
    SCENARIOS,
    BagReader,
    Dropout,
    Reorder,
    Spike,
    StampJump,
    analyze_recording,
    format_report,
    session_report,
    simulate,
    write_faulty_bag,
    write_simulated_bag,
)
from gait_biofeedback.wire.stamps import stamp_to_ns

FLEXION = ("left_knee_flexion", "right_knee_flexion", "left_ankle_dorsiflexion", "right_ankle_dorsiflexion")
FAULTS = {
    "dropout 2 s, every sensor": [Dropout(60.0, 2.0)],
    "2 samples out of order": [Reorder("left_shank", 70.0)],
    "acc 1e6 m/s² × 3 samples": [Spike("right_foot", 75.0)],
    "stamp 0.5 s early": [StampJump("left_thigh", 80.0)],
}
FAULTS["all four"] = [f for faults in FAULTS.values() for f in faults]
FAULTS["left shank off 6 s"] = [Dropout(60.0, 6.0, ("left_shank",))]
FAULTS["hole 0.1 s, every sensor"] = [Dropout(60.0, 0.1)]
FAULTS["hole 0.3 s, every sensor"] = [Dropout(60.0, 0.3)]
CALIBRATE_AT = 36.0


def _angles(path: Path) -> tuple[dict[int, dict[str, float]], dict[int, dict[str, float]]]:
    """(estimated, true) flexion angles by stamp."""
    est: dict[int, dict[str, float]] = {}
    true: dict[int, dict[str, float]] = {}
    with BagReader(path) as reader:
        for topic, msg, _ in reader.messages(["/joint_states", "/ground_truth/joint_states"]):
            target = est if topic == "/joint_states" else true
            target[stamp_to_ns(msg.header.stamp)] = {n: p for n, p in zip(msg.name, msg.position, strict=True)
                                            if n in FLEXION}
    return est, true


def _plausible_across(path: Path, spans: list[tuple[float, float]], start_ns: int) -> int:
    count = 0
    with BagReader(path) as reader:
        for _, msg, _ in reader.messages(["/gait/cycles"]):
            lo = (stamp_to_ns(msg.start) - start_ns) / 1e9
            hi = (stamp_to_ns(msg.header.stamp) - start_ns) / 1e9
            if msg.plausible and any(lo < b and hi > a for a, b in spans if b > a):
                count += 1
    return count


def _diagnostics(path: Path, spans: list[tuple[float, float]], start_ns: int) -> list[str]:
    """The distinct WARN/ERROR texts of /diagnostics stamped from a fault to 3 s after it."""
    said: list[str] = []
    with BagReader(path) as reader:
        for _, msg, _ in reader.messages(["/diagnostics"]):
            t = (stamp_to_ns(msg.header.stamp) - start_ns) / 1e9
            if not any(a <= t <= b + 3.0 for a, b in spans):
                continue
            for status in msg.status:
                text = f"{status.name.split(': ')[-1]}: {status.message}"
                if status.level != b"\x00" and text not in said:
                    said.append(text)
    return said


def _run(bag: Path, out: Path) -> tuple[object, dict]:
    result = analyze_recording(bag, out, calibrate_at=[(CALIBRATE_AT, "hip_flexion")])
    return result, session_report(out)


def main() -> None:
    """Run every fault and print the table."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--verbose", action="store_true", help="also print each run's report and notices")
    args = parser.parse_args()
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        clean_bag = write_simulated_bag(work / "clean", simulate(SCENARIOS["demo"](seed=args.seed)))
        with BagReader(clean_bag) as reader:
            start_ns = reader.start_time_ns
            raw = sum(n for t, n in reader.message_counts().items() if t.endswith("/imu/data_raw"))
        clean_result, clean_report = _run(clean_bag, work / "clean_out")
        clean_est, true = _angles(work / "clean_out")
        clean_worst = max(abs(v - true[ns][n]) for ns, a in clean_est.items() if ns in true
                          for n, v in a.items())
        rows = [("clean", clean_result, clean_report, 0, 0.0, clean_worst, 0.0, [])]
        for name, faults in FAULTS.items():
            bag = write_faulty_bag(clean_bag, work / f"bag_{len(rows)}", faults)
            result, report = _run(bag, work / f"out_{len(rows)}")
            est, _ = _angles(work / f"out_{len(rows)}")
            spans = [f.span for f in faults]
            after = [start_ns + round((b + 1.0) * 1e9) for _, b in spans]
            before = [start_ns + round(a * 1e9) for a, _ in spans]

            def outside(ns: int, before=before, after=after) -> bool:
                return not any(lo <= ns < hi for lo, hi in zip(before, after, strict=True))

            worst = max((abs(v - true[ns][n]) for ns, a in est.items() if ns in true and outside(ns)
                         for n, v in a.items()), default=np.nan)
            during = max((abs(v - true[ns][n]) for ns, a in est.items() if ns in true and not outside(ns)
                          for n, v in a.items()), default=0.0)
            recover = 0.0
            for k, (_, b) in enumerate(sorted(spans)):
                end = start_ns + round(b * 1e9)
                following = sorted(spans)[k + 1][0] if k + 1 < len(spans) else np.inf
                until = start_ns + round(min(following, b + 10.0) * 1e9)
                off = [ns for ns, a in est.items() if end <= ns < until and ns in clean_est
                       and any(abs(v - clean_est[ns].get(n, v)) > np.radians(2.0) for n, v in a.items())]
                recover = max(recover, (max(off) - end) / 1e9 if off else 0.0)
            said = _diagnostics(result.output, spans, start_ns)
            feet = [f.span for f in faults if isinstance(f, Dropout)
                    and (not f.segments or {"left_foot", "right_foot"} & set(f.segments))]
            rows.append((name, result, report, _plausible_across(result.output, feet, start_ns), during,
                         worst, recover, said))
            if args.verbose:
                print(f"== {name}")
                print("\n".join(format_report(report)))
                print("\n".join(f"  said: {w}" for w in result.warnings))
    print(f"demo session, seed {args.seed}; calibrated at {CALIBRATE_AT:g} s; clean worst flexion error "
          f"{np.degrees(clean_worst):.1f}°; {time.monotonic() - t0:.0f} s")
    head = (f"{'fault':28s} {'lost':>5s} {'knee RMSE L/R':>14s} {'ankle RMSE L/R':>15s} {'during':>7s} "
            f"{'worst >1 s':>10s} "
            f"{'recover':>8s} {'IC Se':>6s} {'strides':>7s} {'steps':>5s}")
    print(head)
    for name, result, report, across, during, worst, recover, _ in rows:
        lost = raw - sum(n for t, n in result.counts.items() if t.endswith("/imu/data"))
        r = report.joint_rmse
        knee = f"{np.degrees(r['left_knee_flexion']):.1f}/{np.degrees(r['right_knee_flexion']):.1f}"
        ankle = (f"{np.degrees(r['left_ankle_dorsiflexion']):.1f}/"
                 f"{np.degrees(r['right_ankle_dorsiflexion']):.1f}")
        print(f"{name:28s} {lost:5d} {knee:>14s} {ankle:>15s} {np.degrees(during):6.1f}° "
              f"{np.degrees(worst):9.1f}° {recover:7.1f}s "
              f"{100 * report.events['ic'].sensitivity:5.1f}% {across:7d} {report.steps:5d}")
    print("\n/diagnostics from each fault to 3 s after it (each distinct text, and the sensors saying it):")
    for name, *_, said in rows[1:]:
        by_text: dict[str, list[str]] = {}
        for entry in said:
            segment, text = entry.split(": ", 1)
            for part in text.split("; "):
                if segment not in by_text.setdefault(part, []):
                    by_text[part].append(segment)
        print(f"  {name}:")
        for text, segments in by_text.items() or {"nothing": []}.items():
            print(f"    {text}" + (f"  [{', '.join(segments)}]" if segments else ""))


if __name__ == "__main__":
    main()
