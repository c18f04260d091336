"""The commands a dashboard page may send, checked field by field before anything runs.

A command is a JSON object ``{"action": ..., <fields>}``. Each action names its fields, their types and
allowed values; a field that is unknown, of the wrong type or out of range refuses the whole command
with a message saying what is allowed (:class:`CommandError`), so a malformed or hostile message can
only ever produce a refusal reply.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from gait_biofeedback.core.biofeedback.evaluator import FEEDBACK_JOINTS, FEEDBACK_SIDES
from gait_biofeedback.core.calibration.sensor_to_segment import REQUESTS


class CommandError(ValueError):
    """A command refused before it ran; the message is the reply to the page."""


@dataclass(frozen=True)
class Field:
    """One command field: ``kind`` "str", "number" or "bool"; ``choices`` or ``low``..``high``."""

    kind: str
    choices: tuple[str, ...] | None = None
    low: float | None = None
    high: float | None = None

    def check(self, action: str, name: str, value: Any) -> Any:
        if self.kind == "bool":
            ok = isinstance(value, bool)
        elif self.kind == "number":
            ok = (isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
                  and self.low <= value <= self.high)
        else:
            ok = isinstance(value, str) and (self.choices is None or value in self.choices)
        if not ok:
            raise CommandError(f"{action}: {name}={shown(value)} refused; {self.allowed()}")
        return float(value) if self.kind == "number" else value

    def allowed(self) -> str:
        if self.kind == "bool":
            return "expected true or false"
        if self.kind == "number":
            return f"expected a number from {self.low:g} to {self.high:g}"
        return f"expected one of {list(self.choices or ())}"


COMMANDS: dict[str, dict[str, Field]] = {
    "calibrate": {"protocol": Field("str", REQUESTS),
                  "standing_duration": Field("number", low=0.0, high=60.0),
                  "motion_duration": Field("number", low=0.0, high=600.0)},
    "record_start": {},
    "record_stop": {},
    "feedback": {"side": Field("str", FEEDBACK_SIDES), "joint": Field("str", FEEDBACK_JOINTS)},
    "mute": {"muted": Field("bool")},
}


SHOWN_CHARS = 40
"""A page's value is echoed at most this long (a 60 kB action name was sent back whole)."""


def shown(value: Any) -> str:
    """``repr(value)`` cut to :data:`SHOWN_CHARS`."""
    text = repr(value)
    return text if len(text) <= SHOWN_CHARS else text[:SHOWN_CHARS] + "…"


def parse_command(message: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    """(action, checked fields) of a page message; CommandError for anything not allowed."""
    action = message.get("action")
    if not isinstance(action, str) or action not in COMMANDS:
        raise CommandError(f"unknown action {shown(action)}; actions: {', '.join(COMMANDS)}")
    fields = COMMANDS[action]
    unknown = sorted(shown(k) for k in message if k != "action" and k not in fields)
    if unknown:
        raise CommandError(f"{action}: unknown field(s) {', '.join(unknown[:5])}; fields: "
                           f"{list(fields) or 'none'}")
    return action, {name: fields[name].check(action, name, value)
                    for name, value in message.items() if name != "action"}
