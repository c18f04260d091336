"""Latency from an IMU sample entering the graph to the dashboard receiving the derived joint angle.

A simulated session (quiet standing, hip-flexion calibration moves, standing, walking; 8 IMUs at 100 Hz)
is replayed live (1x) through orientation_filter → calibration → joint_angles → gait_events →
biofeedback in one process. The benchmark asks for the calibration over the dashboard's websocket (as the
page's "Calibrate" button does) after the calibration moves, and a websocket client timestamps every
frame. Each joint-angle sample in a frame is matched by its header stamp to the arrival of the raw
``pelvis/imu/data_raw`` sample with the same stamp (a subscriber in this process, i.e. the time the
sample entered the graph). Prints p50/p99/max in ms, and how many samples reached the page.

Run:  .venv/bin/python benchmarks/dashboard_latency.py [--speed 1.0] [--walk 20]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import threading
import time
from pathlib import Path

import numpy as np


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speed", type=float, default=1.0)
    parser.add_argument("--walk", type=float, default=20.0, help="s of walking after calibration")
    args = parser.parse_args()

    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node

    from gait_biofeedback.nodes.biofeedback import BiofeedbackNode
    from gait_biofeedback.nodes.calibration import CalibrationNode
    from gait_biofeedback.nodes.common import make_executor, spin_until
    from gait_biofeedback.nodes.gait_events import GaitEventsNode
    from gait_biofeedback.nodes.imu_replayer import ImuReplayer
    from gait_biofeedback.nodes.joint_angles import JointAnglesNode
    from gait_biofeedback.nodes.orientation_filter import OrientationFilterNode
    from gait_biofeedback.sim.recording import write_simulated_bag
    from gait_biofeedback.sim.simulator import Phase, SimulationConfig, simulate
    from gait_biofeedback.wire import topics
    from gait_biofeedback.wire.calibration import mounting_msg
    from gait_biofeedback.wire.stamps import stamp_to_ns

    phases = [Phase("stand", 5.0), Phase("hip_flexion", 26.0, {"side": "both"}), Phase("stand", 5.0),
              Phase("walk", args.walk), Phase("stand", 2.0)]
    calibrate_at = 5.0 + 26.0 + 1.0  # data time: after the moves, during the standing
    work = Path(tempfile.mkdtemp(prefix="dashboard-latency-"))
    session = simulate(SimulationConfig(phases=phases))
    bag = write_simulated_bag(work / "session", session)

    context = Context()
    rclpy.init(args=[], context=context)
    executor = make_executor(context)
    entered: dict[int, float] = {}
    probe = Node("latency_probe", context=context)
    raw = topics.raw_imu("pelvis")
    probe.create_subscription(raw.msg_type, raw.name,
                              lambda m: entered.setdefault(stamp_to_ns(m.header.stamp), time.monotonic()),
                              raw.qos)
    cal = topics.CALIBRATION
    fallback = probe.create_publisher(cal.msg_type, cal.name, cal.qos)
    bio = BiofeedbackNode(context, port=0)
    nodes = [probe, bio, OrientationFilterNode(context), CalibrationNode(context, session_dir=str(work)),
             JointAnglesNode(context), GaitEventsNode(context)]
    arrivals: list[tuple[float, float]] = []  # (sample stamp s, arrival monotonic s)
    frames: list[float] = []
    replies: list[dict] = []
    stop = threading.Event()
    ws_box: dict = {}

    def client() -> None:
        from websockets.sync.client import connect

        with connect(f"ws://127.0.0.1:{bio.port}/ws?token={bio.server.token}", max_size=None) as ws:
            ws_box["ws"] = ws
            while not stop.is_set():
                try:
                    raw = ws.recv(timeout=0.5)
                except TimeoutError:
                    continue
                now = time.monotonic()
                msg = json.loads(raw)
                if msg.get("type") != "frame":
                    continue
                frames.append(now)
                arrivals.extend((row[0], now) for row in msg.get("samples", []))
                replies.extend(m for m in msg.get("messages", []) if m.get("type") == "reply")

    reader = threading.Thread(target=client, daemon=True)
    reader.start()
    for n in nodes:
        executor.add_node(n)
    replayer = ImuReplayer(context, bag=str(bag), speed=args.speed, wait_for_subscribers_s=5.0)
    executor.add_node(replayer)
    t_start = time.monotonic()
    asked = False
    used_truth = False
    try:
        def step() -> bool:
            nonlocal asked, used_truth
            refused = [r for r in replies if r.get("action") == "calibrate" and r.get("success") is False]
            if refused and not used_truth:  # the latency path is the same with the true mounting
                used_truth = True
                fallback.publish(mounting_msg(session.truth.mounting, 0, "hip_flexion", "ground truth"))
            if not asked and entered and "ws" in ws_box:
                data_t = (max(entered) - min(entered)) * 1e-9
                if data_t >= calibrate_at:
                    ws_box["ws"].send(json.dumps({"action": "calibrate", "protocol": "hip_flexion"}))
                    asked = True
            return replayer.finished.is_set()

        spin_until(executor, step, timeout=sum(p.duration for p in phases) / args.speed + 60)
        settle = time.monotonic() + 1.0
        spin_until(executor, lambda: time.monotonic() > settle)
    finally:
        stop.set()
        reader.join(2)
        for n in [replayer, *reversed(nodes)]:
            n.destroy_node()
        executor.shutdown()
        if context.ok():
            rclpy.shutdown(context=context)

    wall = time.monotonic() - t_start
    done = [r for r in replies if r.get("action") == "calibrate" and not r.get("pending")]
    duration = sum(p.duration for p in phases)
    print(f"replayed {bag.name}: {duration:.0f} s of data at {args.speed:g}x in {wall:.1f} s")
    print("calibration:", (("OK " if done[0]["success"] else "REFUSED ") + done[0]["message"]) if done
          else "no reply")
    if used_truth:
        print("  → the simulator's true sensor mounting was published as the calibration instead")
    lat = np.array([now - entered[round(t * 1e9)] for t, now in arrivals if round(t * 1e9) in entered])
    if not len(lat):
        print("no joint angles reached the page (calibration failed?)")
        return 1
    lat_ms = 1e3 * lat
    fr = np.diff(frames)
    print(f"joint-angle samples at the page: {len(arrivals)} ({len(lat)} matched to raw IMU samples); "
          f"frames: {len(frames)}, median interval {1e3 * np.median(fr):.1f} ms")
    print(f"latency IMU sample → page (ms): p50 {np.percentile(lat_ms, 50):.1f}, "
          f"p99 {np.percentile(lat_ms, 99):.1f}, max {lat_ms.max():.1f}, min {lat_ms.min():.1f}")
    stamps = np.array([t for t, _ in arrivals if round(t * 1e9) in entered])
    steady = lat_ms[stamps > stamps.min() + 2.0]
    if len(steady):
        print(f"  after the first 2 s of angles (start-up burst): p50 {np.percentile(steady, 50):.1f}, "
              f"p99 {np.percentile(steady, 99):.1f}, max {steady.max():.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
