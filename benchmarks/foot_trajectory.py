"""CPU time of the foot-trajectory stage (issue 46): per foot sample through the gait-events stream, and
the batch API over a long recording.

``PYTHONPATH=. .venv/bin/python benchmarks/foot_trajectory.py [--seconds 120] [--long-seconds 600]``

Prints: µs of CPU per foot sample of
:meth:`~gait_biofeedback.core.gait.stream.GaitEventStream.update` (both feet of a simulated walk, with
orientations, gyro and acceleration: the ``gait_events`` node's and ``analyze``'s path), the part of it
in :meth:`~gait_biofeedback.core.spatial.stream.FootTrajectoryStream.update`, and the seconds of CPU of
:func:`gait_biofeedback.batch.estimate_foot_trajectory` on one foot of a ``--long-seconds`` walk (its
``live_strides`` count as a check). Runs on any revision with these APIs (run it with ``PYTHONPATH`` at
another checkout to compare); numba's compilation is done before the clocks start.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from gait_biofeedback.batch import SCENARIOS, estimate_foot_trajectory, simulate
from gait_biofeedback.core.gait.stream import GaitEventsParams, GaitEventStream
from gait_biofeedback.core.spatial import stream as spatial_stream


def per_sample(seconds: float) -> tuple[float, float, int]:
    """(µs per foot sample of GaitEventStream.update, of it in FootTrajectoryStream.update, strides)."""
    sim = simulate(SCENARIOS["walk"](seconds, seed=5, segments=("left_foot", "right_foot")))
    rows = []
    for side in ("left", "right"):
        imu = sim.imu[f"{side}_foot"]
        q = sim.truth.sensor_orientation[f"{side}_foot"]
        stamps = np.round(imu.t * 1e9).astype(np.int64)
        rows += [(int(stamps[k]), side, tuple(q[k].tolist()), tuple(imu.gyr[k].tolist()),
                  tuple(imu.acc[k].tolist())) for k in range(len(stamps))]
    rows.sort(key=lambda row: row[0])
    stream = GaitEventStream(GaitEventsParams(use_standing_reference=True))
    foot_s = [0.0]
    original = spatial_stream.FootTrajectoryStream.update

    def timed(self, *args):
        start = time.process_time()
        out = original(self, *args)
        foot_s[0] += time.process_time() - start
        return out

    spatial_stream.FootTrajectoryStream.update = timed
    strides = 0
    start = time.process_time()
    for stamp_ns, side, q, gyr, acc in rows:
        strides += len(stream.update(side, stamp_ns, q, gyr=gyr, acc=acc)[1])
    total = time.process_time() - start
    spatial_stream.FootTrajectoryStream.update = original
    return total / len(rows) * 1e6, foot_s[0] / len(rows) * 1e6, strides


def batch(seconds: float) -> tuple[float, int]:
    """(s of CPU of estimate_foot_trajectory on one foot of a ``seconds`` walk, its live strides)."""
    imu = simulate(SCENARIOS["walk"](seconds, seed=6, segments=("left_foot",))).imu["left_foot"]
    start = time.process_time()
    result = estimate_foot_trajectory(imu.gyr, imu.acc, 100.0)
    return time.process_time() - start, len(result["live_strides"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=120.0, help="the walk for the per-sample time")
    parser.add_argument("--long-seconds", type=float, default=600.0, help="the walk for the batch API")
    args = parser.parse_args()
    warm = simulate(SCENARIOS["walk"](8.0, seed=1, segments=("left_foot",))).imu["left_foot"]
    estimate_foot_trajectory(warm.gyr, warm.acc, 100.0)  # compiled (or loaded) before the clocks start
    us, foot_us, strides = per_sample(args.seconds)
    print(f"GaitEventStream.update: {us:.1f} us CPU per foot sample, of which FootTrajectoryStream.update "
          f"{foot_us:.1f} us ({args.seconds:.0f} s walk, 2 feet, {strides} strides out)")
    seconds, live = batch(args.long_seconds)
    print(f"estimate_foot_trajectory: {seconds:.2f} s CPU for one foot of a {args.long_seconds:.0f} s walk "
          f"({live} live strides)")


if __name__ == "__main__":
    main()
