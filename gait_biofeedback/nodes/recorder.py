"""Node ``recorder``: topics → a rosbag2 folder (metadata.yaml + MCAP), crash-safe.

Subscriptions are raw (the CDR bytes, no deserialisation); a callback only appends to a queue, and a
writer thread does all file work, so no message callback ever waits for the disk (the
``recorder/stop`` service waits, up to 30 s, for the writer thread to close the bag, so that its
reply means "saved"). The writer closes a chunk
at least every ``flush_period_s`` s, so a killed session still leaves a readable file
(``gait-biofeedback repair`` restores its index and metadata.yaml).

QoS per topic follows its publishers, as ``ros2 bag record`` does: reliable only if every publisher
is reliable, transient-local (latched) only if every publisher is, so latched state such as the
calibration is recorded even when it was published before the recorder started.

Parameters: :class:`~gait_biofeedback.io.params.RecorderParams`. Services ``recorder/start`` and
``recorder/stop`` (std_srvs/Trigger) open a new bag folder
(``<output>_1``, ``<output>_2``, … after the first) and close it, e.g. from the dashboard.

Log time is the receive time: the system clock, or with ``use_sim_time`` the ``/clock`` (a replay
recording then has one time base, the recording's; messages before the first tick are logged at it).
"""

from __future__ import annotations

import contextlib
import queue
import threading
import time
from pathlib import Path

from rclpy.context import Context
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_srvs.srv import Trigger

from gait_biofeedback.core.rate import MISSING_WARN, StampHoles
from gait_biofeedback.io.bag import BagWriter, message_class
from gait_biofeedback.io.params import RecorderParams
from gait_biofeedback.nodes.common import GuardedNode
from gait_biofeedback.nodes.parameters import declare_parameters, node_overrides
from gait_biofeedback.wire import diagnostics, topics
from gait_biofeedback.wire.body import BodyFrameTracker
from gait_biofeedback.wire.cdr import header_stamp_ns
from gait_biofeedback.wire.tf import TF_TOPIC, TF_TYPE, tf_message
from gait_biofeedback.wire.topics import RELIABLE_QOS, SENSOR_QOS

ALWAYS_EXCLUDED = ("/parameter_events", "/rosout", "/clock")
"""Never recorded: ROS bookkeeping, and a replayer's clock (a recording's time is its log time)."""
BATCH_WAIT = 0.01
"""Seconds the writer thread waits, once it has emptied the queue, before it blocks on it again."""


class Recorder(GuardedNode):
    """Records topics to a rosbag2/MCAP folder (see module docstring)."""

    NODE_NAME = "recorder"

    def __init__(self, context: Context | None = None, params: RecorderParams | None = None,
                 **overrides: object) -> None:
        super().__init__(self.NODE_NAME, context=context, parameter_overrides=node_overrides(overrides))
        p: RecorderParams = declare_parameters(self, RecorderParams, params)
        self.params = p
        self._base_output = p.output
        self.requested = [t if t.startswith("/") else self.resolve_topic_name(t) for t in p.topics if t]
        self.excluded = {*ALWAYS_EXCLUDED, *(t for t in p.exclude if t)}
        if p.body_frames:
            self.excluded.add(TF_TOPIC)  # written from the body's frames, not recorded twice
        self._body = BodyFrameTracker(p.body, self.resolve_topic_name) if p.body_frames else None
        self._writer_options = {
            "compression": p.compression,
            "flush_period_s": p.flush_period_s,
            "split_size_bytes": p.split_size_bytes or None,
            "split_duration_s": p.split_duration_s or None,
        }
        self.writer: BagWriter | None = None
        self.output: Path | None = None
        self.sessions: list[Path] = []
        self.received = 0
        self._raw_topics: set[str] = set()
        self._holes: dict[str, StampHoles] = {}  # raw IMU topic → samples missing from its stamps
        self._holes_reported: dict[str, tuple[int, int]] = {}
        self.dropped_while_stopped = 0
        self.dropped_by_writer = 0
        self._written_before = 0
        self._recording = False
        self._recorded_topics: dict[str, object] = {}
        self._latched_topics: set[str] = set()
        self._latched: dict[str, tuple[str, bytes]] = {}  # the last message of each, for a new bag
        self.write_error: str | None = None
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        # Log time = receive time in ns. Without use_sim_time the node's ROS_TIME clock is the system
        # clock, i.e. time.time_ns() (≈10× cheaper than get_clock().now() per message).
        self._sim_time = bool(self.get_parameter("use_sim_time").value)
        self._now_ns = (lambda: self.get_clock().now().nanoseconds) if self._sim_time else time.time_ns
        self._before_clock: list[tuple[str, str, bytes]] = []  # received before the first /clock
        self._closed = threading.Event()
        self._thread = threading.Thread(target=self._write_loop, name="recorder_writer", daemon=True)
        if p.autostart:
            self.start()  # before the writer thread: an unusable output folder raises with nothing to undo
        self._thread.start()
        self.create_service(Trigger, topics.RECORDER_START_SERVICE, self._on_start)
        self.create_service(Trigger, topics.RECORDER_STOP_SERVICE, self._on_stop)
        self._discover()
        self.create_timer(p.discovery_period_s, self._discover)
        self.create_timer(1.0, self._publish_diagnostics)

    def _next_output(self) -> Path:
        if not self._base_output:
            return Path(time.strftime("recordings/session_%Y%m%d_%H%M%S"))
        base = Path(self._base_output)
        return base if not self.sessions else base.with_name(f"{base.name}_{len(self.sessions)}")

    def start(self) -> Path:
        """Open a new bag (a new folder per start) and record into it; returns its path. The bag
        starts with the last message of every latched topic received so far (the calibration in
        force, also when it came while recording was stopped). Raises OSError (nothing left behind,
        the next start tries the same folder again) when the folder cannot be written."""
        if self._recording and self.output is not None:
            return self.output
        output = self._next_output()
        self.writer = BagWriter(output, **self._writer_options)
        self.output = output
        self.sessions.append(output)
        self.write_error = None
        self._recording = True
        for topic, (type_name, data) in self._latched.items():
            self._log(topic, type_name, data)
        self.get_logger().info(f"recording to {self.output}")
        return self.output

    def stop(self) -> Path | None:
        """Stop recording and close the bag (the writer thread closes it; this waits for that).
        None when not recording; after it, :attr:`write_error` says whether closing failed."""
        if not self._recording:
            return None
        self._recording = False
        self._before_clock.clear()
        done = threading.Event()
        self._queue.put(("__close__", done))
        done.wait(timeout=30.0)
        self.get_logger().info(f"recording closed: {self.output}")
        return self.output

    def _on_start(self, _request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        was = self._recording
        try:
            path = self.start()
        except OSError as exc:
            response.success = False
            response.message = f"could not start recording: {exc}"
            self.get_logger().error(response.message)
            return response
        response.success = True
        response.message = f"already recording to {path}" if was else f"recording to {path}"
        return response

    def _on_stop(self, _request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        path = self.stop()
        response.success = path is not None and self.write_error is None
        response.message = (self.write_error or f"saved {path}") if path else "not recording"
        return response

    def subscribe(self, topic: str, type_name: str) -> None:
        """Record ``topic`` of ``type_name`` from now on (idempotent)."""
        if topic in self._recorded_topics or topic in self.excluded:
            return
        qos = self._qos_for(topic)
        if qos.durability == DurabilityPolicy.TRANSIENT_LOCAL:
            self._latched_topics.add(topic)
        if topics.segment_of(topic) is not None and topic.endswith("/data_raw"):
            self._raw_topics.add(topic)  # its stamps are checked for holes
        self._recorded_topics[topic] = self.create_subscription(
            message_class(type_name), topic,
            lambda data, topic=topic, type_name=type_name: self._on_message(topic, type_name, data),
            qos, raw=True)

    def _qos_for(self, topic: str) -> QoSProfile:
        infos = self.get_publishers_info_by_topic(topic)
        if not infos:
            return RELIABLE_QOS if topic == topics.DIAGNOSTICS.name else SENSOR_QOS
        reliable = all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in infos)
        latched = all(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos)
        base = RELIABLE_QOS if reliable else SENSOR_QOS
        durability = DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE
        return QoSProfile(history=base.history, depth=base.depth, reliability=base.reliability,
                          durability=durability)

    def recording(self, topic: str) -> bool:
        """True once ``topic`` (absolute name) has a recording subscription."""
        return topic in self._recorded_topics

    def discover(self) -> None:
        """Subscribe to every matching topic that exists now (also runs on a timer)."""
        self._discover()

    def _discover(self) -> None:
        for topic, types in self.get_topic_names_and_types():
            if self.requested and topic not in self.requested:
                continue
            if topic not in self._recorded_topics and topic not in self.excluded and types:
                self.subscribe(topic, types[0])

    def _on_message(self, topic: str, type_name: str, data: bytes) -> None:
        self.received += 1
        if topic in self._raw_topics:
            stamp_ns = header_stamp_ns(data)
            if stamp_ns is not None:
                self._holes.setdefault(topic, StampHoles()).update(stamp_ns)
        if topic in self._latched_topics:
            self._latched[topic] = (type_name, data)
        if not self._recording:
            self.dropped_while_stopped += 1
            return
        self._log(topic, type_name, data)

    def _log(self, topic: str, type_name: str, data: bytes) -> None:
        now = self._now_ns()
        if self._sim_time:
            if now == 0:  # no /clock yet: logged at its first tick, not at 0 (another time base)
                self._before_clock.append((topic, type_name, data))
                return
            while self._before_clock:
                self._queue.put((*self._before_clock.pop(0), now))
        self._queue.put((topic, type_name, data, now))

    def _close_writer(self) -> None:
        if self.writer is not None:
            try:
                self.writer.close()
            except OSError as err:
                self._write_failed(err)
                return
            self._written_before += self.writer.message_count
            self.writer = None

    def _write_failed(self, err: OSError) -> None:
        """A write error (a full disk): stop recording at the last complete chunk, say so once."""
        writer, self.writer = self.writer, None
        self._recording = False
        if writer is None:
            return
        writer.abandon()
        self._written_before += writer.good_message_count
        good = writer.good_end_ns
        if not good:
            upto = "its start"
        elif good > 1e18:  # wall-clock log times (live): a time of day
            upto = time.strftime("%H:%M:%S", time.localtime(good / 1e9))
        else:
            upto = f"{good / 1e9:.1f} s"
        self.write_error = (f"recording stopped: writing {writer.path} failed ({err.strerror or err}); it is "
                            f"readable up to {upto}. Processing goes on: free space, then press Record to "
                            "go on in a new folder")
        self.get_logger().error(self.write_error)

    def _write_loop(self) -> None:
        while True:
            try:
                item = self._queue.get(timeout=0.2)
            except queue.Empty:
                item = None
            if item is None:
                if self._closed.is_set():
                    break
                if self.writer is not None:
                    try:
                        self.writer.maybe_flush()
                    except OSError as err:
                        self._write_failed(err)
                continue
            if item[0] == "__close__":
                self._close_writer()
                item[1].set()
                continue
            if self.writer is None:  # recording stopped by a write error
                self.dropped_while_stopped += 1
                continue
            try:
                self.writer.write_serialized(*item)
                if self._body is not None and item[0] in self._body.topics:
                    self._write_body(item[0], item[2], item[3])
            except OSError as err:
                self._write_failed(err)
            except Exception as err:  # e.g. a type the writer cannot describe: that message only
                self.dropped_by_writer += 1
                if self.dropped_by_writer == 1:
                    self.get_logger().error(f"could not record a message on {item[0]} ({err}); further "
                                            "ones are counted on /diagnostics")
            if self._queue.empty():
                # let messages gather: a put that has to wake this thread costs the executor thread
                # ~10 µs (GIL hand-over), one per message at ~2,600 messages/s
                time.sleep(BATCH_WAIT)

    def _write_body(self, topic: str, data: bytes, log_ns: int) -> None:
        """The body's frames completed by this message, as ``/tf`` at its log time (writer thread)."""
        pose = self._body.feed(topic, data)
        if pose is None:
            return
        tf = tf_message(*pose)
        if tf:
            self.writer.write_serialized(TF_TOPIC, TF_TYPE, tf, log_ns, padded=True)

    def _missing_raw(self) -> tuple[float, str]:
        """The largest share of raw samples missing from one topic since the last report, and the topic."""
        worst, name = 0.0, ""
        for topic, holes in self._holes.items():
            samples, missing = self._holes_reported.get(topic, (0, 0))
            new_missing, new_samples = holes.missing - missing, holes.samples - samples
            self._holes_reported[topic] = (holes.samples, holes.missing)
            if new_missing and new_missing / (new_missing + new_samples) > worst:
                worst, name = new_missing / (new_missing + new_samples), topic
        return worst, name

    def _publish_diagnostics(self) -> None:
        values = {"received": self.received, "written": self.written, "bags": len(self.sessions),
                  "dropped_while_stopped": self.dropped_while_stopped,
                  "dropped_by_writer": self.dropped_by_writer,
                  "raw_missing": sum(h.missing for h in self._holes.values())}
        missing, topic = self._missing_raw()
        if self.write_error:
            level, text = diagnostics.ERROR, self.write_error
        elif self._recording and missing > MISSING_WARN:
            level = diagnostics.WARN
            text = (f"recording to {self.output}; {100 * missing:.1f} % of the raw samples of {topic} "
                    "missing from the stamps (the link, or this process falling behind: record in a "
                    "process of its own)")
        elif self._recording:
            level, text = diagnostics.OK, f"recording to {self.output}"
        else:
            level, text = diagnostics.WARN, "not recording: press Record on the dashboard (recorder/start)"
        self.publish_diagnostics([diagnostics.status("recorder", level, text, values=values)])

    @property
    def written(self) -> int:
        """Messages handed to the files so far, over every start/stop."""
        writer = self.writer  # read once: the writer thread may drop it after a write error
        return self._written_before + (writer.message_count if writer is not None else 0)

    def discard(self) -> None:
        """After :meth:`destroy_node` of a graph that never started (a node refused to start):
        remove the bag files it created, so that the corrected command can use the same folder."""
        for folder in self.sessions:
            for file in [*folder.glob("*.mcap"), folder / "metadata.yaml"]:
                file.unlink(missing_ok=True)
            with contextlib.suppress(OSError):
                folder.rmdir()
        self.sessions.clear()

    def destroy_node(self) -> None:
        for sub in self._recorded_topics.values():
            self.destroy_subscription(sub)
        self._recorded_topics.clear()
        self._recording = False
        self._closed.set()
        self._queue.put(None)
        self._thread.join(timeout=30.0)
        self._close_writer()
        self.get_logger().info(f"recording closed: {self.written} messages in {self.output}")
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Console script: record until Ctrl-C / SIGTERM, then close the bag."""
    from gait_biofeedback.nodes.common import run_nodes

    return run_nodes([Recorder], args)


if __name__ == "__main__":
    import sys

    sys.exit(main())
