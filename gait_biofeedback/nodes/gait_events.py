"""Node ``gait_events``: both feet's orientations → IC/TC events and per-stride temporal parameters.

Subscribes ``<side>_foot/imu/data`` (sensor_msgs/Imu with orientation, reliable) and
``calibration/sensor_to_segment`` (SegmentCalibrationArray, latched: rotation r of each foot, segment →
sensor). Publishes ``gait/events`` (GaitEvent, one sample after the event: stamp = the event sample's
stamp, ``detection_latency`` = to the confirming sample) and ``gait/cycles`` (GaitCycle of each stride,
IC to IC; an implausible stride, < ``min_stride_s`` or > ``max_stride_s`` or without exactly one
TC, is published with ``plausible = false`` and its ``flag``; its spatial values come from the foot's
trajectory, :mod:`~gait_biofeedback.core.gait.spatial`: it is published ``provisional_after_s`` (15 ms)
after the closing IC with a provisional stride length, speed and swing values (foot height and
clearance, foot and turning angles, lateral excursion), whose smoothed values follow on
``gait/stride_space`` (StrideSpace) once the next stance closes the trajectory; without a provisional
value it waits for the smoothed ones, at most ``spatial_wait_s`` s after the
closing IC), plus ``/diagnostics``. The detection is
:class:`~gait_biofeedback.core.gait.events.GaitEventDetector` (thesis Algorithm 1), the strides
:class:`~gait_biofeedback.core.gait.cycles.GaitCycleTracker`, the stream rules below
:class:`~gait_biofeedback.core.gait.stream.GaitEventStream` (a calibration is in force from its header
stamp, 0 = at once).

Bad input: a foot without data for ``stale_after_s`` s (wall clock), a stamp gap > ``max_gap_s`` s or a
stamp going backwards resets that foot's detector and stride state, counted and said on /diagnostics.
Until a valid calibration of a foot arrives its samples are not used (counted), unless
``use_standing_reference``: then the foot's anterior axis is taken from its first orientation sample
(IMU x axis made horizontal, thesis §6.2.2 correction 1; assumes the IMU x axis points toe-ward).

Parameters: :class:`~gait_biofeedback.core.gait.stream.GaitEventsParams`.
"""

from __future__ import annotations

import time

from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.context import Context

from gait_biofeedback.core.gait.events import GaitEventDetector
from gait_biofeedback.core.gait.stream import GaitEventsParams, GaitEventStream
from gait_biofeedback.nodes.common import GuardedNode, log_notices, publisher, subscribe
from gait_biofeedback.nodes.parameters import declare_parameters, node_overrides
from gait_biofeedback.wire import diagnostics, topics
from gait_biofeedback.wire.calibration import entries
from gait_biofeedback.wire.cdr import decode_imu
from gait_biofeedback.wire.gait import event_msg, foot_frame, stride_output
from gait_biofeedback.wire.imu import is_recovering, orientation_sample
from gait_biofeedback_msgs.msg import SegmentCalibrationArray


class GaitEventsNode(GuardedNode):
    """Gait events and stride parameters of both feet (see module docstring)."""

    NODE_NAME = "gait_events"

    def __init__(self, context: Context | None = None, params: GaitEventsParams | None = None,
                 **overrides: object) -> None:
        super().__init__(self.NODE_NAME, context=context, parameter_overrides=node_overrides(overrides))
        self.params: GaitEventsParams = declare_parameters(self, GaitEventsParams, params)
        self.stream = GaitEventStream(self.params)
        self.sides = self.stream.sides
        self.stale_after_s = self.params.stale_after_s
        self._last_arrival: dict[str, float] = {}
        self._stopped: dict[str, bool] = {s: False for s in self.sides}
        self._events = publisher(self, topics.GAIT_EVENTS)
        self._strides = {t.name: publisher(self, t) for t in (topics.GAIT_CYCLES, topics.STRIDE_SPACE)}
        for side in self.sides:
            subscribe(self, topics.orientation(foot_frame(side)), lambda data, s=side: self._on_imu(s, data),
                      raw=True)
        subscribe(self, topics.CALIBRATION, self._on_calibration)
        self.create_timer(self.params.diagnostics_period_s, self._check_streams)

    @property
    def detectors(self) -> dict[str, GaitEventDetector]:
        """Per-foot detectors (held by the core stream)."""
        return self.stream.detectors

    @property
    def calibrated(self) -> dict[str, bool]:
        """Whether each foot's calibration is in force."""
        return self.stream.calibrated

    @property
    def counts(self) -> dict[str, dict[str, int]]:
        """Per-foot counters shown on /diagnostics."""
        return self.stream.counts

    def _on_calibration(self, msg: SegmentCalibrationArray) -> None:
        self.stream.apply_calibration(*entries(msg))

    def _on_imu(self, side: str, data: bytes) -> None:
        self._last_arrival[side] = time.monotonic()
        self._stopped[side] = False
        imu = decode_imu(data)
        _, acc, gyr, q = orientation_sample(imu)
        events, cycles = self.stream.update(side, imu.ns, q, is_recovering(imu), gyr, acc)
        for event in events:
            self._events.publish(event_msg(event))
        self._publish_strides(cycles)
        log_notices(self.get_logger(), self.stream.notices.pop())

    def _publish_strides(self, cycles: list) -> None:
        for cycle in cycles:
            topic, msg = stride_output(cycle)
            self._strides[topic.name].publish(msg)

    def finish(self) -> None:
        """The data ended (the end of a replay): the strides still held for their spatial values go
        out (:meth:`GaitEventStream.finish`), as ``analyze`` publishes them at the end of a file."""
        self._publish_strides(self.stream.finish())

    def _check_streams(self) -> None:
        now = time.monotonic()
        statuses = []
        note = self.stream.notes
        for side in self.sides:
            last = self._last_arrival.get(side)
            level, message = DiagnosticStatus.OK, "detecting"
            if last is None:
                level, message = DiagnosticStatus.WARN, f"no {side} foot orientation yet"
            elif now - last > self.stale_after_s:
                if not self._stopped[side]:
                    self._stopped[side] = True
                    self.stream.stream_stopped(side, now - last)
                    self._publish_strides(self.stream.take_released(side))
                    log_notices(self.get_logger(), self.stream.notices.pop())
                level = DiagnosticStatus.ERROR
                message = (f"no data for {now - last:.1f} s: {side} foot state reset; check the sensor "
                           "and the orientation filter")
            elif not self.calibrated[side]:
                level, message = DiagnosticStatus.WARN, "waiting for the foot calibration " + (
                    f"({note[side]})" if note[side] else "(calibration/sensor_to_segment)")
            elif note[side]:
                level, message = DiagnosticStatus.WARN, note[side]
                note[side] = ""
            extra = {"waiting_for_ic": self.detectors[side].waiting_for_ic}
            foot = self.stream.feet.get(side)
            if foot is not None:
                rest = foot.rest_of_swing
                extra["provisional_spread_m"] = rest.spread
                if not rest.trusted and rest.withheld and level == DiagnosticStatus.OK:
                    message = (f"detecting; provisional stride lengths withheld ({100 * rest.spread:.1f} cm "
                               "RMS from the smoothed ones): spatial values come with the next stance")
            statuses.append(diagnostics.status(f"gait_events: {side} foot", level, message, foot_frame(side),
                                               {**self.counts[side], **extra}))
        self.publish_diagnostics(statuses)


def main(args: list[str] | None = None) -> int:
    """Console script."""
    from gait_biofeedback.nodes.common import run_nodes

    return run_nodes([GaitEventsNode], args)


if __name__ == "__main__":
    import sys

    sys.exit(main())
