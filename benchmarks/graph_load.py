"""CPU load and message loss of the in-process node graph at live rate (prints a table).

Replays ``--seconds`` of the demo session (8 IMUs at 100 Hz with magnetometers) at ``--speed``
through growing sets of nodes, recording everything, and reports per set: CPU time of the process
per second of recording (100 % = one core), and how many raw samples and orientations reached the
recording (loss = best-effort samples dropped somewhere in the graph).

    .venv/bin/python benchmarks/graph_load.py [--seconds 20] [--speed 1]
"""

from __future__ import annotations

import argparse
import resource
import tempfile
from pathlib import Path

from gait_biofeedback.demo import ensure_demo_bag
from gait_biofeedback.graph import replay_through_graph
from gait_biofeedback.io.bag import BagReader

STAGES = (
    [],
    ["orientation_filter"],
    ["orientation_filter", "calibration"],
    ["orientation_filter", "calibration", "joint_angles"],
    ["orientation_filter", "calibration", "joint_angles", "gait_events"],
    ["orientation_filter", "calibration", "joint_angles", "gait_events", "activity_monitor"],
)


def cpu_seconds() -> float:
    """User + system CPU time of this process so far."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--speed", type=float, default=1.0)
    args = parser.parse_args()
    bag, _ = ensure_demo_bag(Path("bags/demo_walk.mcap"))
    expected = round(args.seconds * 100) * 8
    print(f"demo session, first {args.seconds:g} s at {args.speed:g}x; {expected} raw IMU samples expected")
    print(f"{'nodes (each row adds one)':36s}{'CPU % of a core':>16s}{'raw kept':>10s}{'orient.':>9s}")
    for stage in STAGES:
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "out"
            before = cpu_seconds()
            replay_through_graph(bag, out, speed=args.speed, nodes=stage, stop_offset=args.seconds,
                                 node_parameters={"calibration": {"session_dir": str(Path(tmp) / "s")}})
            cpu = cpu_seconds() - before
            counts = BagReader(out).message_counts()
        raw = sum(n for t, n in counts.items() if t.endswith("/imu/data_raw"))
        orientations = sum(n for t, n in counts.items() if t.endswith("/imu/data"))
        label = "+ " + stage[-1] if stage else "replayer + recorder"
        load = 100.0 * cpu / (args.seconds / args.speed)
        print(f"{label:36s}{load:15.0f}%{100.0 * raw / expected:9.1f}%"
              f"{100.0 * orientations / expected if stage else float('nan'):8.1f}%")


if __name__ == "__main__":
    main()
