"""Node ``activity_monitor``: chest accelerometer → posture, transitions, walking modality, steps.

Subscribes ``chest/imu/data_raw`` (sensor_msgs/Imu; only the accelerometer is used, thesis ch. 7) and
``calibration/sensor_to_segment`` (latched; the chest's rotation gives the trunk's forward axis, in
force from the message's stamp),
publishes ``activity/state`` (gait_biofeedback_msgs/ActivityState) whenever posture, locomotion or
the last transition change, and every ``publish_period`` s. The state describes the sample
``delay`` s before the newest one (:data:`gait_biofeedback.core.activity.DELAY_S`): the monitor
needs that look-ahead to confirm steps and transitions. Bad input: NaN samples and repeated stamps
are skipped and counted; a stamp going backwards or a gap > ``max_gap`` s restarts the monitor
(its upright reference is taken again from the next ``reference_s`` s).

Parameters: ``segment`` (chest), ``rate_hz`` (nominal rate of the chest IMU, 20–200 Hz), ``units``
(``m/s2`` or ``g``), ``reference_s``, ``thigh_length`` (m), ``initial_posture``, ``forward_axis`` (the
trunk's forward direction in sensor axes until a calibration gives it; it only decides upstairs vs
downstairs, and a wrong one swaps them), ``max_gap``, ``publish_period``.
"""

from __future__ import annotations

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu

from gait_biofeedback.core.activity import ActivityState as CoreActivityState
from gait_biofeedback.core.activity_stream import ActivityStream
from gait_biofeedback.core.quaternion import rotate
from gait_biofeedback.core.segments import raw_topic
from gait_biofeedback.io.cdr import LINEAR_ACCELERATION, Stamped, decode_imu
from gait_biofeedback.nodes.common import (
    CALIBRATION_TOPIC,
    DIAGNOSTICS_TOPIC,
    LATCHED_QOS,
    RELIABLE_QOS,
    SENSOR_QOS,
    diagnostic_array,
    diagnostic_status,
    s_to_stamp,
    stamp_to_s,
)
from gait_biofeedback.nodes.joint_angles import calibration_rotations
from gait_biofeedback_msgs.msg import ActivityState, SegmentCalibrationArray

POSTURE_CODES = {"standing": ActivityState.POSTURE_STANDING, "sitting": ActivityState.POSTURE_SITTING,
                 "lying": ActivityState.POSTURE_LYING}
LOCOMOTION_CODES = {"none": ActivityState.LOCOMOTION_NONE, "level": ActivityState.LOCOMOTION_LEVEL,
                    "upstairs": ActivityState.LOCOMOTION_UPSTAIRS,
                    "downstairs": ActivityState.LOCOMOTION_DOWNSTAIRS}
TRANSITION_CODES = {None: ActivityState.TRANSITION_NONE,
                    "sit_to_stand": ActivityState.TRANSITION_SIT_TO_STAND,
                    "stand_to_sit": ActivityState.TRANSITION_STAND_TO_SIT,
                    "sit_to_lie": ActivityState.TRANSITION_SIT_TO_LIE,
                    "lie_to_sit": ActivityState.TRANSITION_LIE_TO_SIT}


def to_message(state: CoreActivityState, newest_t: float, frame_id: str = "chest") -> ActivityState:
    """Core state → ActivityState message (stamp = the instant the state describes)."""
    msg = ActivityState()
    msg.header.stamp = s_to_stamp(state.t)
    msg.header.frame_id = frame_id
    msg.posture = POSTURE_CODES[state.posture]
    msg.locomotion = LOCOMOTION_CODES[state.locomotion]
    msg.last_transition = TRANSITION_CODES[state.last_transition]
    if state.last_transition_t is not None:
        msg.last_transition_stamp = s_to_stamp(state.last_transition_t)
    msg.step_count = int(state.step_count)
    msg.trunk_inclination = float(state.trunk_inclination)
    msg.delay = float(newest_t - state.t)
    return msg


def apply_calibration_msg(stream: ActivityStream, msg: SegmentCalibrationArray,
                          segment: str) -> tuple[str, str]:
    """Hand the trunk forward axis of ``segment``'s calibration entry to the stream; (level, log line).

    The entry's rotation maps segment axes into sensor axes, so the segment's x (anterior) in
    sensor axes is rotate(r, x). It is in force from the message's stamp, like every calibration.
    """
    rotations, _ = calibration_rotations(msg)
    if segment not in rotations:
        return "info", f"calibration has no valid {segment} entry: the current forward axis is kept"
    forward = rotate(rotations[segment], np.array([1.0, 0.0, 0.0]))
    try:
        stream.set_forward_axis(forward, stamp_to_s(msg.header.stamp))
    except ValueError as exc:
        return "warn", f"{segment} calibration not used for the forward axis: {exc}"
    return "info", f"{segment} forward axis from the calibration: {np.round(forward, 3).tolist()} (sensor)"


def chest_sample(imu: Stamped) -> tuple[float, tuple[float, float, float]]:
    """(stamp s, acceleration) of a decoded raw chest Imu message: all the monitor uses."""
    return imu.ns / 1_000_000_000, imu.values[LINEAR_ACCELERATION]


class ActivityMonitorNode(Node):
    """Chest activity monitor (see module docstring)."""

    def __init__(self, context: Context | None = None, **overrides: object) -> None:
        super().__init__("activity_monitor", context=context,
                         parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
        self.segment = self.declare_parameter("segment", "chest").value
        self.rate_hz = float(self.declare_parameter("rate_hz", 100.0).value)
        self.options = {
            "units": self.declare_parameter("units", "m/s2").value,
            "reference_s": float(self.declare_parameter("reference_s", 2.0).value),
            "thigh_length_m": float(self.declare_parameter("thigh_length", 0.42).value),
            "initial_posture": self.declare_parameter("initial_posture", "standing").value,
            "forward_axis": list(self.declare_parameter("forward_axis", [1.0, 0.0, 0.0]).value),
        }
        self.max_gap = float(self.declare_parameter("max_gap", 0.5).value)
        self.stream = ActivityStream(self.rate_hz, max_gap=self.max_gap, **self.options)
        self._newest_t = 0.0
        self.published = 0
        self._pub = self.create_publisher(ActivityState, "activity/state", RELIABLE_QOS)
        self._diagnostics = self.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, RELIABLE_QOS)
        self.create_subscription(Imu, raw_topic(self.segment), self._on_imu, SENSOR_QOS, raw=True)
        self.create_subscription(SegmentCalibrationArray, CALIBRATION_TOPIC, self._on_calibration,
                                 LATCHED_QOS)
        self.create_timer(float(self.declare_parameter("publish_period", 1.0).value), self._periodic)

    @property
    def counts(self) -> dict[str, int]:
        """Input counters of the stream plus states published."""
        return {**self.stream.counts, "published": self.published}

    def _on_calibration(self, msg: SegmentCalibrationArray) -> None:
        level, text = apply_calibration_msg(self.stream, msg, self.segment)
        (self.get_logger().warning if level == "warn" else self.get_logger().info)(text)

    def _on_imu(self, data: bytes) -> None:
        t, acc = chest_sample(decode_imu(data))
        state, changed, warning = self.stream.update(t, acc)
        if warning:
            self.get_logger().warning(f"{self.segment}: {warning}")
        self._newest_t = t
        if changed:
            self._publish(state)

    def _publish(self, state: CoreActivityState) -> None:
        self._pub.publish(to_message(state, self._newest_t, self.segment))
        self.published += 1

    def _periodic(self) -> None:
        latest = self.stream.latest
        if latest is not None:
            self._publish(latest)
        level = DiagnosticStatus.OK if latest is not None else DiagnosticStatus.WARN
        message = "monitoring" if latest is not None else "waiting for chest data"
        self._diagnostics.publish(diagnostic_array(self, [diagnostic_status(
            "activity_monitor", level, message, f"{self.segment}_imu", self.counts)]))


def main(args: list[str] | None = None) -> int:
    """Console script."""
    from gait_biofeedback.nodes.common import run_nodes

    return run_nodes([ActivityMonitorNode], args)


if __name__ == "__main__":
    import sys

    sys.exit(main())
