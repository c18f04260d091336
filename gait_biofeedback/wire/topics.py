"""Every topic and service of the graph: name, message type and QoS, once (``docs/conventions.md``).

Names are relative (``-r __ns:=/patient1`` namespaces a whole session) except ``/diagnostics``
and ``/clock``; recordings store the absolute form (:meth:`Topic.absolute`).
"""

from __future__ import annotations

from dataclasses import dataclass

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, JointState, MagneticField
from visualization_msgs.msg import MarkerArray

from gait_biofeedback_msgs.msg import (
    ActivityState,
    BiofeedbackCue,
    GaitCycle,
    GaitEvent,
    SegmentCalibrationArray,
    StrideSpace,
)

SENSOR_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100, reliability=ReliabilityPolicy.BEST_EFFORT,
                        durability=DurabilityPolicy.VOLATILE)
"""Raw sensor streams (``docs/conventions.md``, Topics: best effort, depth 100)."""

RELIABLE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)
"""Derived streams: orientations, joint states, events, cues. Depth 1000, not the 100 first designed: the
orientation filter releases its start-up window (1 s) and the re-acquisition window after a gap
(``recover_s``, 2 s: 400 samples at 200 Hz, 800 at 400 Hz) in one burst, and a KEEP_LAST history
shallower than the burst drops its first samples."""

LATCHED_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""State a late subscriber must still get: the calibration in force."""


@dataclass(frozen=True)
class Topic:
    """One topic: ``name`` (relative unless it starts with ``/``), message class, QoS."""

    name: str
    msg_type: type
    qos: QoSProfile

    @property
    def type_name(self) -> str:
        """``package/msg/Type``, as recordings and ``ros2 topic`` name it."""
        return f"{self.msg_type.__module__.split('.')[0]}/msg/{self.msg_type.__name__}"

    def absolute(self) -> str:
        """The name in a recording of a graph in the root namespace."""
        return self.name if self.name.startswith("/") else f"/{self.name}"


def raw_imu(segment: str) -> Topic:
    """``<segment>/imu/data_raw``: the driver's or replayer's IMU samples (no orientation)."""
    return Topic(f"{segment}/imu/data_raw", Imu, SENSOR_QOS)


def magnetometer(segment: str) -> Topic:
    """``<segment>/imu/mag``: the magnetometer, at its own rate."""
    return Topic(f"{segment}/imu/mag", MagneticField, SENSOR_QOS)


def orientation(segment: str) -> Topic:
    """``<segment>/imu/data``: the filtered IMU stream with orientation and bias-corrected rate."""
    return Topic(f"{segment}/imu/data", Imu, RELIABLE_QOS)


def segment_of(topic: str) -> str | None:
    """The segment of an IMU topic name (raw, magnetometer or orientation, any namespace), else None."""
    parts = topic.rstrip("/").split("/")
    if len(parts) >= 3 and parts[-2] == "imu" and parts[-1] in ("data_raw", "mag", "data") and parts[-3]:
        return parts[-3]
    return None


def qos_of_recorded(name: str) -> QoSProfile:
    """The QoS to republish a recorded topic with: sensor QoS for raw IMU and magnetometer streams,
    reliable for everything else."""
    segment = segment_of(name)
    sensor = segment is not None and name.endswith((raw_imu(segment).name, magnetometer(segment).name))
    return SENSOR_QOS if sensor else RELIABLE_QOS


CALIBRATION = Topic("calibration/sensor_to_segment", SegmentCalibrationArray, LATCHED_QOS)
JOINT_STATES = Topic("joint_states", JointState, RELIABLE_QOS)
SKELETON = Topic("skeleton", MarkerArray, RELIABLE_QOS)
GAIT_EVENTS = Topic("gait/events", GaitEvent, RELIABLE_QOS)
GAIT_CYCLES = Topic("gait/cycles", GaitCycle, RELIABLE_QOS)
STRIDE_SPACE = Topic("gait/stride_space", StrideSpace, RELIABLE_QOS)  # smoothed after provisional values
ACTIVITY = Topic("activity/state", ActivityState, RELIABLE_QOS)
CUES = Topic("biofeedback/cues", BiofeedbackCue, RELIABLE_QOS)
DIAGNOSTICS = Topic("/diagnostics", DiagnosticArray, RELIABLE_QOS)

CALIBRATE_SERVICE = "calibration/calibrate"  # gait_biofeedback_msgs/srv/Calibrate
RECORDER_START_SERVICE = "recorder/start"  # std_srvs/srv/Trigger
RECORDER_STOP_SERVICE = "recorder/stop"  # std_srvs/srv/Trigger

TRUTH_PREFIX = "/ground_truth"
"""Simulated recordings carry their exact truth under this prefix (the graph never subscribes)."""


def truth(topic: Topic) -> str:
    """The ground-truth twin of a derived topic, e.g. ``/ground_truth/joint_states``."""
    return TRUTH_PREFIX + topic.absolute()


def recorded_imu_topics(types: dict[str, str]) -> tuple[dict[str, str], dict[str, str]]:
    """(segment → raw Imu topic, segment → MagneticField topic) among a recording's ``types``
    (topic → type name): the ``<segment>/imu/data_raw`` topics, in any namespace, and the
    ``<segment>/imu/mag`` beside each."""
    imu_type, mag_type = raw_imu("x").type_name, magnetometer("x").type_name
    imu = {segment_of(topic): topic for topic, type_name in types.items()
           if type_name == imu_type and topic.endswith("/imu/data_raw") and segment_of(topic)}
    mag = {seg: topic[: -len("data_raw")] + "mag" for seg, topic in imu.items()}
    return imu, {seg: t for seg, t in mag.items() if types.get(t) == mag_type}
