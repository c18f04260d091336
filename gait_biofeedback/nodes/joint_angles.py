"""Node ``joint_angles``: calibrated segment orientations → ISB joint angles and a stick figure.

Subscribes ``<segment>/imu/data`` of the pelvis and both legs and ``calibration/sensor_to_segment``
(latched; in force from its header stamp, 0 = at once). Synchronisation, calibration switching and
offset removal are :class:`~gait_biofeedback.core.joint_angles.JointAngleStream`: samples are
synchronised by exact header stamp (the IMUs are sampled together); a stamp is published when every
calibrated segment has it, when a newer stamp is complete, or ``max_wait`` s after its first sample
arrived; then with the joints whose two segments are present (the missing segments are counted and
named on /diagnostics). Until a calibration is in force nothing is published (WARN "not calibrated:
run calibration"). Standing offset (gait.md §1.9): with ``remove_standing_offset``, the mean of the
first ``offset_window_s`` s after calibration during which every segment is still (|ω| <
``still_gyro`` rad/s) is subtracted from then on.

Publishes ``joint_states`` (sensor_msgs/JointState, names from JOINT_NAMES, rad, stamp = sample stamp)
and ``skeleton`` (visualization_msgs/MarkerArray, one LINE_LIST in frame "world", pelvis at the origin,
every ``skeleton_every`` samples). Segment lengths: ``thigh_length``, ``shank_length``, ``hip_width``,
``foot_length``, ``ankle_height`` (m).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Point
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu, JointState
from visualization_msgs.msg import Marker, MarkerArray

from gait_biofeedback.core.joint_angles import (
    STREAM_SEGMENTS,
    JointAngleCalculator,
    JointAngleStream,
    SyncedAngles,
    segment_orientations,
)
from gait_biofeedback.core.segments import WORLD_FRAME, orientation_topic
from gait_biofeedback.core.skeleton import SegmentLengths, stick_figure
from gait_biofeedback.io.cdr import ANGULAR_VELOCITY, Stamped, decode_imu
from gait_biofeedback.nodes.common import (
    CALIBRATION_TOPIC,
    DIAGNOSTICS_TOPIC,
    LATCHED_QOS,
    RELIABLE_QOS,
    diagnostic_array,
    diagnostic_status,
    ns_to_stamp,
    stamp_to_ns,
)
from gait_biofeedback_msgs.msg import SegmentCalibrationArray

JOINT_SEGMENTS = STREAM_SEGMENTS


def calibration_rotations(msg: SegmentCalibrationArray) -> tuple[dict[str, np.ndarray], int]:
    """(segment → r of the valid segments, stamp ns from which it is in force) of a calibration message."""
    rotations = {m.segment: np.array([m.rotation.w, m.rotation.x, m.rotation.y, m.rotation.z])
                 for m in msg.segments if m.valid}
    return rotations, stamp_to_ns(msg.header.stamp)


def imu_to_joint_sample(imu: Stamped) -> tuple[int, np.ndarray, float]:
    """(stamp ns, sensor→world q, |ω| rad/s) of a decoded ``<segment>/imu/data`` message."""
    v = imu.values
    return imu.ns, np.array((v[3], v[0], v[1], v[2])), math.hypot(*v[ANGULAR_VELOCITY])


def joint_state_msg(synced: SyncedAngles) -> JointState:
    """``joint_states`` message of one emitted instant (names from JOINT_NAMES, rad)."""
    msg = JointState(name=list(synced.angles), position=[float(v) for v in synced.angles.values()])
    msg.header.stamp = ns_to_stamp(synced.ns)
    return msg


def skeleton_msg(synced: SyncedAngles, lengths: SegmentLengths) -> MarkerArray:
    """``skeleton`` stick figure (one LINE_LIST in "world", pelvis at the origin) of one instant."""
    m = Marker(ns="skeleton", id=0, type=Marker.LINE_LIST, action=Marker.ADD)
    m.header.stamp = ns_to_stamp(synced.ns)
    m.header.frame_id = WORLD_FRAME
    m.pose.orientation.w = 1.0
    m.scale.x = 0.02
    m.color.r, m.color.g, m.color.b, m.color.a = 0.1, 0.6, 1.0, 1.0
    orientations = segment_orientations(synced.sensor_quats, synced.rotations)
    for _seg, a, b in stick_figure(orientations, lengths):
        m.points.append(Point(x=float(a[0]), y=float(a[1]), z=float(a[2])))
        m.points.append(Point(x=float(b[0]), y=float(b[1]), z=float(b[2])))
    return MarkerArray(markers=[m])


def segment_lengths(get: Callable[[str, float], float]) -> SegmentLengths:
    """Stick-figure lengths from parameters (``get(name, default)``)."""
    return SegmentLengths(thigh=float(get("thigh_length", 0.43)), shank=float(get("shank_length", 0.43)),
                          hip_width=float(get("hip_width", 0.18)), foot=float(get("foot_length", 0.14)),
                          ankle_height=float(get("ankle_height", 0.08)))


class JointAnglesNode(Node):
    """Joint angles and stick figure (see module docstring)."""

    def __init__(self, context: Context | None = None, **overrides: object) -> None:
        super().__init__("joint_angles", context=context,
                         parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
        p = self.declare_parameter
        self.max_wait = float(p("max_wait", 0.1).value)
        self.remove_offset = bool(p("remove_standing_offset", True).value)
        self.offset_window_s = float(p("offset_window_s", 2.0).value)
        self.still_gyro = float(p("still_gyro", 0.2).value)
        self.skeleton_every = int(p("skeleton_every", 5).value)
        self.lengths = segment_lengths(lambda name, default: p(name, default).value)
        self.stream = JointAngleStream(JOINT_SEGMENTS, self.max_wait, self.remove_offset,
                                       self.offset_window_s, self.still_gyro)
        self.published = 0
        for seg in JOINT_SEGMENTS:
            self.create_subscription(Imu, orientation_topic(seg), lambda m, s=seg: self._on_imu(s, m),
                                     RELIABLE_QOS, raw=True)
        self.create_subscription(SegmentCalibrationArray, CALIBRATION_TOPIC,
                                 self._on_calibration, LATCHED_QOS)
        self._joints = self.create_publisher(JointState, "joint_states", RELIABLE_QOS)
        self._skeleton = self.create_publisher(MarkerArray, "skeleton", RELIABLE_QOS)
        self._diagnostics = self.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, RELIABLE_QOS)
        self.create_timer(max(self.max_wait / 2, 0.01), self._flush)
        self.create_timer(float(p("diagnostics_period", 1.0).value), self._publish_diagnostics)

    @property
    def calculator(self) -> JointAngleCalculator | None:
        """The calculator of the calibration in force (None until one is)."""
        return self.stream.calculator

    @property
    def missing_counts(self) -> dict[str, int]:
        """Emitted stamps that lacked each segment."""
        return self.stream.missing_counts

    def _on_calibration(self, msg: SegmentCalibrationArray) -> None:
        rotations, from_ns = calibration_rotations(msg)
        self.stream.set_calibration(rotations, from_ns)
        when = f"from stamp {from_ns * 1e-9:.3f} s" if from_ns > 0 else "now"
        self.get_logger().info(f"calibration in force {when} ({msg.protocol}): {sorted(rotations)}")

    def _on_imu(self, segment: str, data: bytes) -> None:
        ns, q, gyro_norm = imu_to_joint_sample(decode_imu(data))
        self._publish(self.stream.add(segment, ns, q, gyro_norm, time.monotonic()))

    def _flush(self) -> None:
        self._publish(self.stream.flush(time.monotonic()))

    def _publish(self, emitted: list[SyncedAngles]) -> None:
        for synced in emitted:
            if synced.angles:
                self._joints.publish(joint_state_msg(synced))
            self.published += 1
            if self.skeleton_every > 0 and self.published % self.skeleton_every == 0:
                self._skeleton.publish(skeleton_msg(synced, self.lengths))

    def _publish_diagnostics(self) -> None:
        if self.calculator is None:
            status = diagnostic_status("joint_angles", DiagnosticStatus.WARN,
                                       "not calibrated: run calibration")
        else:
            missing = {s: n for s, n in self.missing_counts.items() if n}
            level, text = DiagnosticStatus.OK, "publishing"
            if missing:
                level = DiagnosticStatus.WARN
                text = "missing samples from " + ", ".join(missing) + ": their joints were skipped"
            elif self.calculator.offset_pending:
                text = f"publishing; standing offset pending: stand still {self.offset_window_s:g} s"
            values = {f"missing_{s}": n for s, n in self.missing_counts.items()}
            values["published"] = self.published
            status = diagnostic_status("joint_angles", level, text, values=values)
        self._diagnostics.publish(diagnostic_array(self, [status]))


def main(args: list[str] | None = None) -> int:
    """Console script."""
    from gait_biofeedback.nodes.common import run_nodes

    return run_nodes([JointAnglesNode], args)


if __name__ == "__main__":
    import sys

    sys.exit(main())
