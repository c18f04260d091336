"""``gait-biofeedback demo``: the main job end to end, with a one-screen summary.

1. Simulate the demo session (seeded, so always the same) unless ``bags/demo_walk.mcap`` exists.
2. Replay it through every processing node of this build, in one process, recording all topics.
3. Read the recording back and summarise what the graph produced.
"""

from __future__ import annotations

import shutil
import sys
import time
from pathlib import Path

from gait_biofeedback.graph import processing_nodes, replay_through_graph
from gait_biofeedback.io.bag import BagReader

DEMO_SCENARIO = "demo"
DEMO_SEED = 0


def ensure_demo_bag(bag: Path) -> tuple[Path, bool]:
    """Make the demo recording if it is missing; returns (path, made_now)."""
    if bag.exists():
        return bag, False
    from gait_biofeedback.core.simulator import SCENARIOS, simulate
    from gait_biofeedback.io.session_bag import write_simulated_bag

    config = SCENARIOS[DEMO_SCENARIO]()
    config.seed = DEMO_SEED
    bag.parent.mkdir(parents=True, exist_ok=True)
    return write_simulated_bag(bag, simulate(config)), True


def summarize(input_bag: Path, output: Path, wall_time: float, published: int) -> str:
    """The one-screen summary of a demo run."""
    source = BagReader(input_bag)
    result = BagReader(output)
    counts = result.message_counts()
    duration = source.duration_ns * 1e-9
    lines = [
        "=" * 78,
        f"gait_biofeedback demo: {input_bag} ({duration:.1f} s of recording)",
        f"replayed {published} messages through {len(processing_nodes())} processing node(s) "
        f"in {wall_time:.1f} s ({duration / wall_time:.1f}x real time)",
        f"recorded {sum(counts.values())} messages on {len(counts)} topics to {output}",
        "-" * 78,
        f"{'topic':44s}{'messages':>10s}{'rate Hz':>10s}",
    ]
    for topic in sorted(counts):
        lines.append(f"{topic:44s}{counts[topic]:10d}{(counts[topic] - 1) / duration:10.1f}")
    lines += [
        "-" * 78,
        f"open {output} in Foxglove (File > Open local file, pick the .mcap) or run "
        f"`gait-biofeedback info {output}`",
        "=" * 78,
    ]
    return "\n".join(lines)


def run_demo(bag: Path, output: Path, speed: float = 4.0) -> int:
    """Run the demo; returns the process exit code."""
    t0 = time.monotonic()
    bag, made = ensure_demo_bag(bag)
    print(("simulated " if made else "reusing ") + f"{bag} ({time.monotonic() - t0:.1f} s)")
    if output.exists():
        shutil.rmtree(output)
    total = BagReader(bag).message_count
    from tqdm import tqdm

    with tqdm(total=total, desc="replay", unit="msg", unit_scale=True, leave=False,
              disable=not sys.stderr.isatty()) as bar:
        result = replay_through_graph(bag, output, speed=speed, progress=bar.update)
    print(summarize(bag, output, result.wall_time, result.published))
    return 0
