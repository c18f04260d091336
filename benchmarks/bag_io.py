"""Throughput of the bag I/O: ``.venv/bin/python benchmarks/bag_io.py [--seconds 120] [--out DIR]``.

Writes 8 segments × 100 Hz (Imu + MagneticField) with :func:`write_imu_bag`, reads it back with
:func:`read_imu_bag`, :meth:`BagReader.raw_messages` and (rclpy objects) :meth:`BagReader.messages`,
and writes rclpy messages through :meth:`BagWriter.write`; prints messages per second.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from gait_biofeedback.batch import SEGMENTS, BagReader, BagWriter, ImuSeries, read_imu_bag, write_imu_bag
from gait_biofeedback.wire.imu import series_messages


def _rate(label: str, count: int, seconds: float) -> None:
    print(f"{label:44s} {count:8d} msgs {seconds:6.2f} s {count / seconds:10,.0f} msg/s")


def main() -> None:
    """Run the benchmark and print one line per measurement."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seconds", type=float, default=120.0, help="recording length (s)")
    parser.add_argument("--out", type=Path, default=None, help="folder for the bags (default: a temp dir)")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    n = round(100 * args.seconds)
    t = (1_700_000_000_000_000_000 + np.arange(n) * 10_000_000) / 1e9
    imu = {
        s: ImuSeries(s, t, rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), rng.normal(size=(n, 3)) * 5e-5)
        for s in SEGMENTS
    }
    total = 2 * n * len(SEGMENTS)
    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or Path(tmp)
        t0 = time.perf_counter()
        bag = write_imu_bag(out / "bench_imu", imu, overwrite=True)
        _rate("write_imu_bag (numpy CDR)", total, time.perf_counter() - t0)
        t0 = time.perf_counter()
        back = read_imu_bag(bag)
        _rate("read_imu_bag (numpy CDR)", total, time.perf_counter() - t0)
        same = all(
            np.array_equal(back[s].acc, imu[s].acc) and np.array_equal(back[s].t, imu[s].t) for s in imu
        )
        size = sum(f.stat().st_size for f in bag.glob("*.mcap"))
        print(f"round trip identical: {same}; file size {size:,} B")
        with BagReader(bag) as reader:
            t0 = time.perf_counter()
            count = sum(1 for _ in reader.raw_messages())
            _rate("BagReader.raw_messages", count, time.perf_counter() - t0)
            t0 = time.perf_counter()
            count = sum(1 for _ in reader.messages(topics=["/pelvis/imu/data_raw", "/pelvis/imu/mag"]))
            _rate("BagReader.messages (rclpy, 2 topics)", count, time.perf_counter() - t0)
        messages = list(series_messages(imu["pelvis"]))
        t0 = time.perf_counter()
        with BagWriter(out / "bench_rclpy", overwrite=True) as writer:
            for topic, msg, t_ns in messages:
                writer.write(topic, msg, t_ns)
        _rate("BagWriter.write (rclpy serialize, 1 segment)", len(messages), time.perf_counter() - t0)


if __name__ == "__main__":
    main()
