"""Node ``calibration``: the ``calibration/calibrate`` service (thesis ch. 3, ch. 8 step 2).

Keeps a rolling buffer (``buffer_s``, default 90 s) of every segment's ``<segment>/imu/data`` (stamp,
raw acc, bias-corrected gyro, orientation) in a core
:class:`~gait_biofeedback.core.calibration_windows.CalibrationBuffer`. A call looks back over it for
the protocol just performed (:func:`~gait_biofeedback.core.calibration_windows.find_standing_then_motion`:
the last quiet standing of ``standing_duration`` s followed by the motion) and returns at once; the
executor never blocks. :meth:`CalibrationNode.calibrate_at` instead calibrates on the window ending at
a given sample stamp once the data gets there (replays; the offline ``analyze`` does the same).
On success: publishes the result latched on ``calibration/sensor_to_segment`` and writes
``<session_dir>/calibration.yaml``; on start it reloads that file and publishes it. The message's
header.stamp is the sample stamp from which the calibration is in force: ``apply_delay`` s after the
newest sample used (0 for a reloaded file: at once), so joint_angles and gait_events switch at the
same sample whenever the message reaches them within that delay. A refused calibration keeps the
previous one in force and publishes nothing.

Parameters: ``segments`` (default all eight), ``buffer_s``, ``session_dir`` ("session"),
``default_standing_duration`` (3 s), ``apply_delay`` (0.5 s).
"""

from __future__ import annotations

from collections import deque
from pathlib import Path

import yaml
from builtin_interfaces.msg import Time
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu

from gait_biofeedback.core.calibration import SessionCalibration
from gait_biofeedback.core.calibration_windows import CalibrationAttempt, CalibrationBuffer
from gait_biofeedback.core.segments import SEGMENTS, WORLD_FRAME, orientation_topic, sensor_frame
from gait_biofeedback.io.cdr import ANGULAR_VELOCITY, LINEAR_ACCELERATION, Stamped, decode_imu
from gait_biofeedback.nodes.common import CALIBRATION_TOPIC, LATCHED_QOS, RELIABLE_QOS, s_to_stamp
from gait_biofeedback_msgs.msg import SegmentCalibration, SegmentCalibrationArray
from gait_biofeedback_msgs.srv import Calibrate

CALIBRATE_SERVICE = "calibration/calibrate"
CALIBRATION_FILE = "calibration.yaml"


def calibration_to_msg(cal: SessionCalibration) -> list[SegmentCalibration]:
    """Per-segment messages of a core result."""
    out = []
    for seg, r in cal.segments.items():
        m = SegmentCalibration(segment=seg, sensor_frame=sensor_frame(seg), valid=bool(r.valid),
                               quality=float(r.quality), quality_metric=r.quality_metric,
                               standing_motion=float(r.standing_motion), message=r.message)
        m.rotation.w, m.rotation.x, m.rotation.y, m.rotation.z = (float(v) for v in r.rotation)
        out.append(m)
    return out


def calibration_array_msg(cal: SessionCalibration, applies_from: float) -> SegmentCalibrationArray:
    """The latched ``calibration/sensor_to_segment`` message of a result; header.stamp = the sample
    stamp from which it is in force (0 = at once, e.g. a calibration reloaded from its file)."""
    msg = SegmentCalibrationArray(protocol=cal.protocol, segments=calibration_to_msg(cal))
    msg.header.stamp = s_to_stamp(applies_from) if applies_from > 0 else Time()
    msg.header.frame_id = WORLD_FRAME
    return msg


def imu_to_calibration_sample(imu: Stamped) -> tuple[float, tuple, tuple, tuple]:
    """(stamp s, acc, gyro, q) of a decoded ``<segment>/imu/data`` message, as the buffer stores them."""
    v = imu.values
    return imu.ns / 1_000_000_000, v[LINEAR_ACCELERATION], v[ANGULAR_VELOCITY], (v[3], v[0], v[1], v[2])


def load_calibration_file(path: Path) -> SessionCalibration:
    """A ``calibration.yaml`` written by this node (ValueError/KeyError/TypeError/YAMLError if not)."""
    return SessionCalibration.from_dict(yaml.safe_load(Path(path).read_text()))


class CalibrationNode(Node):
    """Sensor-to-segment calibration service (see module docstring)."""

    def __init__(self, context: Context | None = None, **overrides: object) -> None:
        super().__init__("calibration", context=context,
                         parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
        self.segments = [s for s in self.declare_parameter("segments", list(SEGMENTS)).value if s]
        unknown = [s for s in self.segments if s not in SEGMENTS]
        if unknown:
            raise ValueError(f"calibration: unknown segments {unknown}; known: {list(SEGMENTS)}")
        self.buffer_s = float(self.declare_parameter("buffer_s", 90.0).value)
        self.session_dir = Path(str(self.declare_parameter("session_dir", "session").value))
        self.default_standing = float(self.declare_parameter("default_standing_duration", 3.0).value)
        self.core = CalibrationBuffer(self.segments, self.buffer_s, self.default_standing,
                                      apply_delay=float(self.declare_parameter("apply_delay", 0.5).value))
        self.current: SessionCalibration | None = None
        self.last_attempt: CalibrationAttempt | None = None
        for seg in self.segments:
            self.create_subscription(Imu, orientation_topic(seg), lambda m, s=seg: self._on_imu(s, m),
                                     RELIABLE_QOS, raw=True)
        self._pub = self.create_publisher(SegmentCalibrationArray, CALIBRATION_TOPIC, LATCHED_QOS)
        self.create_service(Calibrate, CALIBRATE_SERVICE, self._on_calibrate)
        self._reload()

    @property
    def buffers(self) -> dict[str, deque]:
        """The rolling buffer per segment (held by the core :class:`CalibrationBuffer`)."""
        return self.core.buffers

    @property
    def calibration_file(self) -> Path:
        return self.session_dir / CALIBRATION_FILE

    def _reload(self) -> None:
        if not self.calibration_file.exists():
            return
        try:
            self.current = load_calibration_file(self.calibration_file)
        except (ValueError, KeyError, TypeError, yaml.YAMLError) as exc:
            self.get_logger().error(f"{self.calibration_file}: unreadable calibration ({exc}); "
                                    "run the calibration again")
            return
        self.get_logger().info(f"reloaded the calibration from {self.calibration_file}")
        self._publish(self.current, 0.0)

    def _on_imu(self, segment: str, data: bytes) -> None:
        self.core.add(segment, *imu_to_calibration_sample(decode_imu(data)))
        if self.core.scheduled:
            for attempt in self.core.run_due():
                self._accept(attempt)
                (self.get_logger().info if attempt.success else self.get_logger().warning)(
                    f"scheduled calibration ({attempt.protocol}, data up to {attempt.until:.3f} s): "
                    f"{attempt.message}")

    def _accept(self, attempt: CalibrationAttempt) -> None:
        """Keep, save and publish a successful result (a refused one changes nothing)."""
        self.last_attempt = attempt
        cal = attempt.calibration
        if attempt.success and cal is not None:
            self.current = cal
            self.session_dir.mkdir(parents=True, exist_ok=True)
            self.calibration_file.write_text(yaml.safe_dump(cal.to_dict(), sort_keys=False))
            self._publish(cal, attempt.applies_from)

    def calibrate(self, protocol: str, standing_duration: float = 0.0, motion_duration: float = 0.0,
                  segments: list[str] | None = None) -> tuple[bool, str, SessionCalibration | None]:
        """Run the calibration on the buffer now (the service body, callable in-process); the result
        is in force from ``apply_delay`` s after the newest sample used."""
        attempt = self.core.calibrate(protocol, standing_duration, motion_duration, segments)
        self._accept(attempt)
        return attempt.success, attempt.message, attempt.calibration

    def calibrate_at(self, stamp_ns: int, protocol: str, **options: object) -> None:
        """Calibrate on the window ending at the sample stamp ``stamp_ns`` (ns) as soon as every
        segment's data gets there (at once if it already has): replays and the offline analysis
        (:mod:`gait_biofeedback.analyze`) then calibrate on exactly the same samples. The outcome
        is in :attr:`last_attempt` (and published when successful)."""
        self.core.schedule(stamp_ns / 1_000_000_000, protocol, **options)
        for attempt in self.core.run_due():
            self._accept(attempt)

    def _on_calibrate(self, request: Calibrate.Request, response: Calibrate.Response) -> Calibrate.Response:
        success, message, cal = self.calibrate(request.protocol, request.standing_duration,
                                               request.motion_duration, list(request.segments))
        response.success, response.message = success, message
        if cal is not None:
            response.segments = calibration_to_msg(cal)
        (self.get_logger().info if success else self.get_logger().warning)(message)
        return response

    def _publish(self, cal: SessionCalibration, applies_from: float) -> None:
        self._pub.publish(calibration_array_msg(cal, applies_from))


def main(args: list[str] | None = None) -> int:
    """Console script."""
    from gait_biofeedback.nodes.common import run_nodes

    return run_nodes([CalibrationNode], args)


if __name__ == "__main__":
    import sys

    sys.exit(main())
