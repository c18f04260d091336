"""Node ``calibration``: the ``calibration/calibrate`` service (thesis ch. 3, ch. 8 step 2).

Keeps a rolling buffer (``buffer_s``, default 90 s) of every segment's ``<segment>/imu/data`` (stamp,
raw acc, bias-corrected gyro, orientation) in a core
:class:`~gait_biofeedback.core.calibration.stream.CalibrationBuffer`. A call looks back over it for
the protocol just performed (:func:`~gait_biofeedback.core.calibration.windows.find_standing_then_motion`:
the last quiet standing of ``standing_duration`` s followed by the motion) and returns at once; the
executor never blocks. :meth:`CalibrationNode.calibrate_at` instead calibrates on the window ending at
a given sample stamp once the data gets there (replays; the offline ``analyze`` does the same).
On success: publishes the result latched on ``calibration/sensor_to_segment`` (with its source:
computed in this session, and when) and writes ``<session_dir>/calibration.yaml`` atomically. At start
it puts that file in force only when asked (``reload_calibration``: a file found in a shared folder may
belong to another patient or dataset), after checking it (:mod:`~gait_biofeedback.core.calibration.file`:
complete, unedited, every value valid); otherwise it says the file is there and not used;
``calibration_file`` names a file to put in force instead (an unusable one is refused at start with the
reason). While the patient performs the protocol, a status ``calibration: progress`` on
``/diagnostics`` every ``PROGRESS_PERIOD_S`` s says how far it has got (seconds of quiet standing,
then each leg's movement cycles: :mod:`~gait_biofeedback.core.calibration.progress`; its key-values
are what the dashboard shows, and the recorder keeps them with the session). A file without
entries for some of ``segments`` is put in force for the others, those named in
a WARN status ``calibration`` on ``/diagnostics`` (every second; OK once a calibration computed in this
session replaces it), in the message's source and as invalid entries (the dashboard counts them).
The message's header.stamp is the sample stamp from which the calibration is in force: ``apply_delay_s``
s after the newest sample used (0 for a reloaded file: at once), so joint_angles and gait_events
switch at the same sample whenever the message reaches them within that delay. A refused calibration
keeps the previous one in force and publishes nothing.

Parameters: :class:`~gait_biofeedback.core.calibration.stream.CalibrationParams`.
"""

from __future__ import annotations

import dataclasses
import time
from collections import deque
from pathlib import Path

from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.context import Context

from gait_biofeedback.core.calibration.file import (
    LoadedCalibration,
    load_calibration_file,
    missing_text,
    placeholder,
)
from gait_biofeedback.core.calibration.progress import CalibrationProgress
from gait_biofeedback.core.calibration.sensor_to_segment import SessionCalibration
from gait_biofeedback.core.calibration.stream import (
    CALIBRATION_FILE,
    CalibrationAttempt,
    CalibrationBuffer,
    CalibrationParams,
    write_calibration_file,
)
from gait_biofeedback.nodes.common import GuardedNode, publisher, subscribe
from gait_biofeedback.nodes.parameters import declare_parameters, node_overrides
from gait_biofeedback.wire import diagnostics, topics
from gait_biofeedback.wire.calibration import calibration_msg, segment_messages
from gait_biofeedback.wire.cdr import decode_imu
from gait_biofeedback.wire.imu import has_heading, orientation_sample
from gait_biofeedback_msgs.srv import Calibrate

PROGRESS_PERIOD_S = 0.5
PROGRESS_STATUS = "calibration: progress"


class CalibrationNode(GuardedNode):
    """Sensor-to-segment calibration service (see module docstring)."""

    NODE_NAME = "calibration"

    def __init__(self, context: Context | None = None, params: CalibrationParams | None = None,
                 **overrides: object) -> None:
        super().__init__(self.NODE_NAME, context=context, parameter_overrides=node_overrides(overrides))
        self.params: CalibrationParams = declare_parameters(self, CalibrationParams, params)
        self.segments = list(self.params.segments)
        self.session_dir = Path(self.params.session_dir or "session")
        self.core = CalibrationBuffer(self.params)
        self.progress = CalibrationProgress(self.segments, self.params.default_standing_duration_s)
        self.current: SessionCalibration | None = None
        self.last_attempt: CalibrationAttempt | None = None
        self.attempts: list[CalibrationAttempt] = []  # every request's outcome, in order
        self.saved_file: Path | None = None  # where the last result in force was saved
        self.file_status: DiagnosticStatus | None = None  # /diagnostics 'calibration', once there is news
        for seg in self.segments:
            subscribe(self, topics.orientation(seg), lambda m, s=seg: self._on_imu(s, m), raw=True)
        self._pub = publisher(self, topics.CALIBRATION)
        self.create_service(Calibrate, topics.CALIBRATE_SERVICE, self._on_calibrate)
        self.create_timer(PROGRESS_PERIOD_S, self._publish_progress)
        self._reload()

    @property
    def buffers(self) -> dict[str, deque]:
        """The rolling buffer per segment (held by the core :class:`CalibrationBuffer`)."""
        return self.core.buffers

    @property
    def calibration_file(self) -> Path:
        return self.session_dir / CALIBRATION_FILE

    def _reload(self) -> None:
        if self.params.calibration_file:
            path = Path(self.params.calibration_file).absolute()
            if not path.is_file():
                raise ValueError(f"calibration: parameter 'calibration_file': {path} not found")
            self._put_in_force(load_calibration_file(path, self.segments), path)  # ValueError says why
            return
        path = self.calibration_file.absolute()
        if not path.exists():
            return
        if not self.params.reload_calibration:
            self.get_logger().info(f"an earlier calibration is saved in {path}; not used (set "
                                   "reload_calibration:=true to put it in force): calibrate this session")
            return
        try:
            loaded = load_calibration_file(path, self.segments)
        except (ValueError, OSError) as exc:
            self.get_logger().error(f"calibration not reloaded: {exc}")
            return
        self._put_in_force(loaded, path)

    def _put_in_force(self, loaded: LoadedCalibration, path: Path) -> None:
        """Put a checked file in force; the session's segments it lacks as invalid entries, said."""
        for note in loaded.notes:
            self.get_logger().info(note)
        calibration = loaded.calibration
        source = f"from {path} (saved {loaded.saved_at or 'at an unknown time'})"
        if loaded.missing:
            warning = missing_text(path, loaded.missing)
            source += f"; no entry for {', '.join(loaded.missing)}: not calibrated"
            absent = {s: placeholder(s, path) for s in loaded.missing}
            calibration = dataclasses.replace(calibration, segments={**calibration.segments, **absent})
            self.get_logger().warning(f"calibration in force {source}; calibrate again to calibrate every "
                                      "segment")
            self._set_file_status(diagnostics.WARN, warning,
                                  {"file": str(path), "missing": ", ".join(loaded.missing)})
        else:
            self.get_logger().info(f"calibration in force {source}")
        self.current = calibration
        self._pub.publish(calibration_msg(calibration, 0, source, path.stat().st_mtime_ns))

    def _set_file_status(self, level: int, message: str, values: dict[str, str]) -> None:
        """The 'calibration' status, published now and every second from now on."""
        first = self.file_status is None
        self.file_status = diagnostics.status(self.NODE_NAME, level, message, values=values)
        if first:
            self.create_timer(1.0, self._publish_file_status)
        self._publish_file_status()

    def _publish_file_status(self) -> None:
        if self.file_status is not None:
            self.publish_diagnostics([self.file_status])

    def _publish_progress(self) -> None:
        if not any(self.core.buffers.values()):
            return  # no sensor yet
        now = self.progress.progress()
        self.publish_diagnostics([diagnostics.status(PROGRESS_STATUS, diagnostics.OK, now.text(),
                                                     values=now.values())])

    def _on_imu(self, segment: str, data: bytes) -> None:
        imu = decode_imu(data)
        stamp_ns, acc, gyr, q = orientation_sample(imu)
        self.core.add(segment, stamp_ns, acc, gyr, q, heading=has_heading(imu))
        self.progress.add(segment, stamp_ns, acc, gyr)
        if self.core.scheduled:
            for attempt in self.core.run_due():
                self._accept(attempt)
                text = (f"scheduled calibration ({attempt.protocol}, data up to "
                        f"{(attempt.until_ns or 0) * 1e-9:.3f} s): {attempt.message}")
                if attempt.success:
                    self.get_logger().info(text)
                else:
                    self.get_logger().warning(text)

    def _accept(self, attempt: CalibrationAttempt) -> None:
        """Keep, save and publish a successful result (a refused one changes nothing)."""
        self.last_attempt = attempt
        self.attempts.append(attempt)
        cal = attempt.calibration
        if attempt.success and cal is not None and attempt.applies_from_ns is not None:
            self.current = cal
            now = time.time_ns()
            when = time.strftime("%H:%M:%S", time.localtime(now / 1e9))
            until = "" if attempt.until_ns is None else f", data up to {attempt.until_ns / 1e9:.1f} s"
            self._pub.publish(calibration_msg(cal, attempt.applies_from_ns,
                                              f"computed in this session at {when}{until}", now))
            if self.file_status is not None:  # the file's warning no longer holds
                self._set_file_status(diagnostics.OK, f"calibration computed in this session at {when} in "
                                      "force", {})
            try:
                write_calibration_file(self.calibration_file, cal, time.strftime("%Y-%m-%dT%H:%M:%S%z"))
                self.saved_file = self.calibration_file.absolute()
            except (OSError, ValueError) as exc:
                self.get_logger().error(f"calibration in force but not saved: {exc}")

    def calibrate(self, protocol: str, standing_duration: float = 0.0, motion_duration: float = 0.0,
                  segments: list[str] | None = None) -> tuple[bool, str, SessionCalibration | None]:
        """Run the calibration on the buffer now (the service body, callable in-process); the result
        is in force from ``apply_delay_s`` s after the newest sample used. The protocol the movement
        looked like is in :attr:`last_attempt`."""
        attempt = self.core.calibrate(protocol, standing_duration, motion_duration, segments)
        self._accept(attempt)
        return attempt.success, attempt.message, attempt.calibration

    def calibrate_at(self, stamp_ns: int, protocol: str, **options: object) -> None:
        """Calibrate on the window ending at the sample stamp ``stamp_ns`` as soon as every segment's
        data gets there (at once if it already has): replays and the offline analysis
        (:mod:`gait_biofeedback.analyze`) then calibrate on exactly the same samples. The outcome
        is in :attr:`last_attempt` (and published when successful)."""
        self.core.schedule(stamp_ns, protocol, **options)
        for attempt in self.core.run_due():
            self._accept(attempt)

    def _on_calibrate(self, request: Calibrate.Request, response: Calibrate.Response) -> Calibrate.Response:
        success, message, cal = self.calibrate(request.protocol, request.standing_duration,
                                               request.motion_duration, list(request.segments))
        response.success, response.message = success, message
        response.looks_like = (self.last_attempt.looks_like or "") if self.last_attempt is not None else ""
        if cal is not None:
            response.segments = segment_messages(cal)
        if success:
            self.get_logger().info(message)
        else:
            self.get_logger().warning(message)
        return response


def main(args: list[str] | None = None) -> int:
    """Console script."""
    from gait_biofeedback.nodes.common import run_nodes

    return run_nodes([CalibrationNode], args)


if __name__ == "__main__":
    import sys

    sys.exit(main())
