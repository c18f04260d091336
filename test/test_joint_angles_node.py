"""joint_angles node: silent (WARN) until calibrated; then joint_states equal to the batch path, a late
segment's joints still published, the missing segment named on /diagnostics (once), a skeleton
published."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import spinning, stamp_s, true_calibration

from gait_biofeedback.core.joints.angles import compute_joint_angles
from gait_biofeedback.sim.simulator import SCENARIOS, simulate

pytestmark = [pytest.mark.ros, pytest.mark.timeout(90)]
SEGMENTS = ["pelvis", "left_thigh", "left_shank", "right_thigh"]


def test_joint_angles_node(ros_context):
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.node import Node
    from sensor_msgs.msg import Imu, JointState
    from visualization_msgs.msg import MarkerArray

    from gait_biofeedback.nodes.common import spin_until
    from gait_biofeedback.nodes.joint_angles import JointAnglesNode
    from gait_biofeedback.wire.calibration import segment_messages
    from gait_biofeedback.wire.stamps import s_to_stamp
    from gait_biofeedback.wire.topics import LATCHED_QOS, RELIABLE_QOS
    from gait_biofeedback_msgs.msg import SegmentCalibrationArray

    session = simulate(SCENARIOS["walk"](duration=4.0, seed=3))
    truth = session.truth
    cal = true_calibration(session, SEGMENTS)
    node = JointAnglesNode(ros_context, remove_standing_offset=False, diagnostics_period_s=0.2,
                           max_wait_s=0.05, heading="filters")  # true orientations: one world already
    source = Node("source", context=ros_context)
    pubs = {s: source.create_publisher(Imu, f"{s}/imu/data", RELIABLE_QOS) for s in SEGMENTS}
    cal_pub = source.create_publisher(SegmentCalibrationArray, "calibration/sensor_to_segment", LATCHED_QOS)
    joints, diags, skeletons = [], [], []
    source.create_subscription(JointState, "joint_states", joints.append, 1000)
    source.create_subscription(DiagnosticArray, "/diagnostics",
                               lambda m: diags.extend(s for s in m.status if s.name == "joint_angles"), 50)
    source.create_subscription(MarkerArray, "skeleton", skeletons.append, 100)

    def send(k, segments):
        for s in segments:
            m = Imu()
            m.header.stamp = s_to_stamp(float(truth.t[k]))
            q = truth.sensor_orientation[s][k]
            m.orientation.w, m.orientation.x, m.orientation.y, m.orientation.z = (float(v) for v in q)
            pubs[s].publish(m)

    with spinning(ros_context, node, source) as executor:
        assert spin_until(executor, lambda: all(p.get_subscription_count() for p in pubs.values()), timeout=5)
        send(0, SEGMENTS)
        assert spin_until(executor, lambda: any("not calibrated" in d.message for d in diags), timeout=5)
        assert joints == []
        cal_pub.publish(SegmentCalibrationArray(protocol="walking", segments=segment_messages(cal)))
        assert spin_until(executor, lambda: node.calculator is not None, timeout=5)
        n = 60
        for k in range(1, n):
            send(k, SEGMENTS if k != 30 else ["pelvis", "left_thigh", "right_thigh"])  # left shank late
            assert spin_until(executor, lambda k=k: len(joints) >= k - 1, timeout=5)
        assert spin_until(executor, lambda: len(joints) == n - 1, timeout=5)
        spin_until(executor, lambda: any("left_shank" in d.message for d in diags), timeout=3)
        said = len(diags)
        # the missing sample is said once (since the last report), not on every status after it
        assert spin_until(executor, lambda: len(diags) > said + 1, timeout=3)
        assert "missing" not in diags[-1].message and diags[-1].level == b"\x00", diags[-1].message
    batch = compute_joint_angles({s: truth.sensor_orientation[s] for s in SEGMENTS}, cal)
    for msg in joints:
        k = round(stamp_s(msg.header.stamp) * 100)
        assert set(msg.name) == ({"left_hip_flexion", "left_hip_adduction", "left_hip_internal_rotation",
                                  "right_hip_flexion", "right_hip_adduction", "right_hip_internal_rotation"}
                                 | (set() if k == 30 else {"left_knee_flexion", "left_knee_adduction",
                                                           "left_knee_internal_rotation"}))
        for name, value in zip(msg.name, msg.position, strict=True):
            assert value == pytest.approx(batch[name][k], abs=1e-9)
    assert node.missing_counts["left_shank"] == 1
    assert any(d.level == b"\x01" and "left_shank" in d.message for d in diags)
    assert skeletons and skeletons[-1].markers[0].header.frame_id == "world"
    assert len(skeletons[-1].markers[0].points) % 2 == 0 and np.isfinite(skeletons[-1].markers[0].points[0].z)
