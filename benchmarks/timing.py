"""Wall-clock figures the tests no longer assert: replay pacing and the simulator's speed.

A test run beside other busy programs (a CI runner, two engineers on one machine) slows every process
and delays every thread, so a figure of milliseconds or seconds failed there and passed alone (issue 46:
a fresh clone's ``make test`` beside two busy processes). The tests keep the behaviour (the replayer
paces at recorded time / speed, the simulator makes the demo); the figures are measured here, on a quiet
machine, against the bounds the tests used to hold them to.

1. Replay pacing (was test/test_graph.py::test_replayer_keeps_original_timing): one sensor, 1 s at
   100 Hz, replayed ``--runs`` times at 1x and at 10x to a subscriber in this process that notes each
   sample's arrival. The first 50 ms of each replay are left out (DDS can hold the first samples after
   the match, which is not the replayer's pacing); of the others, |arrival - recorded time / speed|
   about its median: p50, p95, max in ms. Former bound: p95 < 5 ms, max < 20 ms, every run.
2. The simulator's speed (was test/test_simulator.py::test_demo_duration_turn_and_speed_of_simulation):
   ``simulate(SCENARIOS["demo"]())``, its wall time per run. Former bound: < 5 s.

Run:  .venv/bin/python benchmarks/timing.py [--runs 5] [--part all|pacing|simulate]
Exit 1 when a figure is past its former bound (a quiet machine should meet them all).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

PACING_BOUND_MS = {"p95": 5.0, "max": 20.0}
SIMULATE_BOUND_S = 5.0


def pacing_errors_ms(context, bag: Path, speed: float) -> np.ndarray:
    """|arrival - recorded offset / speed| about the median, ms, of the samples after the first 50 ms."""
    from gait_biofeedback.nodes.imu_replayer import replay_arrivals

    stamps, wall = (np.array(v) for v in replay_arrivals(context, bag, speed))
    expected, arrived = (stamps - stamps[0]) / speed, wall - wall[0]
    settled = expected >= 0.05
    lag = arrived[settled] - expected[settled]
    return np.abs(lag - np.median(lag)) * 1e3


def pacing(runs: int) -> bool:
    import rclpy
    from rclpy.context import Context

    from gait_biofeedback.core.segments import ImuSeries
    from gait_biofeedback.io.bag import write_imu_bag

    rng = np.random.default_rng(0)
    t = 1000.0 + np.arange(100) / 100.0
    acc = rng.normal(0, 3, (100, 3)) + np.array([0.0, 0.0, 9.81])
    series = ImuSeries("left_foot", t, acc, rng.normal(0, 1, (100, 3)), None)
    bag = write_imu_bag(Path(tempfile.mkdtemp(prefix="timing-")) / "in", {"left_foot": series})
    context = Context()
    rclpy.init(args=[], context=context)  # ROS_DOMAIN_ID: one no other graph on this machine uses
    ok = True
    print("replay pacing, |arrival - recorded time / speed| about its median (ms), 1 s at 100 Hz, "
          f"first 50 ms left out; former test bound p95 < {PACING_BOUND_MS['p95']:g}, "
          f"max < {PACING_BOUND_MS['max']:g}")
    print("| speed | run | p50 | p95 | max | within |")
    print("|---|---|---|---|---|---|")
    try:
        for speed in (1.0, 10.0):
            for run in range(1, runs + 1):
                e = pacing_errors_ms(context, bag, speed)
                p95, worst = float(np.percentile(e, 95)), float(e.max())
                within = p95 < PACING_BOUND_MS["p95"] and worst < PACING_BOUND_MS["max"]
                ok &= within
                print(f"| {speed:g}x | {run} | {np.percentile(e, 50):.2f} | {p95:.2f} | {worst:.2f} | "
                      f"{'yes' if within else 'NO'} |")
    finally:
        rclpy.shutdown(context=context)
    return ok


def simulate_speed(runs: int) -> bool:
    from gait_biofeedback.sim.simulator import SCENARIOS, simulate

    seconds = []
    for _ in range(runs):
        start = time.perf_counter()
        simulate(SCENARIOS["demo"]())
        seconds.append(time.perf_counter() - start)
    worst = max(seconds)
    print(f"\nsimulate demo: {', '.join(f'{s:.2f}' for s in seconds)} s "
          f"(former test bound < {SIMULATE_BOUND_S:g} s: {'yes' if worst < SIMULATE_BOUND_S else 'NO'})")
    return worst < SIMULATE_BOUND_S


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5, help="runs per figure [%(default)s]")
    parser.add_argument("--part", choices=("all", "pacing", "simulate"), default="all")
    args = parser.parse_args()
    ok = True
    if args.part in ("all", "pacing"):
        ok &= pacing(args.runs)
    if args.part in ("all", "simulate"):
        ok &= simulate_speed(args.runs)
    print(f"\nload average while measured: {', '.join(f'{v:.2f}' for v in os.getloadavg())}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
