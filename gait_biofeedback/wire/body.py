"""The body's frames (:mod:`~gait_biofeedback.core.joints.body_pose`) from the graph's own messages, as
they pass: what the recorder writes as ``/tf`` and the Foxglove view serves.

From ``joint_states`` (the angles), the pelvis' and the chest's ``imu/data`` (their sensor→world
orientations) and ``calibration/sensor_to_segment`` (r of each segment, ``q_segment = q_sensor ⊗ r``,
in force from its stamp): one pose of the 8 frames per ``joint_states`` message, at its stamp, the
pelvis taken at that same stamp (the joint-angle stream turns every sensor into the pelvis sensor's
heading, so its raw orientation is the legs' reference). Messages are CDR bytes; anything that does
not decode is counted in :attr:`BodyFrameTracker.refused`, never raised.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState

from gait_biofeedback.core.body import BodyDimensions
from gait_biofeedback.core.joints.body_pose import body_transforms_at
from gait_biofeedback.wire import topics
from gait_biofeedback.wire.calibration import rotations
from gait_biofeedback.wire.cdr import ORIENTATION, decode_imu, unpack_imu
from gait_biofeedback.wire.joints import angles_of, joint_state_of
from gait_biofeedback_msgs.msg import SegmentCalibrationArray

KEPT_STAMPS = 512
"""Pelvis orientations kept to meet their joint states (5 s at 100 Hz; the angles lag by < max_wait_s)."""
KEPT_CALIBRATIONS = 8


class BodyPose(NamedTuple):
    """One instant's frames (:data:`~gait_biofeedback.core.joints.body_pose.BODY_FRAMES` order): stamp
    ns, translations (x, y, z), rotations (w, x, y, z), present flags."""

    ns: int
    trans: list[tuple[float, float, float]]
    rot: list[tuple[float, float, float, float]]
    present: list[bool]


INPUTS = (topics.JOINT_STATES, topics.CALIBRATION, topics.orientation("pelvis"), topics.orientation("chest"))
"""The topics the tracker reads."""


class BodyFrameTracker:
    """Feed it the messages of :data:`INPUTS` (:meth:`feed`); each joint state gives a pose.
    ``resolve``: a topic's name as the graph has it (a node's ``resolve_topic_name``: its namespace);
    default: the absolute form of recordings."""

    def __init__(self, body: BodyDimensions | None = None,
                 resolve: Callable[[str], str] | None = None) -> None:
        self.body = body or BodyDimensions()
        names = [resolve(t.name) if resolve is not None else t.absolute() for t in INPUTS]
        self.joint_states, self.calibration, self.pelvis, self.chest = names
        self.topics = frozenset(names)
        self._pelvis: OrderedDict[int, tuple[float, float, float, float]] = OrderedDict()
        self._chest: tuple[float, float, float, float] | None = None
        self._calibrations: list[tuple[int, dict[str, np.ndarray]]] = []  # (from ns, segment → r)
        self.refused: dict[str, int] = {}
        self.poses = 0
        self.angles: tuple[int, dict[str, float]] = (0, {})
        """The last joint states read: (stamp ns, name → rad)."""

    def feed(self, topic: str, data: bytes) -> BodyPose | None:
        """One message of ``topic`` (CDR bytes); the pose it completes, if any."""
        try:
            if topic == self.joint_states:
                return self._joint_states(data)
            if topic == self.pelvis:
                ns, q = _orientation(data)
                self._pelvis[ns] = q
                while len(self._pelvis) > KEPT_STAMPS:
                    self._pelvis.popitem(last=False)
            elif topic == self.chest:
                self._chest = _orientation(data)[1]
            elif topic == self.calibration:
                self._calibration(data)
        except Exception:  # a message that does not decode: counted, the stream goes on
            self.refused[topic] = self.refused.get(topic, 0) + 1
        return None

    def _calibration(self, data: bytes) -> None:
        found, from_ns = rotations(deserialize_message(data, SegmentCalibrationArray))
        if from_ns <= 0:
            self._calibrations.clear()
        self._calibrations.append((max(from_ns, 0), found))
        self._calibrations.sort(key=lambda c: c[0])
        del self._calibrations[:-KEPT_CALIBRATIONS]

    def rotations_at(self, ns: int) -> dict[str, np.ndarray]:
        """The calibration in force at stamp ``ns`` (empty before any)."""
        found: dict[str, np.ndarray] = {}
        for from_ns, rot in self._calibrations:
            if from_ns <= ns:
                found = rot
        return found

    def _joint_states(self, data: bytes) -> BodyPose | None:
        parsed = joint_state_of(data)
        if parsed is None:
            ns, angles = angles_of(deserialize_message(data, JointState))
        else:
            ns, angles, _ = parsed
        self.angles = (ns, angles)
        r = self.rotations_at(ns)
        pelvis = self._pelvis.get(ns) or (next(reversed(self._pelvis.values())) if self._pelvis else None)
        if pelvis is None or "pelvis" not in r:
            return None
        chest = _mul(self._chest, r["chest"]) if self._chest is not None and "chest" in r else None
        self.poses += 1
        return BodyPose(ns, *body_transforms_at(_mul(pelvis, r["pelvis"]), angles, chest, self.body))


def _mul(q: tuple[float, float, float, float], r: np.ndarray) -> tuple[float, float, float, float]:
    """``q ⊗ r`` (a sensor's orientation and its calibration: the segment's) in floats."""
    w, x, y, z = q
    rw, rx, ry, rz = r.tolist()
    return (w * rw - x * rx - y * ry - z * rz, w * rx + x * rw + y * rz - z * ry,
            w * ry - x * rz + y * rw + z * rx, w * rz + x * ry - y * rx + z * rw)


def _orientation(data: bytes) -> tuple[int, tuple[float, float, float, float]]:
    """(stamp ns, sensor→world w, x, y, z) of a filtered ``imu/data`` message."""
    imu = unpack_imu(data) or decode_imu(data)
    x, y, z, w = imu.values[ORIENTATION]
    return imu.ns, (w, x, y, z)
