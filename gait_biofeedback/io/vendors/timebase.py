"""Sequence numbers for devices that send a timestamp but no sample counter (x-IMU3, NGIMU).

The driver core counts loss and duplicates by sequence number. A device without a counter gets one
from its own clock: the nominal period is learnt as the median interval of its first
:data:`LEARN_SAMPLES` samples (device time, so link jitter does not enter), and each later sample's
number is the newest sample's plus its device-time distance in periods, rounded. Counting from the
newest sample rather than the first keeps a period learnt slightly off (a clock calibrated by the
vendor to ppm, a rate not an integer number of µs) from accumulating into a wrong count.
"""

from __future__ import annotations

from collections.abc import Callable
from itertools import pairwise

LEARN_SAMPLES = 8
SEQUENCE_MODULO = 1 << 32
REANCHOR_STEPS = 1000
"""Periods back in device time beyond which a sample is taken as a restarted clock (numbering goes
on from it) rather than one reordered on the way."""


class SequenceFromTime:
    """Device time (µs) → sequence number, for one device (module docstring). :meth:`push` holds
    the first samples until the period is learnt and then releases them all, numbered."""

    def __init__(self) -> None:
        self.period_us: float | None = None
        self._held: list[tuple[int, object]] = []
        self._newest: tuple[int, int] | None = None  # (device µs, sequence) of the newest sample

    def push(self, device_us: int, item: object, make: Callable[[int, object], object]) -> list[object]:
        """One sample taken at ``device_us`` → what is released now, each ``make(sequence, item)``."""
        if self.period_us is None:
            self._held.append((device_us, item))
            times = sorted({t for t, _ in self._held})
            steps = sorted(b - a for a, b in pairwise(times))
            if len(self._held) < LEARN_SAMPLES or not steps:
                if len(self._held) > 4 * LEARN_SAMPLES:  # one timestamp again and again: no rate
                    self._held = self._held[-LEARN_SAMPLES:]
                return []
            self.period_us = float(steps[len(steps) // 2])
            held, self._held = sorted(self._held, key=lambda h: h[0]), []
            return [make(self._number(t), i) for t, i in held]
        return [make(self._number(device_us), item)]

    def _number(self, device_us: int) -> int:
        if self._newest is None:
            self._newest = (device_us, 0)
            return 0
        t, seq = self._newest
        steps = round((device_us - t) / self.period_us)
        if steps > 0 or steps < -REANCHOR_STEPS:  # newer, or the clock went far back (a reboot)
            self._newest = (device_us, seq + steps)
        return (seq + steps) % SEQUENCE_MODULO

    def reset(self) -> None:
        """Start again (the connection to the device was opened anew)."""
        self.__init__()
