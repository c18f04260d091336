"""``/diagnostics`` (diagnostic_msgs/DiagnosticArray): one status per node and stream."""

from __future__ import annotations

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

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
