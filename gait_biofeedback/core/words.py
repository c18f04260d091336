"""Counts in words for the messages and reports a clinician reads ("1 stride", "3 strides")."""

from __future__ import annotations


def plural(count: int, singular: str, many: str | None = None) -> str:
    """``count`` and the noun in its number: ``plural(1, "stride")`` → "1 stride", ``plural(3,
    "stride")`` → "3 strides" (``many`` for an irregular plural)."""
    return f"{count} {singular if count == 1 else many or singular + 's'}"
