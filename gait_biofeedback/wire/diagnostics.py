"""``/diagnostics`` (diagnostic_msgs/DiagnosticArray): one status per node and stream."""

from __future__ import annotations

from collections.abc import Sequence

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from gait_biofeedback.core.orientation.stream import INFORMATION, SegmentOrientationTracker
from gait_biofeedback.core.segments import sensor_frame

OK, WARN, ERROR, STALE = (int.from_bytes(level, "little") for level in (
    DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR, DiagnosticStatus.STALE))


def status(name: str, level: int | bytes, message: str, hardware_id: str = "",
           values: dict | None = None) -> DiagnosticStatus:
    """One DiagnosticStatus with ``values`` rendered as strings (floats with 4 significant digits);
    ``level`` is DiagnosticStatus.OK/WARN/ERROR/STALE (bytes) or the same as an int."""
    if isinstance(level, int):
        level = bytes([level])
    out = DiagnosticStatus(name=name, level=level, message=message, hardware_id=hardware_id)
    for key, value in (values or {}).items():
        text = f"{value:.4g}" if isinstance(value, float) else str(value)
        out.values.append(KeyValue(key=str(key), value=text))
    return out


def array(stamp: Time, statuses) -> DiagnosticArray:
    """DiagnosticArray of ``statuses`` stamped ``stamp`` (the publishing node's clock)."""
    msg = DiagnosticArray()
    msg.header.stamp = stamp
    msg.status = list(statuses)
    return msg


def level_of(s: DiagnosticStatus) -> int:
    """A status' level as an int (rclpy gives it as bytes)."""
    return s.level[0] if isinstance(s.level, bytes) else int(s.level)


def no_data(silent_s: float | None, stale_after_s: float) -> tuple[int, str] | None:
    """The ``problem`` of :func:`orientation_status` for a stream silent ``silent_s`` s (None: no sample
    yet): the node's rule, and ``analyze``'s on the recording's time."""
    if silent_s is None:
        return WARN, "no data yet: is the sensor on and publishing?"
    if silent_s > stale_after_s:
        return ERROR, f"no data for {silent_s:.1f} s: check the sensor, its battery and the link"
    return None


def orientation_status(segment: str, tracker: SegmentOrientationTracker,
                       problem: tuple[int, str] | None = None, extra: Sequence[str] = (),
                       values: dict | None = None) -> DiagnosticStatus:
    """``orientation_filter: <segment>``, as the node and ``analyze`` publish it: ``problem`` (level,
    text) when the stream itself is missing (no data, stale: only the node knows), else the filter's
    state, with ``extra`` texts and the tracker's :meth:`~SegmentOrientationTracker.report` (what
    happened since its last status) appended (WARN; OK when they are all the kit's normal state,
    :data:`~gait_biofeedback.core.orientation.stream.INFORMATION`)."""
    conditions = tracker.report()
    info = {**tracker.diagnostics(), **(values or {})}
    if problem is not None:
        level, message = problem
    elif not info["initialized"]:
        level, message = OK, f"start-up: collecting {tracker.startup_s:g} s of quiet standing"
    else:
        texts = [*extra, *conditions]
        if info["mag_disturbed"]:
            texts.insert(0, "magnetic disturbance: heading from gyro only")
        if info["startup_quiet"] is False:
            texts.append("moved during start-up: gyro bias not removed")
        level = WARN if any(t not in INFORMATION for t in texts) else OK  # a 6D kit is not a fault
        message = "; ".join(texts) or "tracking"
    return status(f"orientation_filter: {segment}", level, message, sensor_frame(segment), info)
