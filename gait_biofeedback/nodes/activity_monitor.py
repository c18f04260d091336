"""Node ``activity_monitor``: chest accelerometer → posture, transitions, walking modality, steps.

Subscribes ``chest/imu/data_raw`` (sensor_msgs/Imu: the accelerometer, thesis ch. 7; the gyro only tells a
sensor not yet worn from a still wearer when the upright reference is sought), the
thighs' ``imu/data_raw`` (``thighs``: their inclination tells sitting from standing while they send) and
``calibration/sensor_to_segment`` (latched; the chest's rotation gives the trunk's forward axis, in
force from the message's stamp), publishes ``activity/state`` (gait_biofeedback_msgs/ActivityState)
whenever posture, locomotion or the last transition change, and every ``publish_period_s`` s of
wall-clock time (:class:`~gait_biofeedback.core.activity.run.ActivityRun`, which ``analyze`` drives on
recording time). The state describes the sample ``delay`` s before the newest one
(:data:`gait_biofeedback.core.activity.output.DELAY_S`): the monitor needs that look-ahead to
confirm steps and transitions. Bad input: NaN samples and repeated stamps are skipped and counted;
a stamp going backwards or a gap > ``max_gap_s`` s restarts the monitor (after a jump back its upright
reference is found again, see :mod:`gait_biofeedback.core.activity.reference`; after a gap it is kept).

Parameters: :class:`~gait_biofeedback.core.activity.stream.ActivityParams` (``forward_axis`` only decides
upstairs vs downstairs, and a wrong one swaps them).
"""

from __future__ import annotations

from functools import partial

from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.context import Context

from gait_biofeedback.core.activity.output import ActivityState
from gait_biofeedback.core.activity.run import ActivityRun
from gait_biofeedback.core.activity.stream import ActivityParams
from gait_biofeedback.core.segments import sensor_frame
from gait_biofeedback.nodes.common import GuardedNode, log_notices, publisher, subscribe
from gait_biofeedback.nodes.parameters import declare_parameters, node_overrides
from gait_biofeedback.wire import diagnostics, topics
from gait_biofeedback.wire.activity import activity_msg
from gait_biofeedback.wire.calibration import entries
from gait_biofeedback.wire.cdr import decode_imu
from gait_biofeedback.wire.imu import raw_sample
from gait_biofeedback_msgs.msg import SegmentCalibrationArray


class ActivityMonitorNode(GuardedNode):
    """Chest activity monitor (see module docstring)."""

    NODE_NAME = "activity_monitor"

    def __init__(self, context: Context | None = None, params: ActivityParams | None = None,
                 **overrides: object) -> None:
        super().__init__(self.NODE_NAME, context=context, parameter_overrides=node_overrides(overrides))
        self.params: ActivityParams = declare_parameters(self, ActivityParams, params)
        self.segment = self.params.segment
        self.run = ActivityRun(self.params, clock="wall")
        self.stream = self.run.stream
        self.published = 0
        self._pub = publisher(self, topics.ACTIVITY)
        subscribe(self, topics.raw_imu(self.segment), self._on_imu, raw=True)
        for thigh in self.stream.thighs.segments:
            subscribe(self, topics.raw_imu(thigh), partial(self._on_thigh, thigh), raw=True)
        subscribe(self, topics.CALIBRATION, self._on_calibration)
        self.create_timer(self.params.publish_period_s, self._periodic)

    @property
    def counts(self) -> dict[str, int]:
        """Input counters of the stream plus states published."""
        return {**self.stream.counts, **self.stream.thighs.counts, "published": self.published}

    def _on_calibration(self, msg: SegmentCalibrationArray) -> None:
        self.stream.apply_calibration(*entries(msg))
        log_notices(self.get_logger(), self.stream.notices.pop())

    def _on_imu(self, data: bytes) -> None:
        stamp_ns, gyro, acc = raw_sample(decode_imu(data))
        states = self.run.update(stamp_ns, acc, gyro)
        log_notices(self.get_logger(), self.stream.notices.pop())
        for state in states:
            self._publish(state)

    def _on_thigh(self, segment: str, data: bytes) -> None:
        stamp_ns, _, acc = raw_sample(decode_imu(data))
        for state in self.run.update_thigh(segment, stamp_ns, acc):
            self._publish(state)

    def finish(self) -> None:
        """The data ended (the end of a replay): the states still held go out, as ``analyze`` publishes
        them at the end of a file (:meth:`ActivityRun.finish`)."""
        for state in self.run.finish():
            self._publish(state)

    def _publish(self, state: ActivityState) -> None:
        self._pub.publish(activity_msg(state, self.run.newest_ns, self.segment))
        self.published += 1

    def _periodic(self) -> None:
        latest = self.run.periodic()
        if latest is not None:
            self._publish(latest)
        level = DiagnosticStatus.OK if latest is not None else DiagnosticStatus.WARN
        message = "monitoring" if latest is not None else "waiting for chest data"
        self.publish_diagnostics([diagnostics.status(
            "activity_monitor", level, message, sensor_frame(self.segment), self.counts)])


def main(args: list[str] | None = None) -> int:
    """Console script."""
    from gait_biofeedback.nodes.common import run_nodes

    return run_nodes([ActivityMonitorNode], args)


if __name__ == "__main__":
    import sys

    sys.exit(main())
