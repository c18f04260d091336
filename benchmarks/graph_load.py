"""CPU load and message loss of the in-process node graph at live rate (prints a table).

Replays the demo session (8 IMUs at 100 Hz with magnetometers) at ``--speed`` through growing sets
of nodes, recording everything, and reports per set: CPU time of the process per second of
recording (100 % = one core), and how many raw samples and orientations reached the recording
(loss = best-effort samples dropped somewhere in the graph).

Two parts:

- ``start``: the first ``--seconds`` s, before any calibration (joint angles and gait events idle);
- ``calibrated``: 36–66 s (quiet standing, then walking) with a calibration in force from the start
  (the demo's hip-flexion calibration at 36 s, computed once offline and reloaded by the
  calibration node from its session file), so joint angles, skeleton and gait events all run.

A last table times the per-message conversions (rclpy objects vs :mod:`gait_biofeedback.wire.cdr`).

``--foxglove`` adds the Foxglove live view (``replay --foxglove``) to every row; ``--viewer`` also
connects a viewer subscribed to every channel, in another process (its CPU is not counted: only what
the graph's process spends serving it). ``--full-only``: only the row of the whole chain;
``--calibrated-seconds``: a shorter calibrated window (from 36 s).

    .venv/bin/python benchmarks/graph_load.py [--seconds 15] [--speed 1] [--part all|start|calibrated|codec]
    .venv/bin/python benchmarks/graph_load.py --part rates   # 8 sensors at 100, 200, 400 Hz
    .venv/bin/python benchmarks/graph_load.py --part calibrated --full-only --calibrated-seconds 15 \
        [--foxglove [--viewer]]
"""

from __future__ import annotations

import argparse
import contextlib
import re
import resource
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

from gait_biofeedback.cli import DEMO_BAG
from gait_biofeedback.demo import calibration_time, ensure_demo_bag
from gait_biofeedback.graph import replay_through_graph
from gait_biofeedback.io.bag import BagReader

CHAIN = ["orientation_filter", "calibration", "joint_angles", "gait_events", "activity_monitor",
         "biofeedback"]
STAGES = [CHAIN[:k] for k in range(len(CHAIN) + 1)]
CALIBRATED_STAGES = [CHAIN[:k] for k in range(3, len(CHAIN) + 1)]
CALIBRATED_WINDOW = (36.0, 66.0)


def cpu_seconds() -> float:
    """User + system CPU time of this process so far."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def demo_calibration(bag: Path, session_dir: Path) -> None:
    """Write the demo's calibration (hip flexion, pressed at 36 s) to ``session_dir/calibration.yaml``,
    where the calibration node reloads it from (in force at once)."""
    from gait_biofeedback.analyze import analyze_recording
    from gait_biofeedback.core.calibration.stream import CALIBRATION_FILE, write_calibration_file

    result = analyze_recording(bag, None, calibrate_at=[(calibration_time(), "hip_flexion")])
    attempt = result.calibrations[0]
    if not attempt.success or attempt.calibration is None:
        raise RuntimeError(f"demo calibration refused: {attempt.message}")
    write_calibration_file(session_dir / CALIBRATION_FILE, attempt.calibration, "benchmark")


VIEWER = """
import json, sys, time
from websockets.sync.client import connect
deadline = time.monotonic() + 30
while True:
    try:
        ws = connect(sys.argv[1], subprotocols=["foxglove.sdk.v1", "foxglove.websocket.v1"])
        break
    except OSError:
        if time.monotonic() > deadline:
            raise
        time.sleep(0.05)
with ws:
    seen = set()
    while True:
        frame = ws.recv()
        if isinstance(frame, str) and json.loads(frame)["op"] == "advertise":
            new = [c["id"] for c in json.loads(frame)["channels"] if c["id"] not in seen]
            seen.update(new)
            subscriptions = [{"id": i, "channelId": i} for i in new]
            ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
"""


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def viewer(port: int | None) -> Iterator[None]:
    """A Foxglove viewer of every channel on ``port`` in another process (None: none)."""
    if port is None:
        yield
        return
    process = subprocess.Popen([sys.executable, "-c", VIEWER, f"ws://127.0.0.1:{port}"],
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        yield
    finally:
        process.kill()
        process.wait()


def run_rows(bag: Path, stages: list[list[str]], start: float, stop: float, speed: float,
             session_dir: Path | None, rate_hz: float = 100.0, foxglove: bool = False,
             with_viewer: bool = False) -> None:
    seconds = stop - start
    expected = round(seconds * rate_hz) * 8
    print(f"{'nodes (each row adds one)':36s}{'CPU % of a core':>16s}{'raw kept':>10s}{'orient.':>9s}")
    for stage in stages:
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "out"
            port = free_port() if foxglove else None
            with viewer(port if with_viewer else None):
                before = cpu_seconds()
                replay_through_graph(bag, out, speed=speed, nodes=stage, start_offset_s=start,
                                     stop_offset_s=stop, foxglove=port,
                                     node_parameters={"calibration": {"session_dir": str(session_dir or
                                                                                         Path(tmp) / "s"),
                                                                      "reload_calibration": True},
                                                      "biofeedback": {"port": 0}})
                cpu = cpu_seconds() - before
            counts = BagReader(out).message_counts()
            said = overload_said(out)
        raw = sum(n for t, n in counts.items() if t.endswith("/imu/data_raw"))
        orientations = sum(n for t, n in counts.items() if t.endswith("/imu/data"))
        label = "+ " + stage[-1] if stage else "replayer + recorder"
        load = 100.0 * cpu / (seconds / speed)
        print(f"{label:36s}{load:15.0f}%{100.0 * raw / expected:9.1f}%"
              f"{100.0 * orientations / expected if stage else float('nan'):8.1f}%  {said}", flush=True)


def overload_said(path: Path) -> str:
    """What /diagnostics said of lost samples (orientation filter, recorder) or lag: the worst of each
    (by its first number), or ''."""
    worst: dict[str, tuple[float, str]] = {}
    with BagReader(path) as reader:
        for _, msg, _ in reader.messages(["/diagnostics"]):
            for status in msg.status:
                for part in status.message.split("; "):
                    for key in ("losing samples", "of the raw samples", "falling behind"):
                        number = re.search(r"\d+(\.\d+)?", part)
                        value = float(number.group()) if number else 0.0
                        if key in part and value > worst.get(key, (-1.0, ""))[0]:
                            worst[key] = (value, f"{status.name.split(': ')[-1]}: {part}")
    return "; ".join(text for _, text in worst.values())


def sustained_rates(seconds: float, speed: float, rates: tuple[float, ...] = (100.0, 200.0, 400.0)) -> None:
    """What the graph and the recorder keep with 8 sensors at each rate: the demo session simulated at
    that rate, calibrated, from 36 s (standing, then walking); the nodes keep their default
    ``rate_hz`` 100 and measure the rate."""
    from gait_biofeedback.batch import SCENARIOS, simulate, write_simulated_bag

    start = CALIBRATED_WINDOW[0]
    for rate_hz in rates:
        with tempfile.TemporaryDirectory() as tmp:
            bag = write_simulated_bag(Path(tmp) / "bag", simulate(SCENARIOS["demo"](seed=1, rate_hz=rate_hz)))
            session = Path(tmp) / "session"
            demo_calibration(bag, session)
            print(f"\n8 sensors at {rate_hz:g} Hz, {start:g}-{start + seconds:g} s at {speed:g}x, "
                  f"calibrated; {round(seconds * rate_hz) * 8} raw IMU samples expected")
            run_rows(bag, [[], CHAIN], start, start + seconds, speed, session, rate_hz)


def time_codec(bag: Path, n: int = 2000) -> None:
    """µs per message: rclpy deserialize/serialize of an Imu vs the CDR codec."""
    from rclpy.serialization import deserialize_message, serialize_message
    from sensor_msgs.msg import Imu

    from gait_biofeedback.wire import cdr

    with BagReader(bag) as reader:
        data = next(d for t, _, d, _ in reader.raw_messages() if t.endswith("/imu/data_raw"))
    msg = deserialize_message(data, Imu)
    stamped = cdr.unpack_imu(data)

    def per_call(fn) -> float:
        t0 = time.perf_counter()
        for _ in range(n):
            fn()
        return (time.perf_counter() - t0) / n * 1e6

    print(f"{'one sensor_msgs/Imu':36s}{'µs':>8s}")
    rows = [("rclpy deserialize_message", lambda: deserialize_message(data, Imu)),
            ("rclpy Imu() + fields", lambda: Imu(header=msg.header, orientation=msg.orientation)),
            ("rclpy serialize_message", lambda: serialize_message(msg)),
            ("cdr.unpack_imu", lambda: cdr.unpack_imu(data)),
            ("cdr.pack_imu", lambda: cdr.pack_imu(stamped.ns, stamped.frame_id, stamped.values))]
    for label, fn in rows:
        print(f"{label:36s}{per_call(fn):8.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=15.0)
    parser.add_argument("--speed", type=float, default=1.0)
    parser.add_argument("--part", choices=["all", "start", "calibrated", "codec", "rates"], default="all")
    parser.add_argument("--foxglove", action="store_true", help="the Foxglove live view in every row")
    parser.add_argument("--viewer", action="store_true", help="with --foxglove: a viewer of every channel")
    parser.add_argument("--full-only", action="store_true", help="only the row of the whole chain")
    parser.add_argument("--calibrated-seconds", type=float,
                        default=CALIBRATED_WINDOW[1] - CALIBRATED_WINDOW[0])
    args = parser.parse_args()
    view = {"foxglove": args.foxglove, "with_viewer": args.foxglove and args.viewer}
    if args.foxglove:
        print("with the Foxglove live view" + (" and a viewer of every channel" if args.viewer else
                                                " (no viewer connected)"))
    if args.part == "rates":
        sustained_rates(args.seconds, args.speed)
        return
    bag, _ = ensure_demo_bag(DEMO_BAG)
    if args.part in ("all", "start"):
        print(f"demo session, first {args.seconds:g} s at {args.speed:g}x, not calibrated; "
              f"{round(args.seconds * 100) * 8} raw IMU samples expected")
        run_rows(bag, STAGES[-1:] if args.full_only else STAGES, 0.0, args.seconds, args.speed, None, **view)
    if args.part in ("all", "calibrated"):
        start = CALIBRATED_WINDOW[0]
        stop = start + args.calibrated_seconds
        with tempfile.TemporaryDirectory() as tmp:
            session = Path(tmp) / "session"
            demo_calibration(bag, session)
            print(f"\ndemo session, {start:g}-{stop:g} s at {args.speed:g}x, calibrated (joint angles and "
                  f"gait events running); {round((stop - start) * 100) * 8} raw IMU samples expected")
            run_rows(bag, CALIBRATED_STAGES[-1:] if args.full_only else CALIBRATED_STAGES, start, stop,
                     args.speed, session, **view)
    if args.part in ("all", "codec"):
        print()
        time_codec(bag)


if __name__ == "__main__":
    main()
