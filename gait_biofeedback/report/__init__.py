"""What a session produced: the summary figures of a recording (:mod:`~gait_biofeedback.report.session`)."""

from gait_biofeedback.report.session import SessionReport, format_report, session_report

__all__ = ["SessionReport", "format_report", "session_report"]
