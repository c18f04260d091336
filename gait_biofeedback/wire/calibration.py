"""``calibration/sensor_to_segment`` (SegmentCalibrationArray, latched) ↔ the core's calibration.

header.stamp = the sample stamp from which the calibration is in force (0 = at once, e.g. a
calibration reloaded from its file); each entry's rotation is r (segment → sensor,
``q_segment = q_sensor ⊗ r``, thesis Eq 17), a geometry_msgs/Quaternion (w, x, y, z fields).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Quaternion

from gait_biofeedback.core.calibration.sensor_to_segment import SegmentEntry, SessionCalibration
from gait_biofeedback.core.segments import WORLD_FRAME, sensor_frame
from gait_biofeedback.wire.stamps import ns_to_stamp, stamp_to_ns
from gait_biofeedback_msgs.msg import SegmentCalibration, SegmentCalibrationArray


def _quaternion(q: np.ndarray) -> Quaternion:
    w, x, y, z = (float(v) for v in q)
    return Quaternion(w=w, x=x, y=y, z=z)


def segment_messages(cal: SessionCalibration) -> list[SegmentCalibration]:
    """Per-segment messages of a core result (the service reply and the latched message)."""
    return [SegmentCalibration(segment=seg, sensor_frame=sensor_frame(seg), rotation=_quaternion(r.rotation),
                               valid=bool(r.valid), quality=float(r.quality), quality_metric=r.quality_metric,
                               standing_motion=float(r.standing_motion), message=r.message)
            for seg, r in cal.segments.items()]


def calibration_msg(cal: SessionCalibration, applies_from_ns: int, source: str = "",
                    computed_at_ns: int = 0) -> SegmentCalibrationArray:
    """The latched message of a result, in force from stamp ``applies_from_ns`` (0 = at once);
    ``source`` and ``computed_at_ns`` (wall clock) tell the clinician which calibration it is."""
    msg = SegmentCalibrationArray(protocol=cal.protocol, source=source, segments=segment_messages(cal))
    msg.header.stamp = ns_to_stamp(applies_from_ns) if applies_from_ns > 0 else Time()
    msg.header.frame_id = WORLD_FRAME
    msg.computed_at = ns_to_stamp(computed_at_ns)
    return msg


def mounting_msg(mountings: Mapping[str, np.ndarray], stamp_ns: int, protocol: str,
                 quality_metric: str) -> SegmentCalibrationArray:
    """A message of known rotations (every entry valid, quality 1): a simulator's true mountings."""
    msg = SegmentCalibrationArray(protocol=protocol)
    msg.header.stamp, msg.header.frame_id = ns_to_stamp(stamp_ns), WORLD_FRAME
    msg.segments = [SegmentCalibration(segment=seg, sensor_frame=sensor_frame(seg), rotation=_quaternion(q),
                                       valid=True, quality=1.0, quality_metric=quality_metric)
                    for seg, q in mountings.items()]
    return msg


def rotation(entry: SegmentCalibration) -> np.ndarray:
    """r (w, x, y, z) of one entry."""
    r = entry.rotation
    return np.array([r.w, r.x, r.y, r.z])


def rotations(msg: SegmentCalibrationArray) -> tuple[dict[str, np.ndarray], int]:
    """(segment → r of the valid entries, stamp ns from which the message is in force)."""
    return {m.segment: rotation(m) for m in msg.segments if m.valid}, stamp_to_ns(msg.header.stamp)


def entries(msg: SegmentCalibrationArray) -> tuple[dict[str, SegmentEntry], int]:
    """(segment → its entry, valid or not, stamp ns from which the message is in force)."""
    return ({m.segment: SegmentEntry(rotation(m), bool(m.valid), m.message) for m in msg.segments},
            stamp_to_ns(msg.header.stamp))
