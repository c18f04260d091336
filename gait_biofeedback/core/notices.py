"""The one channel by which a core stream tells what a clinician or operator should know.

Every stream owns a :class:`Notices`; it says things as it processes samples (``say``), and whoever
drives it (a node, the offline analysis) takes them (``pop``) after each call: a node logs them (one
call site per severity, as rclpy requires) and the offline path collects them into its result.
"""

from __future__ import annotations

from dataclasses import dataclass

LEVELS = ("info", "warn", "error")


@dataclass(frozen=True)
class Notice:
    """One thing said: ``level`` one of :data:`LEVELS`, ``text`` a sentence that names the source."""

    level: str
    text: str


class Notices:
    """Notices said since the last :meth:`pop`, oldest first."""

    def __init__(self) -> None:
        self._items: list[Notice] = []

    def say(self, level: str, text: str) -> None:
        if level not in LEVELS:
            raise ValueError(f"notice level must be one of {LEVELS}, got {level!r}")
        self._items.append(Notice(level, text))

    def __bool__(self) -> bool:
        return bool(self._items)

    def pop(self) -> list[Notice]:
        """Everything said since the last call (and forget it)."""
        out, self._items = self._items, []
        return out
