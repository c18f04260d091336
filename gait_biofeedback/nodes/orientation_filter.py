"""Node ``orientation_filter``: raw IMU streams of every segment → orientations, one node.

Per segment: subscribes ``<segment>/imu/data_raw`` (sensor_msgs/Imu) and ``<segment>/imu/mag``
(sensor_msgs/MagneticField, optional, at its own rate), publishes ``<segment>/imu/data``: the same
stamp and frame, the orientation (sensor→world ENU), the bias-corrected angular velocity, the raw
acceleration and ``orientation_covariance`` (diagonal, ``orientation_variance`` rad², the accuracy
the benchmark measured; the filters give no calibrated covariance). All time handling, start-up
and bad-input rules are in :class:`~gait_biofeedback.core.orientation_stream.SegmentOrientationTracker`.

Parameters: ``segments`` (default all eight), ``algorithm`` (default: the most accurate of the
benchmark), ``<segment>.algorithm`` per-segment override ("" = ``algorithm``), ``rate_hz`` (nominal,
for the filters' defaults; dt always comes from stamps), ``startup_s``, ``max_gap``,
``mag_max_age``, ``orientation_variance``, ``diagnostics_period``, ``stale_after`` (s without
data before a segment is reported stale).

Messages travel as CDR bytes (raw subscriptions, serialized publishing; :mod:`gait_biofeedback.io.cdr`):
no rclpy message object is built per sample. ``analyze`` uses the same conversion functions.
"""

from __future__ import annotations

import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu, MagneticField

from gait_biofeedback.core.filters import ALGORITHMS, DEFAULT_ALGORITHM
from gait_biofeedback.core.orientation_stream import OrientationSample, SegmentOrientationTracker
from gait_biofeedback.core.segments import (
    SEGMENTS,
    mag_topic,
    orientation_topic,
    raw_topic,
    sensor_frame,
)
from gait_biofeedback.io.cdr import (
    ANGULAR_VELOCITY,
    ANGULAR_VELOCITY_COV,
    LINEAR_ACCELERATION,
    LINEAR_ACCELERATION_COV,
    Stamped,
    decode_imu,
    decode_mag,
    pack_imu,
)
from gait_biofeedback.nodes.common import (
    DIAGNOSTICS_TOPIC,
    RELIABLE_QOS,
    SENSOR_QOS,
    diagnostic_array,
    diagnostic_status,
)


def orientation_payload(segment: str, sample: OrientationSample, raw: Stamped, variance: float) -> bytes:
    """Serialized ``<segment>/imu/data`` of one filtered sample, as the ``orientation_filter`` node
    publishes it: the sample's stamp (int ns, handed through the tracker), the sensor frame, q, the
    bias-corrected gyro, the raw acceleration, a diagonal orientation covariance and the raw
    covariances of the message that released the sample."""
    w, x, y, z = sample.q.tolist()
    v = variance
    values = (x, y, z, w, v, 0.0, 0.0, 0.0, v, 0.0, 0.0, 0.0, v, *sample.gyr.tolist(),
              *raw.values[ANGULAR_VELOCITY_COV], *sample.acc.tolist(), *raw.values[LINEAR_ACCELERATION_COV])
    return pack_imu(sample.stamp, sensor_frame(segment), values)


def raw_imu_sample(raw: Stamped) -> tuple[float, tuple, tuple]:
    """(stamp s, gyro, acc) of a raw ``<segment>/imu/data_raw`` message."""
    v = raw.values
    return raw.ns / 1_000_000_000, v[ANGULAR_VELOCITY], v[LINEAR_ACCELERATION]


def mag_sample(mag: Stamped) -> tuple[float, tuple]:
    """(stamp s, field) of a ``<segment>/imu/mag`` message."""
    return mag.ns / 1_000_000_000, mag.values[0:3]


class OrientationFilterNode(Node):
    """All segments' orientation filters (see module docstring)."""

    def __init__(self, context: Context | None = None, **overrides: object) -> None:
        super().__init__("orientation_filter", context=context,
                         parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
        segments = [s for s in self.declare_parameter("segments", list(SEGMENTS)).value if s]
        unknown = [s for s in segments if s not in SEGMENTS]
        if unknown:
            raise ValueError(f"orientation_filter: unknown segments {unknown}; known: {list(SEGMENTS)}")
        default_algorithm = self.declare_parameter("algorithm", DEFAULT_ALGORITHM).value
        rate_hz = float(self.declare_parameter("rate_hz", 100.0).value)
        startup_s = float(self.declare_parameter("startup_s", 1.0).value)
        max_gap = float(self.declare_parameter("max_gap", 0.5).value)
        mag_max_age = float(self.declare_parameter("mag_max_age", 0.05).value)
        self.orientation_variance = float(self.declare_parameter("orientation_variance", 0.0012).value)
        self.stale_after = float(self.declare_parameter("stale_after", 1.0).value)
        diagnostics_period = float(self.declare_parameter("diagnostics_period", 1.0).value)

        self.trackers: dict[str, SegmentOrientationTracker] = {}
        self._out: dict[str, object] = {}
        self._last_arrival: dict[str, float] = {}
        self._frame_warned: set[str] = set()
        self._frames = {s: sensor_frame(s) for s in segments}
        self.wrong_frame: dict[str, int] = {}
        for segment in segments:
            algorithm = self.declare_parameter(f"{segment}.algorithm", "").value or default_algorithm
            if algorithm not in ALGORITHMS:
                raise ValueError(f"orientation_filter: {segment}.algorithm {algorithm!r} is not one of "
                                 f"{sorted(ALGORITHMS)}")
            self.trackers[segment] = SegmentOrientationTracker(
                segment, rate_hz=rate_hz, algorithm=algorithm, startup_s=startup_s, max_gap=max_gap,
                mag_max_age=mag_max_age)
            self.wrong_frame[segment] = 0
            self._out[segment] = self.create_publisher(Imu, orientation_topic(segment), RELIABLE_QOS)
            self.create_subscription(Imu, raw_topic(segment),
                                     lambda data, s=segment: self._on_imu(s, data), SENSOR_QOS, raw=True)
            self.create_subscription(MagneticField, mag_topic(segment),
                                     lambda data, s=segment: self._on_mag(s, data), SENSOR_QOS, raw=True)
        self._diagnostics = self.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, RELIABLE_QOS)
        self.create_timer(diagnostics_period, self._publish_diagnostics)
        self.get_logger().info(
            "tracking " + ", ".join(f"{s} ({t.algorithm})" for s, t in self.trackers.items()))

    def _check_frame(self, segment: str, frame_id: str) -> None:
        if frame_id == sensor_frame(segment):
            return
        self.wrong_frame[segment] += 1
        if segment not in self._frame_warned:
            self._frame_warned.add(segment)
            self.get_logger().warning(
                f"{raw_topic(segment)} carries frame_id {frame_id!r}, expected {sensor_frame(segment)!r}: "
                "is the sensor mapped to the right segment? (processing it anyway)")

    def _on_mag(self, segment: str, data: bytes) -> None:
        self.trackers[segment].add_mag(*mag_sample(decode_mag(data)))

    def _on_imu(self, segment: str, data: bytes) -> None:
        self._last_arrival[segment] = time.monotonic()
        raw = decode_imu(data)
        if raw.frame_id != self._frames[segment]:
            self._check_frame(segment, raw.frame_id)
        tracker = self.trackers[segment]
        samples = tracker.update(*raw_imu_sample(raw), raw.ns)
        for level, text in tracker.pop_messages():
            (self.get_logger().warning if level == "warn" else self.get_logger().info)(text)
        publish = self._out[segment].publish
        for sample in samples:
            publish(orientation_payload(segment, sample, raw, self.orientation_variance))

    def _segment_status(self, segment: str, now: float) -> DiagnosticStatus:
        info = self.trackers[segment].diagnostics()
        info["wrong_frame_id"] = self.wrong_frame[segment]
        last = self._last_arrival.get(segment)
        level, message = DiagnosticStatus.OK, "tracking"
        if last is None:
            level, message = DiagnosticStatus.WARN, "no data yet: is the sensor on and publishing?"
        elif now - last > self.stale_after:
            level = DiagnosticStatus.ERROR
            message = f"no data for {now - last:.1f} s: check the sensor, its battery and the link"
        elif not info["initialized"]:
            message = f"start-up: collecting {self.trackers[segment].startup_s:g} s of quiet standing"
        elif info["mag_disturbed"] or self.wrong_frame[segment] or info["startup_quiet"] is False:
            level = DiagnosticStatus.WARN
            message = ("magnetic disturbance: heading from gyro only" if info["mag_disturbed"]
                       else "wrong frame_id on the raw stream" if self.wrong_frame[segment]
                       else "moved during start-up: gyro bias not removed")
        return diagnostic_status(f"orientation_filter: {segment}", level, message,
                                 sensor_frame(segment), info)

    def _publish_diagnostics(self) -> None:
        now = time.monotonic()
        self._diagnostics.publish(diagnostic_array(
            self, (self._segment_status(s, now) for s in self.trackers)))


def main(args: list[str] | None = None) -> int:
    """Console script."""
    from gait_biofeedback.nodes.common import run_nodes

    return run_nodes([OrientationFilterNode], args)


if __name__ == "__main__":
    import sys

    sys.exit(main())
