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

from gait_biofeedback.core.stamps import seconds_to_ns
from gait_biofeedback.io.imu_bag import write_imu_bag
from gait_biofeedback.sim.simulator import SimulatedSession
from gait_biofeedback.wire import topics
from gait_biofeedback.wire.calibration import mounting_msg
from gait_biofeedback.wire.gait import truth_event_msg
from gait_biofeedback.wire.joints import joint_state_msg


def truth_messages(session: SimulatedSession) -> Iterator[tuple[str, object, int]]:
    """(topic, message, t_ns) of a SimulatedSession's ground truth, in time order per topic."""
    truth = session.truth
    t_ns = seconds_to_ns(truth.t)  # exactly as the IMU stamps are made, so they pair by stamp
    yield (topics.truth(topics.CALIBRATION), mounting_msg(truth.mounting, int(t_ns[0]), "ground_truth",
                                                          "ground truth"), int(t_ns[0]))
    names = list(truth.joint_angles)
    angles = np.stack([np.asarray(truth.joint_angles[n], dtype=float) for n in names], axis=1)
    for k, tk in enumerate(t_ns.tolist()):
        msg = joint_state_msg(dict(zip(names, angles[k], strict=True)), tk)
        yield topics.truth(topics.JOINT_STATES), msg, tk
    events = []
    for kind, per_side in (("ic", truth.initial_contacts), ("tc", truth.terminal_contacts)):
        for side, times in per_side.items():
            for index, ns in enumerate(seconds_to_ns(np.asarray(times, dtype=float)).tolist()):
                events.append((ns, side, kind, index))
    for ev_ns, side, kind, index in sorted(events):
        yield topics.truth(topics.GAIT_EVENTS), truth_event_msg(side, kind, ev_ns, index), ev_ns


def write_simulated_bag(path: str | Path, session: SimulatedSession, overwrite: bool = False) -> Path:
    """Write a SimulatedSession (:mod:`gait_biofeedback.sim.simulator`) as a recording with its truth."""
    extra = sorted(truth_messages(session), key=lambda item: item[2])
    return write_imu_bag(path, session.imu, extra=extra, overwrite=overwrite)
