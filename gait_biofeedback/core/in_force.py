"""Values waiting for the sample stamp from which they are in force.

A calibration message names the sample stamp from which it holds (``calibration_windows``: the end
of its window + ``apply_delay_s``), so every consumer, live or offline, switches at the same sample
whenever the message arrived. The streams that consume one (joint angles, gait events, the activity
monitor's trunk axis) keep what has arrived early in an :class:`InForceQueue` and take it when their
samples reach its stamp.
"""

from __future__ import annotations

import bisect
from typing import Generic, TypeVar

T = TypeVar("T")


class InForceQueue(Generic[T]):
    """Values ordered by the stamp from which they are in force (equal stamps: arrival order)."""

    def __init__(self) -> None:
        self._items: list[tuple[float, T]] = []

    def __bool__(self) -> bool:
        return bool(self._items)

    def put(self, from_stamp: float, value: T) -> None:
        bisect.insort(self._items, (from_stamp, value), key=lambda item: item[0])

    def due(self, stamp: float) -> list[T]:
        """Remove and return, oldest first, the values in force at ``stamp``."""
        n = bisect.bisect_right(self._items, stamp, key=lambda item: item[0])
        out = [value for _, value in self._items[:n]]
        del self._items[:n]
        return out

    def first(self) -> T | None:
        """The value that comes into force next, or None."""
        return self._items[0][1] if self._items else None

    def clear(self) -> None:
        self._items.clear()
