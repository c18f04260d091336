"""CPU time per message of encoding ``joint_states`` and ``<segment>/imu/data``, as the nodes publish them
and as ``analyze`` writes them (issue 46).

``PYTHONPATH=TREE .venv/bin/python benchmarks/encoding.py [DOMAIN_ID]``: the code of TREE, this checkout
or an exported revision (995e248's API is recognised: ``orientation_payload``, the JointState message).
Each figure is the best of 60 runs of 5000 messages in process CPU time (other processes' load does not
count). The publishers have no subscriber: their cost is the encoding, rclpy and the middleware's write.
"""

from __future__ import annotations

import sys
import time
import timeit
from collections.abc import Callable

import numpy as np
import rclpy
from rclpy.context import Context
from sensor_msgs.msg import Imu, JointState

from gait_biofeedback.core.orientation.stream import OrientationSample
from gait_biofeedback.wire import cdr
from gait_biofeedback.wire import imu as wire_imu
from gait_biofeedback.wire import joints as wire_joints

N, REPEAT = 5000, 60
NAMES = [f"{side}_{j}" for side in ("left", "right") for j in (
    "hip_flexion", "hip_adduction", "hip_internal_rotation", "knee_flexion", "knee_adduction",
    "knee_internal_rotation", "ankle_dorsiflexion", "ankle_inversion", "ankle_internal_rotation")]
STAMP = 1_700_000_000_123_456_789


def best(stmt: Callable[[], object]) -> float:
    """µs of CPU time per call, best of REPEAT."""
    return min(timeit.repeat(stmt, number=N, repeat=REPEAT, timer=time.process_time)) / N * 1e6


def main() -> None:
    rng = np.random.default_rng(1)
    angles = {n: float(v) for n, v in zip(NAMES, rng.normal(size=len(NAMES)), strict=True)}
    raw = cdr.decode_imu(cdr.pack_imu(STAMP, "left_foot_imu", wire_imu.raw_imu_values((0.1, 0.2, 0.3),
                                                                                       (0.0, 0.0, 9.81))))
    q = rng.normal(size=4)
    sample = OrientationSample(STAMP, q / np.linalg.norm(q), rng.normal(size=3), rng.normal(size=3),
                               recovering=False, heading=True)
    if hasattr(wire_imu, "orientation_payload"):  # 995e248: the node built an rclpy JointState

        def node_joints() -> object:
            return wire_joints.joint_state_msg(angles, STAMP, ())

        def node_orientation() -> bytes:
            return wire_imu.orientation_payload("left_foot", sample, raw, 0.01)

        def pass_orientation() -> tuple:
            return wire_imu.orientation_message("left_foot", sample, raw, 0.01)
    else:

        def node_joints() -> object:
            return wire_joints.joint_state_bytes(angles, STAMP, ())

        def node_orientation() -> bytes:
            return cdr.pack_imu(*wire_imu.orientation_fields("left_foot", sample, raw, 0.01))

        def pass_orientation() -> tuple:
            fields = wire_imu.orientation_fields("left_foot", sample, raw, 0.01)
            return cdr.pack_imu(*fields), cdr.Stamped(*fields)

    context = Context()
    rclpy.init(context=context, domain_id=int(sys.argv[1]) if len(sys.argv) > 1 else 77)
    node = rclpy.create_node("benchmark_encoding", context=context)
    joints_out = node.create_publisher(JointState, "benchmark_joint_states", 10)
    imu_out = node.create_publisher(Imu, "benchmark_imu", 10)
    try:
        figures = {
            "joint_angles node: encode joint_states": best(node_joints),
            "joint_angles node: publish(encoded)": best(lambda: joints_out.publish(node_joints())),
            "analyze: joint_state_bytes": best(lambda: wire_joints.joint_state_bytes(angles, STAMP)),
            "joint_state_msg (sim truth, tests)": best(lambda: wire_joints.joint_state_msg(angles, STAMP)),
            "orientation_filter node: encode imu/data": best(node_orientation),
            "orientation_filter node: publish(encoded)": best(lambda: imu_out.publish(node_orientation())),
            "analyze: imu/data (bytes, Stamped)": best(pass_orientation),
        }
    finally:
        node.destroy_node()
        rclpy.shutdown(context=context)
    for name, us in figures.items():
        print(f"{name:52s} {us:6.2f} us/message")


if __name__ == "__main__":
    main()
