"""Node ``orientation_filter``: raw IMU streams of every segment → orientations, one node.

Per segment: subscribes ``<segment>/imu/data_raw`` (sensor_msgs/Imu) and ``<segment>/imu/mag``
(sensor_msgs/MagneticField, optional, at its own rate), publishes ``<segment>/imu/data``: the same
stamp and frame, the orientation (sensor→world ENU), the bias-corrected angular velocity, the raw
acceleration and ``orientation_covariance`` (diagonal, ``orientation_variance`` rad², the accuracy
the benchmark measured; the filters give no calibrated covariance). All time handling, start-up
and bad-input rules are in :class:`~gait_biofeedback.core.orientation.stream.SegmentOrientationTracker`.

Parameters: :class:`~gait_biofeedback.core.orientation.stream.OrientationParams` (``ros2 param describe``
gives each one's description, unit and range).

Messages travel as CDR bytes (raw subscriptions, serialized publishing; :mod:`gait_biofeedback.wire.cdr`):
no rclpy message object is built per sample. ``analyze`` uses the same conversion functions.
"""

from __future__ import annotations

import time

from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.context import Context

from gait_biofeedback.core.orientation.stream import OrientationParams, SegmentOrientationTracker
from gait_biofeedback.core.segments import sensor_frame
from gait_biofeedback.nodes.common import GuardedNode, log_notices, publisher, subscribe
from gait_biofeedback.nodes.parameters import declare_parameters, node_overrides
from gait_biofeedback.wire import diagnostics, topics
from gait_biofeedback.wire.cdr import decode_imu, decode_mag, pack_imu
from gait_biofeedback.wire.imu import mag_sample, orientation_fields, raw_sample

FALLING_BEHIND_S = 0.5
"""A sample processed this long after its stamp (by the node's clock) means the node falls behind."""

OTHER_CLOCK_S = 60.0
"""Beyond this, the stamps are in another time base than the node's clock (not a backlog)."""

FLUSH_AFTER = 0.25
"""Wall-clock seconds without a sample after which a stream's reorder window is flushed."""


class OrientationFilterNode(GuardedNode):
    """All segments' orientation filters (see module docstring)."""

    NODE_NAME = "orientation_filter"

    def __init__(self, context: Context | None = None, params: OrientationParams | None = None,
                 **overrides: object) -> None:
        super().__init__(self.NODE_NAME, context=context, parameter_overrides=node_overrides(overrides))
        self.params: OrientationParams = declare_parameters(self, OrientationParams, params)
        self.orientation_variance = self.params.orientation_variance
        self.stale_after_s = self.params.stale_after_s
        self.trackers: dict[str, SegmentOrientationTracker] = {}
        self._out: dict[str, object] = {}
        self._last_arrival: dict[str, float] = {}
        self._frame_warned: set[str] = set()
        self._frames = {s: sensor_frame(s) for s in self.params.segments}
        self.wrong_frame: dict[str, int] = {}
        for segment in self.params.segments:
            self.trackers[segment] = self.params.tracker(segment)
            self.wrong_frame[segment] = 0
            self._out[segment] = publisher(self, topics.orientation(segment))
            subscribe(self, topics.raw_imu(segment), lambda data, s=segment: self._on_imu(s, data), raw=True)
            subscribe(self, topics.magnetometer(segment), lambda data, s=segment: self._on_mag(s, data),
                      raw=True)
        self._last_raw: dict[str, object] = {}
        self._lag: dict[str, float] = {}  # largest (clock now - sample stamp) since the last /diagnostics
        self.create_timer(self.params.diagnostics_period_s, self._publish_diagnostics)
        self.create_timer(FLUSH_AFTER / 2, self._flush_silent)
        self.get_logger().info(
            "tracking " + ", ".join(f"{s} ({t.algorithm})" for s, t in self.trackers.items()))

    def _check_frame(self, segment: str, frame_id: str) -> None:
        if frame_id == sensor_frame(segment):
            return
        self.wrong_frame[segment] += 1
        if segment not in self._frame_warned:
            self._frame_warned.add(segment)
            self.get_logger().warning(
                f"{topics.raw_imu(segment).name} carries frame_id {frame_id!r}, expected "
                f"{sensor_frame(segment)!r}: "
                "is the sensor mapped to the right segment? (processing it anyway)")

    def _on_mag(self, segment: str, data: bytes) -> None:
        self.trackers[segment].add_mag(*mag_sample(decode_mag(data)))

    def _on_imu(self, segment: str, data: bytes) -> None:
        self._last_arrival[segment] = time.monotonic()
        raw = decode_imu(data)
        now_ns = self.get_clock().now().nanoseconds
        if now_ns:
            self._lag[segment] = max(self._lag.get(segment, 0.0), (now_ns - raw.ns) / 1e9)
        if raw.frame_id != self._frames[segment]:
            self._check_frame(segment, raw.frame_id)
        self._last_raw[segment] = raw
        tracker = self.trackers[segment]
        self._publish(segment, tracker.update(*raw_sample(raw)), raw)

    def _publish(self, segment: str, samples: list, raw: object) -> None:
        log_notices(self.get_logger(), self.trackers[segment].notices.pop())
        publish = self._out[segment].publish
        for sample in samples:
            publish(pack_imu(*orientation_fields(segment, sample, raw, self.orientation_variance)))

    def _flush_silent(self) -> None:
        """A stream that stopped (a recording ended, a sensor went silent) releases what its reorder
        window still holds, as the offline analysis does at the end of a recording."""
        now = time.monotonic()
        for segment, tracker in self.trackers.items():
            last = self._last_arrival.get(segment)
            if last is not None and now - last > FLUSH_AFTER and tracker.sequencer.holding:
                self._publish(segment, tracker.flush(), self._last_raw[segment])

    def _segment_status(self, segment: str, now: float) -> DiagnosticStatus:
        tracker = self.trackers[segment]
        extra = ["wrong frame_id on the raw stream"] if self.wrong_frame[segment] else []
        values = {"wrong_frame_id": self.wrong_frame[segment]}
        lag = self._lag.pop(segment, None)
        if lag is not None:
            values["lag_s"] = round(lag, 3)
            if lag > OTHER_CLOCK_S:
                extra.insert(0, f"stamps {lag:.0f} s behind this node's clock: the sensor time is not mapped "
                                "to ROS time (a replay needs use_sim_time)")
            elif lag > FALLING_BEHIND_S:
                extra.insert(0, f"falling behind: samples processed up to {lag:.2f} s after their stamps")
        last = self._last_arrival.get(segment)
        problem = diagnostics.no_data(None if last is None else now - last, self.stale_after_s)
        return diagnostics.orientation_status(segment, tracker, problem, extra, values)

    def _publish_diagnostics(self) -> None:
        now = time.monotonic()
        self.publish_diagnostics(self._segment_status(s, now) for s in self.trackers)


def main(args: list[str] | None = None) -> int:
    """Console script."""
    from gait_biofeedback.nodes.common import run_nodes

    return run_nodes([OrientationFilterNode], args)


if __name__ == "__main__":
    import sys

    sys.exit(main())
