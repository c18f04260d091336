"""``gait-biofeedback demo``: the main job end to end, with a one-screen summary.

1. Simulate the demo session (seeded, so always the same) unless the bag folder ``bags/demo_walk`` exists.
2. Replay it through every processing node of this build, in one process, recording all topics; one
   second after the subject's hip flexion/extension moves end, "press Calibrate" (call the
   calibration node), as the clinician would.
3. Read the recording back and summarise what the graph produced and how far it is from the truth.
"""

from __future__ import annotations

import shutil
import sys
import time
from pathlib import Path

from gait_biofeedback.graph import catch_up_advice, processing_nodes, replay_through_graph
from gait_biofeedback.io.bag import BagReader
from gait_biofeedback.report.session import format_report, session_report

DEMO_SCENARIO = "demo"
DEMO_SEED = 0


def ensure_demo_bag(bag: Path) -> tuple[Path, bool]:
    """Make the demo recording if it is missing; returns (path, made_now)."""
    if bag.exists():
        return bag, False
    from gait_biofeedback.sim.recording import write_simulated_bag
    from gait_biofeedback.sim.simulator import SCENARIOS, simulate

    config = SCENARIOS[DEMO_SCENARIO]()
    config.seed = DEMO_SEED
    bag.parent.mkdir(parents=True, exist_ok=True)
    return write_simulated_bag(bag, simulate(config)), True


def calibration_time() -> float:
    """Seconds into the demo session at which the clinician presses Calibrate: 1 s after the hip
    flexion/extension moves end (the calibration looks back for quiet standing + moves)."""
    from gait_biofeedback.sim.simulator import SCENARIOS

    t = 0.0
    for phase in SCENARIOS[DEMO_SCENARIO]().phases:
        t += phase.duration
        if phase.kind == "hip_flexion":
            return t + 1.0
    raise ValueError("the demo scenario has no hip flexion calibration moves")


_SLOWER = "run `gait-biofeedback demo --speed 1`"


def summarize(input_bag: Path, output: Path, wall_time: float, published: int,
              calibration_message: str = "", speed: float = 1.5, cut_short: str = "",
              graph_note: str | None = None) -> str:
    """The one-screen summary of a demo run (replayed at ``speed``; ``cut_short``: why the replay or
    the recording ended early, if it did): raw samples the recording lacks are said, with what to do
    (on a slow or busy machine the graph falls behind and drops them, and every figure above
    suffers), and ``graph_note``, what the processing graph lost
    (:meth:`~gait_biofeedback.graph.ReplayResult.loss_note`)."""
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
    ]
    if calibration_message:
        lines.append(f"calibrate (hip flexion protocol): {calibration_message}")
    lines += ["-" * 78, *format_report(session_report(output)), "-" * 78]
    derived = sorted(t for t in counts if not t.startswith("/ground_truth") and "/imu/" not in t)
    imu = sorted(t for t in counts if "/imu/" in t)
    lines.append("outputs: " + ", ".join(f"{t} {counts[t]}" for t in derived))
    raw = sum(counts[t] for t in imu if t.endswith("data_raw"))
    filtered = sum(counts[t] for t in imu if t.endswith("/imu/data"))
    lines.append(f"IMU: {raw} raw samples recorded, {filtered} orientations published "
                 f"({len([t for t in imu if t.endswith('data_raw')])} segments)")
    sent = sum(n for t, n in source.message_counts().items() if "/imu/" in t and t.endswith("data_raw"))
    if raw < sent:
        lost = sent - raw
        advice = catch_up_advice(speed, input_bag, _SLOWER)
        why = cut_short or f"the figures above are from what arrived. {advice}"
        lines.append(f"LOST: {lost} of the {sent} raw samples of the recording ({100 * lost / sent:.1f} %) "
                     f"never reached the output: {why}")
    elif graph_note and not cut_short:  # (the LOST line above gives the same advice)
        lines.append(f"LOST in the graph: {graph_note}")
    lines += [
        "-" * 78,
        f"open {output} in Foxglove (File > Open local file, pick the .mcap) or run "
        f"`gait-biofeedback info {output}`; the clinician's report: "
        f"`gait-biofeedback report {output} -o {output}_report`",
        "=" * 78,
    ]
    return "\n".join(lines)


def run_demo(bag: Path, output: Path, speed: float = 1.5, dashboard_port: int = 0) -> int:
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
        # by stamp, not "now": the same samples whatever the replay speed (and `analyze` agrees)
        result = replay_through_graph(
            bag, output, speed=speed, progress=bar.update,
            node_parameters={"biofeedback": {"port": dashboard_port}},
            calibrate_at=[(calibration_time(), "hip_flexion")])
    said = [("" if a.success else "REFUSED: ") + a.message for a in result.calibrations]
    cut_short = ("the replay was interrupted" if result.interrupted else
                 f"the recorder stopped: {result.write_error}" if result.write_error else "")
    print(summarize(bag, output, result.wall_time, result.published, " ".join(said), speed, cut_short,
                    result.loss_note(speed, bag, slower=_SLOWER)))
    return 0
