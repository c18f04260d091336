"""The node graph in one process: replayer → processing nodes → recorder, on one executor.

Used by ``gait-biofeedback replay`` / ``demo`` and by the graph tests. Every node is the same class
the console scripts run; here they share one rclpy Context and one executor, which is how a
developer replays a session without launching processes.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import rclpy
from rclpy.context import Context
from rclpy.executors import Executor
from rclpy.node import Node

from gait_biofeedback.core.calibration.stream import CalibrationAttempt
from gait_biofeedback.io.bag import BagReader
from gait_biofeedback.nodes.common import (
    STOP,
    GraphClaim,
    init_ros,
    make_executor,
    refuse_other_graph,
    spin_until,
    stop_on_signals,
)
from gait_biofeedback.nodes.imu_replayer import ImuReplayer
from gait_biofeedback.nodes.recorder import Recorder
from gait_biofeedback.parameters import stage_parameters

NodeFactory = Callable[[Context], Node]
Action = tuple[float, Callable[[dict[str, Node]], object]]
"""(seconds into the recording, callback given the nodes by name, the recorder as ``"recorder"``) run
once the replay gets there."""


def processing_nodes() -> dict[str, NodeFactory]:
    """The processing nodes that exist in this build, by name, in data-flow order."""
    from gait_biofeedback.nodes.activity_monitor import ActivityMonitorNode
    from gait_biofeedback.nodes.biofeedback import BiofeedbackNode
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
        "biofeedback": BiofeedbackNode,
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


def _wait_until_heard(driver: Node, timeout: float = 5.0) -> None:
    """Block until every raw topic of the driver has its subscribers matched (the recorder's, the
    filter's), so the first samples are not published into the void."""
    deadline = time.monotonic() + timeout
    raw = [p for p in driver.publishers if p.topic_name.endswith("/imu/data_raw")]
    while time.monotonic() < deadline and not all(p.get_subscription_count() > 0 for p in raw):
        time.sleep(0.02)
    time.sleep(0.25)  # the readers match the writer a moment after it matched them (see imu_replayer)


LOST_WARN = 0.005
"""A replay says what the graph lost, and exits 1, above this share of the raw IMU samples (or a hole)."""


@dataclass
class ReplayResult:
    """What one in-process replay did."""

    output: Path | None
    published: int
    recorded: int
    wall_time: float
    nodes: list[str] = field(default_factory=list)
    outputs: list[Path] = field(default_factory=list)  # every bag folder (a stop/start opens a new one)
    write_error: str | None = None  # the recorder stopped on a write error (a full disk)
    interrupted: bool = False  # SIGINT / SIGTERM ended the replay before the recording did
    calibrations: list[CalibrationAttempt] = field(default_factory=list)  # each request's outcome
    start_ns: int = 0  # log time of the replayed recording's first message (the zero of calibrate_at)
    calibration_file: Path | None = None  # where the calibration node saved its last result
    raw_lost: dict[str, tuple[int, int]] = field(default_factory=dict)
    """Segment → (raw IMU samples the orientation filter never received, samples replayed): what a
    graph that could not keep up lost (DDS best effort drops the samples a busy process cannot take)."""
    graph_holes: dict[str, list[tuple[float, int]]] = field(default_factory=dict)
    """Segment → (s, samples) of each gap the orientation filter took for a sensor dropout although the
    recording has samples in it: holes the graph itself dropped."""

    def loss_note(self, speed: float, bag: str | Path, threshold: float = LOST_WARN,
                  slower: str = "replay at --speed 1") -> str | None:
        """What the graph lost, with what to do (fitting ``speed``; ``slower``: how to run slower), or
        None when it lost at most ``threshold`` of the raw samples and no hole."""
        lost = sum(n for n, _ in self.raw_lost.values())
        sent = sum(n for _, n in self.raw_lost.values())
        holes = [(seconds, segment) for segment, found in self.graph_holes.items() for seconds, _ in found]
        if not holes and not (sent and lost > threshold * sent):
            return None
        worst = max(self.raw_lost, key=lambda s: self.raw_lost[s][0] / max(self.raw_lost[s][1], 1))
        text = (f"the graph lost {100 * lost / max(sent, 1):.1f} % of the raw IMU samples (worst {worst}: "
                f"{self.raw_lost[worst][0]} of {self.raw_lost[worst][1]})")
        if holes:
            longest, where = max(holes)
            text += (f", among them {len(holes)} hole(s) of consecutive samples (longest {longest:.2f} s, "
                     f"{where}) that the recording has: the filters took them for sensor dropouts, but the "
                     "graph dropped them")
        return f"{text}; its outputs miss those samples. {catch_up_advice(speed, bag, slower)}"


def catch_up_advice(speed: float, bag: str | Path, slower: str = "replay at --speed 1") -> str:
    """What to do when a replay at ``speed`` (0: as fast as possible) lost samples: at real time or
    slower, nothing but a quieter machine or the offline path helps."""
    offline = f"`gait-biofeedback analyze {bag} -o OUT --calibrate-at auto`"
    if 0 < speed <= 1:
        return ("This machine could not keep up even at real time: close other programs, or analyze the "
                f"recording offline ({offline}: the same core objects, nothing dropped).")
    pace = "as fast as possible" if speed <= 0 else f"at {speed:g}x"
    return (f"This machine could not keep up {pace}: {slower}, or run {offline} (the same core objects "
            "offline, nothing dropped).")


@dataclass
class RunningGraph:
    """The nodes of one in-process graph on one executor (see :func:`running_graph`)."""

    context: Context
    executor: Executor
    nodes: dict[str, Node]
    recorder: Recorder | None
    started: list[Node] = field(default_factory=list)

    def add(self, node: Node) -> Node:
        """Add one more node (e.g. a replayer) to the executor; it is destroyed with the graph."""
        self.started.append(node)
        self.executor.add_node(node)
        return node


@contextmanager
def running_graph(
    nodes: Sequence[str] | None = None,
    output: str | Path | None = None,
    node_parameters: dict[str, dict] | None = None,
    args: list[str] | None = None,
    use_sim_time: bool = False,
    driver: bool = False,
    foxglove: int | None = None,
) -> Iterator[RunningGraph]:
    """Context, executor, recorder (when ``output`` is given) and the processing ``nodes`` (default:
    all), created in data-flow order; the recorder is subscribed to every output before this
    yields. ``driver``: an ``imu_driver`` (parameters ``node_parameters["imu_driver"]``) comes first
    and starts receiving only once the recorder and the nodes listen to it. ``use_sim_time``: every
    node follows ``/clock`` (a replayer's). ``foxglove``: the Foxglove live view
    (:mod:`~gait_biofeedback.nodes.foxglove_view`) on this port (0: any free one), started with the
    processing nodes (``graph.nodes["foxglove"]``). With ``output``, the calibration and the dashboard's link
    are saved in it unless the stage's ``session_dir`` is set. SIGINT and SIGTERM end every spin loop (see
    :func:`stop_on_signals`). Everything is destroyed (files closed, bags summarised) and rclpy shut
    down on exit, whatever happened."""
    factories = processing_nodes()
    chosen = list(factories) if nodes is None else list(nodes)
    unknown = [n for n in chosen if n not in factories]
    if unknown:
        raise ValueError(f"unknown node(s) {unknown}; this build has {sorted(factories)}")
    params = dict(node_parameters or {})
    if foxglove is not None:
        params["foxglove"] = {**params.get("foxglove", {}), "port": int(foxglove)}
    # every stage's parameters checked once, here, before anything starts; the nodes take them as they are
    stages = {name: stage_parameters(name, params.get(name))
              for name in {*chosen, *params, *(["recorder"] if output is not None else []),
                           *(["imu_driver"] if driver else [])}}  # a foxglove port is in params
    if output is not None:
        for name in ("calibration", "biofeedback"):
            if name in stages and not stages[name].session_dir:
                stages[name] = replace(stages[name], session_dir=str(output))
    ros = {"use_sim_time": True} if use_sim_time else {}
    context = Context()
    init_ros(args or [], context)
    graph = RunningGraph(context, make_executor(context), {}, None)
    ready = False
    claim = GraphClaim([])
    with stop_on_signals():
        try:
            claim = refuse_other_graph(context, [*chosen, *(["recorder"] if output is not None else []),
                                                 *(["imu_driver"] if driver else []),
                                                 *(["foxglove"] if foxglove is not None else [])])
            if output is not None:
                recorder = Recorder(context, replace(stages["recorder"], output=str(output)), **ros)
                graph.recorder = graph.add(recorder)
            if driver:
                from gait_biofeedback.nodes.imu_driver import ImuDriverNode

                graph.nodes["imu_driver"] = graph.add(
                    ImuDriverNode(context, stages["imu_driver"], start=False, **ros))
            for name in chosen:
                graph.nodes[name] = graph.add(factories[name](context, stages[name], **ros))
            if foxglove is not None:
                from gait_biofeedback.nodes.foxglove_view import FoxgloveView

                view = graph.nodes["foxglove"] = graph.add(FoxgloveView(context, stages["foxglove"], **ros))
                print(f"Foxglove live view: {view.url} (Foxglove: Open connection, Foxglove WebSocket; "
                      "layout config/foxglove_layout.json)", flush=True)
            if graph.recorder is not None:
                _wait_until_recorded(graph.recorder, list(graph.nodes.values()))
            if driver:
                if graph.recorder is not None or chosen:
                    _wait_until_heard(graph.nodes["imu_driver"])
                graph.nodes["imu_driver"].start()
            ready = True
            yield graph
        finally:
            for node in reversed(graph.started):
                node.destroy_node()
            if not ready and graph.recorder is not None:  # a node refused: no recording to keep
                graph.recorder.discard()
            claim.release()
            graph.executor.shutdown()
            if context.ok():
                rclpy.shutdown(context=context)


def replay_through_graph(
    bag: str | Path,
    output: str | Path | None = None,
    speed: float = 1.0,
    nodes: Sequence[str] | None = None,
    start_offset_s: float = 0.0,
    stop_offset_s: float = 0.0,
    timeout: float | None = None,
    progress: Callable[[int], None] | None = None,
    node_parameters: dict[str, dict] | None = None,
    actions: Sequence[Action] = (),
    calibrate_at: Sequence[tuple[float, str] | tuple[float, str, dict]] = (),
    foxglove: int | None = None,
) -> ReplayResult:
    """Replay ``bag`` through the processing ``nodes`` (default: all that exist) and record every
    topic to ``output`` (None: no recording). ``actions`` run on the executor thread when the replay
    reaches their time (e.g. the clinician pressing "calibrate"). ``calibrate_at``: (s into the
    recording, protocol[, options of ``calibrate_at``]) requests to the calibration node, on the window
    ending at that sample stamp (the same samples as ``analyze --calibrate-at``, whatever the speed).
    Returns when the replay has ended and the graph has settled; ``timeout`` (s) bounds the whole run
    (TimeoutError).

    The replayer publishes ``/clock`` and every node runs with ``use_sim_time``: the recording's
    stamps (``/diagnostics`` included) and log times are all in the replayed recording's time base."""
    t0 = time.monotonic()
    with BagReader(bag) as reader:
        start_ns = reader.start_time_ns
    for t, protocol, *options in calibrate_at:
        press = _calibration_request(start_ns + round(t * 1e9), protocol, **(options[0] if options else {}))
        actions = [*actions, (t, press)]
    with running_graph(nodes, output, node_parameters, use_sim_time=True, foxglove=foxglove) as graph:
        replayer = graph.add(ImuReplayer(
            graph.context, bag=str(bag), speed=float(speed), start_offset_s=float(start_offset_s),
            stop_offset_s=float(stop_offset_s), wait_for_subscribers_s=5.0, publish_clock=True,
            use_sim_time=True))
        last = 0
        pending = sorted(actions, key=lambda a: a[0])

        def done() -> bool:
            nonlocal last
            if progress is not None and replayer.published != last:
                progress(replayer.published - last)
                last = replayer.published
            while pending and replayer.position_ns - replayer.reader.start_time_ns >= pending[0][0] * 1e9:
                pending.pop(0)[1]({**graph.nodes, "recorder": graph.recorder})
            return replayer.finished.is_set()

        if not spin_until(graph.executor, done, timeout=timeout) and not STOP.is_set():
            raise TimeoutError(f"replay of {bag} did not finish within {timeout} s")
        interrupted = STOP.is_set()
        # let the last messages travel through the graph; a calibration request waits until its
        # data has come through the filters (they lag behind a fast replay), at most SETTLE_MAX_S
        settle, limit = time.monotonic() + 0.5, time.monotonic() + SETTLE_MAX_S
        calibrating = graph.nodes.get("calibration")

        def settled() -> bool:
            now = time.monotonic()
            waiting = calibrating is not None and calibrating.core.scheduled
            return now > limit or (now > settle and (not waiting or STOP.is_set()))

        spin_until(graph.executor, settled)
        finish_streams(graph)
        recorder = graph.recorder
    recorded = recorder.written if recorder is not None else 0
    calibration = graph.nodes.get("calibration")
    return ReplayResult(Path(output) if output else None, replayer.published, recorded, time.monotonic() - t0,
                        list(graph.nodes), list(recorder.sessions) if recorder is not None else [],
                        recorder.write_error if recorder is not None else None, interrupted,
                        list(getattr(calibration, "attempts", [])), start_ns,
                        getattr(calibration, "saved_file", None),
                        _raw_lost(replayer.published_by_topic, graph.nodes.get("orientation_filter")),
                        _graph_holes(replayer.raw_stamps, graph.nodes.get("orientation_filter")))


def _raw_lost(sent: dict[str, int], orientation: Node | None) -> dict[str, tuple[int, int]]:
    """Per tracked segment: (raw samples replayed that its filter never received, samples replayed)."""
    if orientation is None:
        return {}
    out = {}
    for segment, tracker in orientation.trackers.items():
        replayed = sum(n for topic, n in sent.items() if topic.endswith(f"/{segment}/imu/data_raw"))
        if replayed:
            out[segment] = (max(replayed - tracker.counts["samples"], 0), replayed)
    return out


def _graph_holes(replayed: dict[str, Sequence[int]], orientation: Node | None
                 ) -> dict[str, list[tuple[float, int]]]:
    """Per tracked segment: (length s, samples replayed within) of each gap its filter saw where the
    replayer had published samples (1 ms inside either end)."""
    if orientation is None:
        return {}
    out: dict[str, list[tuple[float, int]]] = {}
    for segment, tracker in orientation.trackers.items():
        stamps = [np.asarray(v) for t, v in replayed.items() if t.endswith(f"/{segment}/imu/data_raw")]
        if not stamps or not tracker.gaps:
            continue
        sent = np.sort(np.concatenate(stamps))
        for before, after in tracker.gaps:
            inside = int(np.searchsorted(sent, after - 1_000_000) - np.searchsorted(sent, before + 1_000_000,
                                                                                    side="right"))
            if inside > 0:
                out.setdefault(segment, []).append(((after - before) * 1e-9, inside))
    return out


SETTLE_MAX_S = 10.0
FINISH_DRAIN_S = 0.3


def finish_streams(graph: RunningGraph) -> None:
    """The end of the data, of a replay or of a live session (also after Ctrl-C / SIGTERM): what the
    streams hold goes out, as ``analyze`` publishes it at the end of a file (the strides waiting for
    their spatial values, the activity states held), and the graph spins ``FINISH_DRAIN_S`` s whatever
    :data:`STOP` says, so the recorder takes them."""
    finishing = [graph.nodes[n] for n in ("gait_events", "activity_monitor") if n in graph.nodes]
    if not finishing:
        return
    for node in finishing:
        node.finish()
    until = time.monotonic() + FINISH_DRAIN_S
    while time.monotonic() < until and graph.executor.context.ok():
        graph.executor.spin_once(timeout_sec=0.05)


def _calibration_request(stamp_ns: int, protocol: str, **options: object
                         ) -> Callable[[dict[str, Node]], None]:
    def press(nodes: dict[str, Node]) -> None:
        if "calibration" in nodes:
            nodes["calibration"].calibrate_at(stamp_ns, protocol, **options)

    return press


def run_live(nodes: Sequence[str] | None = None, output: str | Path | None = None,
             node_parameters: dict[str, dict] | None = None, args: list[str] | None = None,
             driver: bool = False, until: Callable[[], bool] | None = None,
             foxglove: int | None = None) -> int:
    """The processing graph (and the recorder, with ``driver`` the imu_driver, with ``foxglove`` the
    Foxglove live view on that port) on live topics until Ctrl-C / SIGTERM (or ``until()``)."""
    with running_graph(nodes, output, node_parameters, args, driver=driver, foxglove=foxglove) as graph:
        names = ", ".join(graph.nodes) or "no processing nodes"
        print(f"running {names}" + (f", recording to {output}" if output else "") + "; Ctrl-C stops")
        with suppress(KeyboardInterrupt):
            spin_until(graph.executor, until or (lambda: False))
            finish_streams(graph)
        recorder = graph.recorder
    if recorder is not None:
        print("recorded to " + ", ".join(str(p) for p in recorder.sessions))
        if recorder.write_error:
            print(f"warning: {recorder.write_error}", file=sys.stderr)
            return 1
    return 0
