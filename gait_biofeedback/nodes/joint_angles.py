"""Node ``joint_angles``: calibrated segment orientations → ISB joint angles and a stick figure.

Subscribes ``<segment>/imu/data`` of the pelvis and both legs and ``calibration/sensor_to_segment``
(latched). Samples are synchronised by exact header stamp (the IMUs are sampled together): a stamp
is published when every calibrated segment has it, when a newer stamp is complete, or ``max_wait`` s
after its first sample arrived; then with the joints whose two segments are present (the missing
segments are counted and named on /diagnostics). Until a calibration is in force nothing is
published (WARN "not calibrated: run calibration"). Standing offset (gait.md §1.9): with
``remove_standing_offset``, the mean of the first ``offset_window_s`` s after calibration during which
every segment is still (|ω| < ``still_gyro`` rad/s) is subtracted from then on.

Publishes ``joint_states`` (sensor_msgs/JointState, names from JOINT_NAMES, rad, stamp = sample stamp)
and ``skeleton`` (visualization_msgs/MarkerArray, one LINE_LIST in frame "world", pelvis at the origin,
every ``skeleton_every`` samples). Segment lengths: ``thigh_length``, ``shank_length``, ``hip_width``,
``foot_length``, ``ankle_height`` (m).
"""

from __future__ import annotations

import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Point
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu, JointState
from visualization_msgs.msg import Marker, MarkerArray

from gait_biofeedback.core.joint_angles import JointAngleCalculator, segment_orientations
from gait_biofeedback.core.segments import WORLD_FRAME, orientation_topic
from gait_biofeedback.core.skeleton import SegmentLengths, stick_figure
from gait_biofeedback.nodes.common import (
    DIAGNOSTICS_TOPIC,
    LATCHED_QOS,
    RELIABLE_QOS,
    diagnostic_array,
    diagnostic_status,
    ns_to_stamp,
    stamp_to_ns,
)
from gait_biofeedback_msgs.msg import SegmentCalibrationArray

JOINT_SEGMENTS = ("pelvis", "left_thigh", "left_shank", "left_foot", "right_thigh", "right_shank",
                  "right_foot")


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
        self.lengths = SegmentLengths(thigh=float(p("thigh_length", 0.43).value),
                                      shank=float(p("shank_length", 0.43).value),
                                      hip_width=float(p("hip_width", 0.18).value),
                                      foot=float(p("foot_length", 0.14).value),
                                      ankle_height=float(p("ankle_height", 0.08).value))
        self.calculator: JointAngleCalculator | None = None
        self.pending: dict[int, dict[str, tuple[np.ndarray, float]]] = {}
        self.first_arrival: dict[int, float] = {}
        self.missing_counts: dict[str, int] = {s: 0 for s in JOINT_SEGMENTS}
        self.published = 0
        for seg in JOINT_SEGMENTS:
            self.create_subscription(Imu, orientation_topic(seg), lambda m, s=seg: self._on_imu(s, m),
                                     RELIABLE_QOS)
        self.create_subscription(SegmentCalibrationArray, "calibration/sensor_to_segment",
                                 self._on_calibration, LATCHED_QOS)
        self._joints = self.create_publisher(JointState, "joint_states", RELIABLE_QOS)
        self._skeleton = self.create_publisher(MarkerArray, "skeleton", RELIABLE_QOS)
        self._diagnostics = self.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, RELIABLE_QOS)
        self.create_timer(max(self.max_wait / 2, 0.01), self._flush)
        self.create_timer(float(p("diagnostics_period", 1.0).value), self._publish_diagnostics)

    def _on_calibration(self, msg: SegmentCalibrationArray) -> None:
        rotations = {m.segment: np.array([m.rotation.w, m.rotation.x, m.rotation.y, m.rotation.z])
                     for m in msg.segments if m.valid}
        self.calculator = JointAngleCalculator(rotations)
        if self.remove_offset:
            self.calculator.collect_offset(self.offset_window_s)
        self.pending.clear()
        self.first_arrival.clear()
        self.get_logger().info(f"calibration in force ({msg.protocol}): {sorted(rotations)}")

    def _on_imu(self, segment: str, msg: Imu) -> None:
        if self.calculator is None:
            return
        ns = stamp_to_ns(msg.header.stamp)
        o, w = msg.orientation, msg.angular_velocity
        self.pending.setdefault(ns, {})[segment] = (np.array([o.w, o.x, o.y, o.z]),
                                                    float(np.linalg.norm([w.x, w.y, w.z])))
        self.first_arrival.setdefault(ns, time.monotonic())
        self._flush()

    def _flush(self) -> None:
        if self.calculator is None or not self.pending:
            return
        wanted = [s for s in JOINT_SEGMENTS if s in self.calculator.rotations]
        now = time.monotonic()
        stamps = sorted(self.pending)
        complete = [ns for ns in stamps if all(s in self.pending[ns] for s in wanted)]
        newest_complete = complete[-1] if complete else None
        for ns in stamps:
            done = ns in complete or (newest_complete is not None and ns < newest_complete)
            if not (done or now - self.first_arrival[ns] > self.max_wait):
                break
            self._emit(ns, self.pending.pop(ns), wanted)
            self.first_arrival.pop(ns, None)

    def _emit(self, ns: int, samples: dict[str, tuple[np.ndarray, float]], wanted: list[str]) -> None:
        for seg in wanted:
            if seg not in samples:
                self.missing_counts[seg] += 1
        quats = {s: q for s, (q, _) in samples.items()}
        still = all(w < self.still_gyro for _, w in samples.values()) and len(samples) == len(wanted)
        angles = self.calculator.update(ns * 1e-9, quats, still=still)
        if angles:
            msg = JointState(name=list(angles), position=[float(v) for v in angles.values()])
            msg.header.stamp = ns_to_stamp(ns)
            self._joints.publish(msg)
        self.published += 1
        if self.skeleton_every > 0 and self.published % self.skeleton_every == 0:
            self._skeleton.publish(self._markers(ns, segment_orientations(quats, self.calculator.rotations)))

    def _markers(self, ns: int, orientations: dict[str, np.ndarray]) -> MarkerArray:
        m = Marker(ns="skeleton", id=0, type=Marker.LINE_LIST, action=Marker.ADD)
        m.header.stamp = ns_to_stamp(ns)
        m.header.frame_id = WORLD_FRAME
        m.pose.orientation.w = 1.0
        m.scale.x = 0.02
        m.color.r, m.color.g, m.color.b, m.color.a = 0.1, 0.6, 1.0, 1.0
        for _seg, a, b in stick_figure(orientations, self.lengths):
            m.points.append(Point(x=float(a[0]), y=float(a[1]), z=float(a[2])))
            m.points.append(Point(x=float(b[0]), y=float(b[1]), z=float(b[2])))
        return MarkerArray(markers=[m])

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
