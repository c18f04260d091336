"""Node ``calibration``: the ``calibration/calibrate`` service (thesis ch. 3, ch. 8 step 2).

Keeps a rolling buffer (``buffer_s``, default 90 s) of every segment's ``<segment>/imu/data`` (stamp,
raw acc, bias-corrected gyro, orientation). A call looks back over it for the protocol just performed
(:func:`~gait_biofeedback.core.calibration_windows.find_standing_then_motion`: the last quiet standing
of ``standing_duration`` s followed by the motion) and returns at once; the executor never blocks.
On success: publishes the result latched on ``calibration/sensor_to_segment`` and writes
``<session_dir>/calibration.yaml``; on start it reloads that file and publishes it. A refused
calibration keeps the previous one in force and publishes nothing.

Parameters: ``segments`` (default all eight), ``buffer_s``, ``session_dir`` ("session"),
``default_standing_duration`` (3 s).
"""

from __future__ import annotations

from collections import deque
from pathlib import Path

import numpy as np
import yaml
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu

from gait_biofeedback.core.calibration import PROTOCOLS, SessionCalibration, calibrate_session
from gait_biofeedback.core.calibration_windows import find_standing_then_motion
from gait_biofeedback.core.segments import SEGMENTS, WORLD_FRAME, ImuSeries, orientation_topic, sensor_frame
from gait_biofeedback.nodes.common import LATCHED_QOS, RELIABLE_QOS, stamp_to_s
from gait_biofeedback_msgs.msg import SegmentCalibration, SegmentCalibrationArray
from gait_biofeedback_msgs.srv import Calibrate

CALIBRATION_TOPIC = "calibration/sensor_to_segment"
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
        self.buffers: dict[str, deque] = {s: deque() for s in self.segments}
        self.current: SessionCalibration | None = None
        for seg in self.segments:
            self.create_subscription(Imu, orientation_topic(seg), lambda m, s=seg: self._on_imu(s, m),
                                     RELIABLE_QOS)
        self._pub = self.create_publisher(SegmentCalibrationArray, CALIBRATION_TOPIC, LATCHED_QOS)
        self.create_service(Calibrate, CALIBRATE_SERVICE, self._on_calibrate)
        self._reload()

    @property
    def calibration_file(self) -> Path:
        return self.session_dir / CALIBRATION_FILE

    def _reload(self) -> None:
        if not self.calibration_file.exists():
            return
        try:
            self.current = SessionCalibration.from_dict(yaml.safe_load(self.calibration_file.read_text()))
        except (ValueError, KeyError, TypeError, yaml.YAMLError) as exc:
            self.get_logger().error(f"{self.calibration_file}: unreadable calibration ({exc}); "
                                    "run the calibration again")
            return
        self.get_logger().info(f"reloaded the calibration from {self.calibration_file}")
        self._publish(self.current)

    def _on_imu(self, segment: str, msg: Imu) -> None:
        t = stamp_to_s(msg.header.stamp)
        a, w, o = msg.linear_acceleration, msg.angular_velocity, msg.orientation
        buf = self.buffers[segment]
        if buf and t <= buf[-1][0]:
            if t < buf[-1][0] - 1.0:  # time went back (a bag restarted): start over
                buf.clear()
            else:
                return
        buf.append((t, a.x, a.y, a.z, w.x, w.y, w.z, o.w, o.x, o.y, o.z))
        while buf and buf[0][0] < t - self.buffer_s:
            buf.popleft()

    def _series(self, segments: list[str]) -> tuple[dict[str, ImuSeries], dict[str, np.ndarray]]:
        data, ori = {}, {}
        for seg in segments:
            if len(self.buffers[seg]) < 2:
                continue
            arr = np.array(self.buffers[seg], dtype=float)
            data[seg] = ImuSeries(seg, arr[:, 0], arr[:, 1:4], arr[:, 4:7])
            ori[seg] = arr[:, 7:11]
        return data, ori

    def calibrate(self, protocol: str, standing_duration: float = 0.0, motion_duration: float = 0.0,
                  segments: list[str] | None = None) -> tuple[bool, str, SessionCalibration | None]:
        """Run the calibration on the buffer (the service body, callable in-process)."""
        if protocol not in PROTOCOLS:
            return False, f"unknown protocol {protocol!r}: use one of {list(PROTOCOLS)}", None
        wanted = list(segments) if segments else self.segments
        bad = [s for s in wanted if s not in self.segments]
        if bad:
            return False, f"segments {bad} are not handled by this node ({self.segments})", None
        data, ori = self._series(wanted)
        silent = [s for s in wanted if s not in data]
        if silent:
            return False, (f"no data from {', '.join(silent)}: check these sensors and the orientation "
                           "filter; previous calibration stays in force"), None
        try:
            standing, motion = find_standing_then_motion(
                data, standing_duration or self.default_standing, motion_duration)
        except ValueError as exc:
            return False, f"{exc}; previous calibration stays in force", None
        cal = calibrate_session(data, standing, motion, protocol, orientations=ori)
        if cal.success:
            self.current = cal
            self.session_dir.mkdir(parents=True, exist_ok=True)
            self.calibration_file.write_text(yaml.safe_dump(cal.to_dict(), sort_keys=False))
            self._publish(cal)
        return cal.success, cal.message, cal

    def _on_calibrate(self, request: Calibrate.Request, response: Calibrate.Response) -> Calibrate.Response:
        success, message, cal = self.calibrate(request.protocol, request.standing_duration,
                                               request.motion_duration, list(request.segments))
        response.success, response.message = success, message
        if cal is not None:
            response.segments = calibration_to_msg(cal)
        (self.get_logger().info if success else self.get_logger().warning)(message)
        return response

    def _publish(self, cal: SessionCalibration) -> None:
        msg = SegmentCalibrationArray(protocol=cal.protocol, segments=calibration_to_msg(cal))
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = WORLD_FRAME
        self._pub.publish(msg)


def main(args: list[str] | None = None) -> int:
    """Console script."""
    from gait_biofeedback.nodes.common import run_nodes

    return run_nodes([CalibrationNode], args)


if __name__ == "__main__":
    import sys

    sys.exit(main())
