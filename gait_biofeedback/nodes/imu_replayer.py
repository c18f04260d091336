"""Node ``imu_replayer``: a recording (MCAP / rosbag2 folder) → its topics, with original stamps.

Messages are published as the recorded CDR bytes (no deserialisation), each at
``start_wall + (log_time - first_log_time) / speed`` from a dedicated thread, so the executor
thread stays free for the rest of the graph and timing does not depend on its load.
Every topic is replayed (or the ``topics`` asked for), but for one whose type has no Python package
here (a recording's ``/tf``, tf2_msgs): it is named in a warning and :attr:`ImuReplayer.skipped`.
Topics are published under the node's namespace: a recorded ``/left_foot/imu/data_raw`` goes out
as ``left_foot/imu/data_raw`` (relative), so ``-r __ns:=/patient1`` works unchanged.

Parameters: :class:`~gait_biofeedback.io.params.ReplayerParams` (``bag`` is required; on each
``loop`` the stamps jump back, which downstream filters treat as a reset).
"""

from __future__ import annotations

import threading
import time
from array import array
from pathlib import Path

from rclpy.context import Context
from rosgraph_msgs.msg import Clock

from gait_biofeedback.io.bag import BagReader, message_class
from gait_biofeedback.io.params import ReplayerParams
from gait_biofeedback.nodes.common import GuardedNode
from gait_biofeedback.nodes.parameters import declare_parameters, node_overrides
from gait_biofeedback.wire import topics
from gait_biofeedback.wire.cdr import header_stamp_ns
from gait_biofeedback.wire.stamps import ns_to_stamp

RAW_SUFFIX = "/imu/data_raw"


class ImuReplayer(GuardedNode):
    """Publishes a recording's messages at their recorded pace (see module docstring)."""

    NODE_NAME = "imu_replayer"

    def __init__(self, context: Context | None = None, params: ReplayerParams | None = None,
                 **overrides: object) -> None:
        super().__init__(self.NODE_NAME, context=context, parameter_overrides=node_overrides(overrides))
        p: ReplayerParams = declare_parameters(self, ReplayerParams, params)
        self.params = p
        bag = p.bag
        if not bag or not Path(bag).exists():
            raise ValueError(f"imu_replayer: parameter 'bag' must name a recording; got {bag!r}")
        self.speed = p.speed
        self.loop = p.loop
        self.start_offset_s = p.start_offset_s
        self.stop_offset_s = p.stop_offset_s
        self.wait_for_subscribers_s = p.wait_for_subscribers_s
        wanted = [t for t in p.topics if t]

        self.reader = BagReader(bag)
        available = self.reader.topics()
        missing = [t for t in wanted if t not in available]
        if missing:
            raise ValueError(f"imu_replayer: topics {missing} are not in {bag}; it has {sorted(available)}")
        self.topics = {t: available[t] for t in (wanted or available)}
        self.skipped: dict[str, str] = {}  # topic → type of the recorded topics not replayed
        if not wanted:  # all of them: those whose type this environment cannot publish are left out
            self.skipped = {t: n for t, n in self.topics.items() if not _installed(n)}
            for topic in self.skipped:
                del self.topics[topic]
            if self.skipped:
                self.get_logger().warning(
                    "not replayed (no Python package of their type here): " + ", ".join(
                        f"{t} ({n})" for t, n in sorted(self.skipped.items())))
        self._topic_publishers = {
            topic: self.create_publisher(message_class(type_name), topic.lstrip("/"),
                                         topics.qos_of_recorded(topic))
            for topic, type_name in self.topics.items()
        }
        self._clock_pub = self.create_publisher(Clock, "/clock", 10) if p.publish_clock else None
        self.published = 0
        self.published_by_topic: dict[str, int] = {}  # recorded topic → messages published
        self.raw_stamps: dict[str, array] = {} if p.loop else {t: array("q") for t in self.topics
                                                               if t.endswith(RAW_SUFFIX)}
        """Raw IMU topic → the header stamps (int ns) published, in order: what the graph was given (one
        pass only: a looping replay keeps none)."""
        self.position_ns = self.reader.start_time_ns  # log time of the newest published message
        self.loops_done = 0
        self.finished = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="imu_replayer", daemon=True)
        self._thread.start()
        self.get_logger().info(
            f"replaying {bag}: {len(self.topics)} topics "
            + (f"at {self.speed:g}x" if self.speed else "as fast as possible")
            + (", looping" if self.loop else ""))

    def _tick(self, log_ns: int) -> None:
        if self._clock_pub is not None:
            self._clock_pub.publish(Clock(clock=ns_to_stamp(log_ns)))

    def _wait_for_subscribers(self, first_ns: int) -> None:
        """Wait for subscribers, ticking /clock at the start time meanwhile, so that nodes with
        use_sim_time have the recording's time before its first message."""
        deadline = time.monotonic() + self.wait_for_subscribers_s
        while time.monotonic() < deadline and not self._stop.is_set():
            self._tick(first_ns)
            if all(pub.get_subscription_count() > 0 for pub in self._topic_publishers.values()):
                # the writer has matched every reader; give the readers time to match the writer
                # too, or the first best-effort messages are dropped on their side (0.25 s was
                # not enough on a loaded 2-core machine)
                for _ in range(20):
                    time.sleep(0.05)
                    self._tick(first_ns)
                return
            time.sleep(0.01)
        lonely = [t for t, pub in self._topic_publishers.items() if pub.get_subscription_count() == 0]
        self.get_logger().warning(f"starting without subscribers on {lonely}")

    def _window_ns(self) -> tuple[int | None, int | None]:
        first = self.reader.start_time_ns
        start = first + round(self.start_offset_s * 1e9) if self.start_offset_s > 0 else None
        stop = first + round(self.stop_offset_s * 1e9) if self.stop_offset_s > 0 else None
        return start, stop

    def _run(self) -> None:
        start_ns, stop_ns = self._window_ns()
        if self.wait_for_subscribers_s > 0:
            self._wait_for_subscribers(start_ns or self.reader.start_time_ns)
        period_ns = round(self.params.clock_period_s * 1e9)
        next_tick = 0
        while not self._stop.is_set():
            wall0 = time.perf_counter()
            first_ns = None
            for topic, _type, data, log_ns in self.reader.raw_messages(
                    list(self.topics), start_ns=start_ns, stop_ns=stop_ns):
                if self._stop.is_set():
                    break
                if first_ns is None:
                    first_ns = log_ns
                if self.speed > 0:
                    delay = wall0 + (log_ns - first_ns) * 1e-9 / self.speed - time.perf_counter()
                    if delay > 0 and self._stop.wait(delay):
                        break
                if log_ns >= next_tick or log_ns < next_tick - period_ns:  # (a loop jumps back)
                    self._tick(log_ns)
                    next_tick = log_ns + period_ns
                self._topic_publishers[topic].publish(data)
                self.published += 1
                self.published_by_topic[topic] = self.published_by_topic.get(topic, 0) + 1
                stamps = self.raw_stamps.get(topic)
                if stamps is not None and (stamp_ns := header_stamp_ns(data)) is not None:
                    stamps.append(stamp_ns)
                self.position_ns = log_ns
            self.loops_done += 1
            if not self.loop or first_ns is None:
                break
        self.finished.set()
        how = "stopped" if self._stop.is_set() else "finished"
        self.get_logger().info(f"replay {how}: {self.published} messages, {self.loops_done} pass(es)")

    def destroy_node(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        self.reader.close()
        super().destroy_node()


def replay_arrivals(context: Context, bag: str | Path, speed: float, segment: str = "left_foot"
                    ) -> tuple[list[float], list[float]]:
    """The replayer's pacing as a subscriber in this process sees it: ``segment``'s raw IMU samples of
    ``bag`` replayed at ``speed``, (their header stamps, their arrival times on ``time.perf_counter``)
    in s, in arrival order (test/test_graph.py and benchmarks/timing.py). Full garbage collections are
    held off while it runs: one would stall the replayer's thread, which is not its pacing."""
    import gc

    from rclpy.node import Node
    from sensor_msgs.msg import Imu

    from gait_biofeedback.nodes.common import make_executor, spin_until

    stamps: list[float] = []
    arrivals: list[float] = []

    def arrived(msg: Imu) -> None:
        stamps.append(msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9)
        arrivals.append(time.perf_counter())

    topic = topics.raw_imu(segment)
    sink = Node("pacing_sink", context=context)
    sink.create_subscription(topic.msg_type, topic.name, arrived, topic.qos)
    replayer = ImuReplayer(context, bag=str(bag), speed=speed, wait_for_subscribers_s=5.0)
    executor = make_executor(context)
    executor.add_node(sink)
    executor.add_node(replayer)
    gc.collect()
    gc.freeze()
    try:
        spin_until(executor, replayer.finished.is_set, timeout=20)
        sent = replayer.published_by_topic.get(topic.absolute(), 0)
        spin_until(executor, lambda: len(stamps) >= sent, timeout=2)
    finally:
        gc.unfreeze()
        replayer.destroy_node()
        sink.destroy_node()
        executor.shutdown()
    return stamps, arrivals



def _installed(type_name: str) -> bool:
    """The rclpy class of ``type_name`` imports here (a recording's ``/tf`` is tf2_msgs, which the PyPI
    ROS wheels lack)."""
    try:
        message_class(type_name)
    except ValueError:
        return False
    return True

def main(args: list[str] | None = None) -> int:
    """Console script: replay until the recording ends (or forever with loop:=true)."""
    import rclpy

    from gait_biofeedback.nodes.common import init_ros, make_executor, spin_until, stop_on_signals

    context = Context()
    init_ros(args, context)
    executor = make_executor(context)
    node = None
    try:
        node = ImuReplayer(context)
        executor.add_node(node)
        with stop_on_signals():
            spin_until(executor, node.finished.is_set)
    except KeyboardInterrupt:
        pass
    except ValueError as err:
        print(err)
        return 2
    finally:
        if node is not None:
            node.destroy_node()
        executor.shutdown()
        if context.ok():
            rclpy.shutdown(context=context)
    return 0


if __name__ == "__main__":
    import sys

    sys.exit(main())
