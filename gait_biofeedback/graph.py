"""The node graph in one process: replayer → processing nodes → recorder, on one executor.

Used by ``gait-biofeedback replay`` / ``demo`` and by the graph tests. Every node is the same class
the console scripts run; here they share one rclpy Context and one executor, which is how a
developer replays a session without launching processes.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import rclpy
from rclpy.context import Context
from rclpy.node import Node

from gait_biofeedback.nodes.common import make_executor, spin_until
from gait_biofeedback.nodes.imu_replayer import ImuReplayer
from gait_biofeedback.nodes.recorder import Recorder

NodeFactory = Callable[[Context], Node]
Action = tuple[float, Callable[[dict[str, Node]], object]]
"""(seconds into the recording, callback given the nodes by name) run once the replay gets there."""


def processing_nodes() -> dict[str, NodeFactory]:
    """The processing nodes that exist in this build, by name, in data-flow order."""
    from gait_biofeedback.nodes.activity_monitor import ActivityMonitorNode
    from gait_biofeedback.nodes.calibration import CalibrationNode
    from gait_biofeedback.nodes.gait_events import GaitEventsNode
    from gait_biofeedback.nodes.joint_angles import JointAnglesNode
    from gait_biofeedback.nodes.orientation_filter import OrientationFilterNode

    return {
        "orientation_filter": OrientationFilterNode,
        "calibration": CalibrationNode,
        "joint_angles": JointAnglesNode,
        "gait_events": GaitEventsNode,
        "activity_monitor": ActivityMonitorNode,
    }


def _wait_until_recorded(recorder: Recorder, nodes: Sequence[Node], timeout: float = 5.0) -> None:
    """Block until the recorder subscribes to every topic the processing nodes publish, so the first
    outputs (e.g. the start-up burst of the orientation filter) are not published into the void."""
    wanted = {
        topic
        for node in nodes
        for topic, _ in node.get_publisher_names_and_types_by_node(node.get_name(), node.get_namespace())
        if topic not in recorder.excluded
    }
    publishers = [p for node in nodes for p in node.publishers if p.topic_name in wanted]
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        recorder.discover()
        if all(recorder.recording(t) for t in wanted) and all(
                p.get_subscription_count() > 0 for p in publishers):
            return
        time.sleep(0.02)
    missing = sorted(t for t in wanted if not recorder.recording(t))
    raise TimeoutError(f"the recorder did not discover {missing} within {timeout} s")


@dataclass
class ReplayResult:
    """What one in-process replay did."""

    output: Path | None
    published: int
    recorded: int
    wall_time: float
    nodes: list[str] = field(default_factory=list)


def replay_through_graph(
    bag: str | Path,
    output: str | Path | None = None,
    speed: float = 1.0,
    nodes: Sequence[str] | None = None,
    start_offset: float = 0.0,
    stop_offset: float = 0.0,
    timeout: float | None = None,
    progress: Callable[[int], None] | None = None,
    node_parameters: dict[str, dict] | None = None,
    actions: Sequence[Action] = (),
) -> ReplayResult:
    """Replay ``bag`` through the processing ``nodes`` (default: all that exist) and record every
    topic to ``output`` (None: no recording). ``actions`` run on the executor thread when the replay
    reaches their time (e.g. the clinician pressing "calibrate"). Returns when the replay has ended
    and the graph has settled; ``timeout`` (s) bounds the whole run (TimeoutError)."""
    factories = processing_nodes()
    chosen = list(factories) if nodes is None else list(nodes)
    unknown = [n for n in chosen if n not in factories]
    if unknown:
        raise ValueError(f"unknown node(s) {unknown}; this build has {sorted(factories)}")
    params = node_parameters or {}
    context = Context()
    rclpy.init(args=[], context=context)
    executor = make_executor(context)
    started: list[Node] = []
    t0 = time.monotonic()
    try:
        recorder = None
        if output is not None:
            recorder = Recorder(context, output=str(output), **params.get("recorder", {}))
            started.append(recorder)
        processing = [factories[name](context, **params.get(name, {})) for name in chosen]
        by_name = dict(zip(chosen, processing, strict=True))
        started += processing
        if recorder is not None:
            _wait_until_recorded(recorder, processing)
        replayer = ImuReplayer(context, bag=str(bag), speed=float(speed), start_offset=float(start_offset),
                               stop_offset=float(stop_offset), wait_for_subscribers=5.0)
        started.append(replayer)
        for node in started:
            executor.add_node(node)
        last = 0
        pending = sorted(actions, key=lambda a: a[0])

        def done() -> bool:
            nonlocal last
            if progress is not None and replayer.published != last:
                progress(replayer.published - last)
                last = replayer.published
            while pending and replayer.position_ns - replayer.reader.start_time_ns >= pending[0][0] * 1e9:
                pending.pop(0)[1](by_name)
            return replayer.finished.is_set()

        if not spin_until(executor, done, timeout=timeout):
            raise TimeoutError(f"replay of {bag} did not finish within {timeout} s")
        # let the last messages travel through the graph
        settle = time.monotonic() + 0.5
        spin_until(executor, lambda: time.monotonic() > settle)
        published = replayer.published
    finally:
        for node in reversed(started):
            node.destroy_node()
        executor.shutdown()
        if context.ok():
            rclpy.shutdown(context=context)
    recorded = recorder.written if recorder is not None else 0
    return ReplayResult(Path(output) if output else None, published, recorded,
                        time.monotonic() - t0, chosen)
