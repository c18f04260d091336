"""Node ``joint_angles``: calibrated segment orientations → ISB joint angles and a stick figure.

Subscribes ``<segment>/imu/data`` of the pelvis and both legs and ``calibration/sensor_to_segment``
(latched; in force from its header stamp, 0 = at once). Synchronisation, calibration switching and
offset removal are :class:`~gait_biofeedback.core.joints.stream.JointAngleStream`: samples are
synchronised by exact header stamp (the IMUs are sampled together); a stamp is published when every
calibrated segment has it, when a newer stamp is complete, or ``max_wait_s`` s after its first sample
arrived; then with the joints whose two segments are present (the missing segments are counted and
named on /diagnostics). Until a calibration is in force nothing is published (WARN "not calibrated:
run calibration"). Standing offset (gait.md §1.9): with ``remove_standing_offset``, the mean of the
first ``offset_window_s`` s after calibration during which every segment is still (|ω| <
``still_gyro`` rad/s) is subtracted from then on.

Publishes ``joint_states`` (sensor_msgs/JointState, names from JOINT_NAMES, rad, stamp = sample stamp)
(marked in ``header.frame_id`` while a segment recovers from a dropout; serialized by
:func:`~gait_biofeedback.wire.joints.joint_state_bytes`, the bytes ``analyze`` writes)
and ``skeleton`` (visualization_msgs/MarkerArray, one LINE_LIST in frame "world", pelvis at the origin,
every ``skeleton_every`` samples), drawn with the body dimensions. Parameters:
:class:`~gait_biofeedback.core.joints.stream.JointAnglesParams`.
"""

from __future__ import annotations

import time

from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.context import Context

from gait_biofeedback.core.joints.alignment import said as stamps_off
from gait_biofeedback.core.joints.angles import JointAngleCalculator
from gait_biofeedback.core.joints.stream import (
    STREAM_SEGMENTS,
    JointAnglesParams,
    JointAngleStream,
    SyncedAngles,
)
from gait_biofeedback.nodes.common import GuardedNode, publisher, subscribe
from gait_biofeedback.nodes.parameters import declare_parameters, node_overrides
from gait_biofeedback.wire import diagnostics, topics
from gait_biofeedback.wire.calibration import rotations
from gait_biofeedback.wire.cdr import decode_imu
from gait_biofeedback.wire.imu import has_heading, is_recovering, orientation_sample
from gait_biofeedback.wire.joints import joint_state_bytes, skeleton_msg
from gait_biofeedback_msgs.msg import SegmentCalibrationArray


class JointAnglesNode(GuardedNode):
    """Joint angles and stick figure (see module docstring)."""

    NODE_NAME = "joint_angles"

    def __init__(self, context: Context | None = None, params: JointAnglesParams | None = None,
                 **overrides: object) -> None:
        super().__init__(self.NODE_NAME, context=context, parameter_overrides=node_overrides(overrides))
        self.params: JointAnglesParams = declare_parameters(self, JointAnglesParams, params)
        self.body = self.params.body
        self.stream = JointAngleStream(self.params)
        self.published = 0
        self._reported_missing: dict[str, int] = {}  # missing_counts at the last /diagnostics
        for seg in STREAM_SEGMENTS:
            subscribe(self, topics.orientation(seg), lambda m, s=seg: self._on_imu(s, m), raw=True)
        subscribe(self, topics.CALIBRATION, self._on_calibration)
        self._joints = publisher(self, topics.JOINT_STATES)
        self._skeleton = publisher(self, topics.SKELETON)
        self.create_timer(max(self.params.max_wait_s / 2, 0.01), self._flush)
        self.create_timer(self.params.diagnostics_period_s, self._publish_diagnostics)

    @property
    def calculator(self) -> JointAngleCalculator | None:
        """The calculator of the calibration in force (None until one is)."""
        return self.stream.calculator

    @property
    def missing_counts(self) -> dict[str, int]:
        """Emitted stamps that lacked each segment."""
        return self.stream.missing_counts

    def _on_calibration(self, msg: SegmentCalibrationArray) -> None:
        valid, from_ns = rotations(msg)
        self.stream.set_calibration(valid, from_ns)
        when = f"from stamp {from_ns * 1e-9:.3f} s" if from_ns > 0 else "now"
        self.get_logger().info(f"calibration in force {when} ({msg.protocol}): {sorted(valid)}")

    def _on_imu(self, segment: str, data: bytes) -> None:
        imu = decode_imu(data)
        ns, acc, gyr, q = orientation_sample(imu)
        self._publish(self.stream.add(segment, ns, q, gyr, acc, time.monotonic(), is_recovering(imu),
                                      has_heading(imu), self.get_clock().now().nanoseconds))

    def _flush(self) -> None:
        self._publish(self.stream.flush(time.monotonic()))

    def _publish(self, emitted: list[SyncedAngles]) -> None:
        for synced in emitted:
            if synced.angles:
                self._joints.publish(joint_state_bytes(synced.angles, synced.ns, synced.recovering))
            self.published += 1
            every = self.params.skeleton_every
            if every > 0 and self.published % every == 0:
                self._skeleton.publish(skeleton_msg(synced, self.body))

    def _publish_diagnostics(self) -> None:
        if self.calculator is None:
            status = diagnostics.status("joint_angles", DiagnosticStatus.WARN,
                                        "not calibrated: run calibration")
        else:
            missing = [s for s, n in self.missing_counts.items() if n > self._reported_missing.get(s, 0)]
            self._reported_missing = dict(self.missing_counts)
            waiting, heading_values = self.stream.heading_status()
            level, text = DiagnosticStatus.OK, "publishing"
            off = self.stream.alignment.misaligned_now(self.get_clock().now().nanoseconds)
            said = [stamps_off(s, o) for s, o in off.items()]
            if missing:
                said.append("missing samples from " + ", ".join(missing) + " since the last report: their "
                            "joints were skipped")
            if said:
                level, text = DiagnosticStatus.WARN, "; ".join(said)
            elif waiting:
                level = DiagnosticStatus.WARN
                text = (f"no angles yet for {', '.join(w.replace('_', ' ') for w in waiting)}: their two "
                        "sensors have no common heading yet (walk a few steps)")
            elif self.calculator.offset_pending:
                text = f"publishing; standing offset pending: stand still {self.params.offset_window_s:g} s"
            values = {f"missing_{s}": n for s, n in self.missing_counts.items()} | heading_values
            values["published"] = self.published
            values["recovering_instants"] = self.stream.recovering_count
            status = diagnostics.status("joint_angles", level, text, values=values)
        self.publish_diagnostics([status])


def main(args: list[str] | None = None) -> int:
    """Console script."""
    from gait_biofeedback.nodes.common import run_nodes

    return run_nodes([JointAnglesNode], args)


if __name__ == "__main__":
    import sys

    sys.exit(main())
