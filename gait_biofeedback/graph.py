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


def processing_nodes() -> dict[str, NodeFactory]:
    """The processing nodes that exist in this build, by name, in data-flow order."""
    return {}


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
) -> ReplayResult:
    """Replay ``bag`` through the processing ``nodes`` (default: all that exist) and record every
    topic to ``output`` (None: no recording). Returns when the replay has ended and the graph has
    settled; ``timeout`` (s) bounds the whole run (TimeoutError)."""
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
        for name in chosen:
            started.append(factories[name](context, **params.get(name, {})))
        replayer = ImuReplayer(context, bag=str(bag), speed=float(speed), start_offset=float(start_offset),
                               stop_offset=float(stop_offset), wait_for_subscribers=5.0)
        started.append(replayer)
        for node in started:
            executor.add_node(node)
        last = 0

        def done() -> bool:
            nonlocal last
            if progress is not None and replayer.published != last:
                progress(replayer.published - last)
                last = replayer.published
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
