"""Single-byte corruption of a complete recording: is a changed byte ever read as data?

``.venv/bin/python benchmarks/corruption.py [--flips 60] [--bag DIR]``

Writes a 20 s, 8-segment recording (or takes ``--bag``), then for each of ``--flips`` byte positions
spread evenly over its .mcap file flips that byte in a copy and reads the copy with
:class:`BagReader`. Each copy is one of: refused as a whole (not an MCAP file any more), read
identical, read with messages lost *and a warning*, read with messages lost silently, or read with
changed data (a message that is not in the original). Prints the counts.
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import warnings
from pathlib import Path

import numpy as np

from gait_biofeedback.batch import SEGMENTS, BagReader, ImuSeries, write_imu_bag


def _read(path: Path) -> tuple[list[tuple[str, bytes, int]], int]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with BagReader(path) as reader:
            messages = [(t, bytes(d), log) for t, _, d, log in reader.raw_messages()]
    return messages, len(caught)


def main() -> None:
    """Run the benchmark and print the table."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--flips", type=int, default=60, help="byte positions to try")
    parser.add_argument("--bag", type=Path, default=None, help="a recording to corrupt (default: synthetic)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        if args.bag is None:
            rng = np.random.default_rng(0)
            t = 1000.0 + np.arange(2000) / 100.0
            imu = {s: ImuSeries(s, t, rng.normal(0, 3, (2000, 3)), rng.normal(0, 1, (2000, 3)), None)
                   for s in SEGMENTS}
            good = write_imu_bag(work / "good", imu, chunk_size=256 * 1024)
        else:
            good = work / "good"
            shutil.copytree(args.bag, good)
        original, _ = _read(good)
        known = set(original)
        (file,) = good.glob("*.mcap")
        size = file.stat().st_size
        outcome = {"refused": 0, "identical": 0, "lost, with a warning": 0, "lost silently": 0,
                   "changed data": 0}
        for k, position in enumerate(np.linspace(40, size - 9, args.flips).astype(int)):
            copy = work / f"flip{k}"
            shutil.copytree(good, copy)
            (target,) = copy.glob("*.mcap")
            data = bytearray(target.read_bytes())
            data[position] ^= 0x5A
            target.write_bytes(bytes(data))
            try:
                messages, said = _read(copy)
            except Exception:  # refused as a whole: nothing read wrongly
                outcome["refused"] += 1
                continue
            if not set(messages) <= known:
                outcome["changed data"] += 1
            elif len(messages) == len(original):
                outcome["identical"] += 1
            else:
                outcome["lost, with a warning" if said else "lost silently"] += 1
            shutil.rmtree(copy)
    print(f"{len(original)} messages, {size / 1e6:.2f} MB, {args.flips} single-byte flips")
    for name, count in outcome.items():
        print(f"  {name:24s} {count:4d}")


if __name__ == "__main__":
    main()
