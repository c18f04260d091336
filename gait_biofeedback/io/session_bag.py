"""A simulated session → a recording: raw IMU topics plus its ground truth on ``/ground_truth/…``.

Ground-truth topics (the graph never subscribes to them; they are there to compare in Foxglove,
in ``gait-biofeedback demo`` and in tests):
- ``/ground_truth/joint_states`` sensor_msgs/JointState, every sample, names as ``joint_states``;
- ``/ground_truth/gait/events`` gait_biofeedback_msgs/GaitEvent at each true IC/TC;
- ``/ground_truth/calibration/sensor_to_segment`` SegmentCalibrationArray, once at the start:
  the true mounting rotations (what a perfect calibration would find).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
from geometry_msgs.msg import Quaternion
from sensor_msgs.msg import JointState

from gait_biofeedback.core.segments import sensor_frame
from gait_biofeedback.io.bag import write_imu_bag
from gait_biofeedback.io.imu_messages import seconds_to_ns
from gait_biofeedback.nodes.common import ns_to_stamp
from gait_biofeedback_msgs.msg import GaitEvent, SegmentCalibration, SegmentCalibrationArray

TRUTH_PREFIX = "/ground_truth"
SIDE_CODES = {"left": GaitEvent.SIDE_LEFT, "right": GaitEvent.SIDE_RIGHT}
EVENT_CODES = {"ic": GaitEvent.INITIAL_CONTACT, "tc": GaitEvent.TERMINAL_CONTACT}


def truth_messages(session) -> Iterator[tuple[str, object, int]]:
    """(topic, message, t_ns) of a SimulatedSession's ground truth, in time order per topic."""
    truth = session.truth
    t_ns = seconds_to_ns(truth.t)  # exactly as the IMU stamps are made, so they pair by stamp

    calib = SegmentCalibrationArray(protocol="ground_truth")
    calib.header.stamp = ns_to_stamp(int(t_ns[0]))
    calib.header.frame_id = "world"
    for segment, q in truth.mounting.items():
        w, x, y, z = (float(v) for v in q)
        calib.segments.append(SegmentCalibration(
            segment=segment, sensor_frame=sensor_frame(segment), rotation=Quaternion(w=w, x=x, y=y, z=z),
            valid=True, quality=1.0, quality_metric="ground truth"))
    yield f"{TRUTH_PREFIX}/calibration/sensor_to_segment", calib, int(t_ns[0])

    names = list(truth.joint_angles)
    angles = np.stack([np.asarray(truth.joint_angles[n], dtype=float) for n in names], axis=1)
    for k, tk in enumerate(t_ns):
        msg = JointState(name=names, position=angles[k].tolist())
        msg.header.stamp = ns_to_stamp(int(tk))
        yield f"{TRUTH_PREFIX}/joint_states", msg, int(tk)

    events = []
    for kind, per_side in (("ic", truth.initial_contacts), ("tc", truth.terminal_contacts)):
        for side, times in per_side.items():
            for index, ns in enumerate(seconds_to_ns(np.asarray(times, dtype=float)).tolist()):
                events.append((ns, side, kind, index))
    for ev_ns, side, kind, index in sorted(events):
        msg = GaitEvent(side=SIDE_CODES[side], type=EVENT_CODES[kind], event_index=index)
        msg.header.frame_id = f"{side}_foot"
        msg.header.stamp = ns_to_stamp(ev_ns)
        yield f"{TRUTH_PREFIX}/gait/events", msg, ev_ns


def write_simulated_bag(path: str | Path, session, overwrite: bool = False) -> Path:
    """Write a SimulatedSession (core/simulator.py) as a recording with its ground truth."""
    extra = sorted(truth_messages(session), key=lambda item: item[2])
    return write_imu_bag(path, session.imu, extra=extra, overwrite=overwrite)
