"""Offline throughput: ``analyze`` on long sessions and ``batch`` on Dask workers.

Run: ``.venv/bin/python benchmarks/throughput.py`` (about 25 min on 2 cores; ``--cohort 16`` for a
shorter look). All recordings are made by the simulator (``gait-biofeedback simulate --scenario
training --duration S``: 8 sensors at 100 Hz, the demo's calibration, then 50 s walking laps).

1. ``analyze`` (``--calibrate-at auto``, output bag written) of a 60 s and a 600 s session, each in a
   fresh process, wall time: the marginal throughput ``(600 - 60) s / (t600 - t60)`` is in real-time
   factors, with start-up (imports, numba compilation) cancelled out; the whole-run factors too.
2. ``batch`` of 8 sessions of 60 s on a local cluster of 1 and of 2 workers (``--no-report``, so that
   analysis is what is compared): the speed-up of 2 workers over 1, and the workers' peak memory
   (``worker_peak_rss_mb`` of the cohort table).
3. ``batch`` of ``--cohort`` sessions of 108 s (100 = 3 h of data; reports included) on 2 workers:
   wall time, and the time 100 sessions take at that rate.

The issue's targets: marginal >= 100x real time, 2 workers >= 1.8x one, 100 sessions <= 5 min.

``--against REV [--pairs N] [--durations 120,600]`` instead compares this checkout's ``analyze`` with
the one of the git revision ``REV`` (a temporary worktree, run with this venv), the two side by side,
one per core, on the same simulated session, ``N`` pairs per duration: their user CPU seconds and the
ratio. This machine's speed drifts during a day by as much as a change is worth (the same 600 s
session took 119 s and 210 s on two evenings); run at the same time, both sides see the same machine.
"""

from __future__ import annotations

import argparse
import csv
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CLI = [sys.executable, "-m", "gait_biofeedback.cli"]


def _run(args: list[str]) -> float:
    started = time.perf_counter()
    subprocess.run([*CLI, *args], check=False, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    return time.perf_counter() - started


def _simulate(path: Path, duration: float, seed: int) -> None:
    subprocess.run(
        [
            *CLI,
            "simulate",
            "--scenario",
            "training",
            "--duration",
            str(duration),
            "--seed",
            str(seed),
            "-o",
            str(path),
        ],
        check=True,
        stdout=subprocess.DEVNULL,
    )


def analyze_rates(work: Path) -> None:
    times = {}
    for duration in (60.0, 600.0):
        bag = work / f"session_{duration:.0f}"
        _simulate(bag, duration, 1)
        times[duration] = _run(
            ["analyze", str(bag), "-o", str(work / f"an_{duration:.0f}"), "--calibrate-at", "auto"]
        )
    marginal = (600.0 - 60.0) / (times[600.0] - times[60.0])
    print("\n1. analyze, one process, one core (8 sensors at 100 Hz)")
    print(f"{'session':>9} {'wall s':>8} {'x real time':>12}")
    for duration, t in times.items():
        print(f"{duration:>8.0f}s {t:>8.1f} {duration / t:>12.1f}")
    print(f"marginal (600 s - 60 s): {marginal:.1f}x real time   (target >= 100x)")


def _batch(inputs: Path, out: Path, workers: int, report: bool) -> tuple[float, list[dict]]:
    args = ["batch", str(inputs), "-o", str(out), "--workers", str(workers)] + (
        [] if report else ["--no-report"]
    )
    wall = _run(args)
    with (out / "cohort.csv").open() as f:
        return wall, list(csv.DictReader(f))


def batch_scaling(work: Path) -> None:
    inputs = work / "eight"
    for k in range(8):
        _simulate(inputs / f"s{k}", 60.0, 10 + k)
    walls = {}
    for workers in (1, 2):
        walls[workers], rows = _batch(inputs, work / f"eight_out_{workers}", workers, report=False)
        failed = [r["session"] for r in rows if r["status"] != "done"]
        peak = max(float(r["worker_peak_rss_mb"]) for r in rows)
        print(
            f"   {workers} worker(s): {walls[workers]:6.1f} s wall, peak memory per worker {peak:.0f} MB"
            + (f", FAILED {failed}" if failed else "")
        )
    print(f"   speed-up 2 workers / 1: {walls[1] / walls[2]:.2f}x   (target >= 1.8x)")


def cohort(work: Path, n: int) -> None:
    inputs = work / "cohort"
    for k in range(n):
        _simulate(inputs / f"p{k:03d}", 108.0, 100 + k)
    wall, rows = _batch(inputs, work / "cohort_out", 2, report=True)
    hours = sum(float(r["duration_s"] or 0.0) for r in rows) / 3600.0
    done = sum(r["status"] == "done" for r in rows)
    print(
        f"\n3. batch of {n} sessions ({hours:.2f} h of data, reports included) on 2 workers: {wall:.0f} s "
        f"wall, {done} done; at that rate 100 sessions take {wall / n * 100 / 60:.1f} min (target <= 5)"
    )


def _analyze_started(code: Path, bag: Path, out: Path) -> subprocess.Popen:
    """``analyze`` with the package in ``code``, started now (:func:`_user_cpu` waits for it)."""
    return subprocess.Popen([*CLI, "analyze", str(bag), "-o", str(out), "--calibrate-at", "auto"], cwd=code,
                            env={**os.environ, "PYTHONPATH": str(code)}, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)


def _user_cpu(process: subprocess.Popen) -> float:
    """The user CPU seconds of a finished child (``os.wait4``'s resource usage)."""
    _, status, usage = os.wait4(process.pid, 0)
    if status:
        raise RuntimeError(f"analyze failed (wait status {status})")
    return usage.ru_utime


def compare(work: Path, revision: str, pairs: int, durations: list[float]) -> None:
    here = Path(__file__).resolve().parent.parent
    other = work / "other"
    subprocess.run(["git", "-C", str(here), "worktree", "add", "--detach", str(other), revision], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        print(f"analyze --calibrate-at auto, user CPU s: {revision} | this checkout, side by side")
        for duration in durations:
            bag = work / f"session_{duration:.0f}"
            _simulate(bag, duration, 1)
            for k in range(pairs):
                runs = [_analyze_started(code, bag, work / f"out_{side}_{duration:.0f}_{k}")
                        for side, code in (("other", other), ("this", here))]
                old, new = (_user_cpu(p) for p in runs)
                print(f"{duration:>6.0f} s session, pair {k + 1}: {old:7.1f} | {new:7.1f}   "
                      f"ratio {new / old:.3f}")
    finally:
        subprocess.run(["git", "-C", str(here), "worktree", "remove", "--force", str(other)], check=False,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--cohort", type=int, default=100, help="sessions of part 3 [%(default)s]")
    parser.add_argument("--against", metavar="REV", help="compare analyze with git revision REV instead")
    parser.add_argument("--pairs", type=int, default=3, help="side-by-side runs per duration [%(default)s]")
    parser.add_argument("--durations", default="120,600", help="session lengths, s [%(default)s]")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="throughput_") as tmp:
        work = Path(tmp)
        if args.against:
            compare(work, args.against, args.pairs, [float(d) for d in args.durations.split(",")])
            return
        analyze_rates(work)
        print("\n2. batch of 8 sessions of 60 s, --no-report")
        batch_scaling(work)
        if args.cohort:
            cohort(work, args.cohort)


if __name__ == "__main__":
    main()
