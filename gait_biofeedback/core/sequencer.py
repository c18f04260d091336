"""Samples of one sensor stream put back in stamp order, and the stamps that cannot be trusted.

A body network delivers a sensor's samples late, twice, out of order, or with a glitched stamp.
:class:`StreamSequencer` sits in front of the core's sensor streams (orientation, activity):

- **reorder window**: a sample is held until one stamped ``window`` s later has arrived, then
  released in stamp order, so samples out of order by less than the window are re-sequenced. This
  adds ``window`` s of latency (30 ms by default: 3 samples at 100 Hz);
- **duplicates** (a stamp seen before) are dropped and counted;
- **late samples** (stamped before the last released one) are dropped and counted: they arrived
  after their turn;
- **a stamp that jumps** (by more than ``max_jump`` s, or 8 sample intervals of a slower stream) is
  held until the samples after it say what it was. The stream goes on where it was: one bad stamp
  (or a few), dropped and counted. The next ``confirm`` − 1 samples follow it: a real jump, released
  with :attr:`Released.gap_s` (ahead: the sensor was silent) or :attr:`Released.restart_s` (back: a
  recording replayed again, a driver or sensor restarted).

A stream that ends holds its last ``window`` s: :meth:`StreamSequencer.flush` releases them. Time is int ns
(``docs/conventions.md``). READING of issue 13 ("a single late or early stamp is dropped and counted;
a reset happens only on a real time jump"): a jump is real when ``confirm`` (3) samples in a row,
each within the jump threshold of the one before, are on its far side.
"""

from __future__ import annotations

import bisect
from collections import deque
from dataclasses import dataclass, field
from typing import Any, NamedTuple

from gait_biofeedback.core.stamps import NS_PER_S

DROPPED = ("duplicates", "late", "bad_stamps")
"""The counts of samples the sequencer drops."""

START_JUMP_S = 1.0
"""The jump threshold while the stream's interval is not known yet (its first 4 intervals)."""


class Released(NamedTuple):
    """A sample let through, in stamp order; ``gap_s`` / ``restart_s``: the first sample after a
    confirmed jump ahead / back of that many seconds (0 otherwise). (A named tuple: one is made per
    sample of every sensor, five times faster than a frozen dataclass.)"""

    stamp_ns: int
    payload: Any
    gap_s: float = 0.0
    restart_s: float = 0.0


@dataclass
class StreamSequencer:
    """Reorder window, duplicates, late samples and stamp jumps of one stream (module docstring)."""

    window: float = 0.03
    max_jump: float = 0.1
    confirm: int = 3
    counts: dict[str, int] = field(default_factory=lambda: {
        "duplicates": 0, "late": 0, "bad_stamps": 0, "gaps": 0, "restarts": 0})
    last_dropped: str = ""  # what the newest dropped sample was, in words

    def __post_init__(self) -> None:
        self._window_ns = round(self.window * NS_PER_S)
        self._max_jump_ns = round(self.max_jump * NS_PER_S)
        self._pending: list[tuple[int, int, Any, float, float]] = []  # stamp, arrival, payload, marks
        self._released_ns: int | None = None
        self._newest_ns: int | None = None
        self._jumped: list[tuple[int, Any]] = []
        self._intervals: deque[int] = deque(maxlen=16)
        self._jump_threshold: int | None = None  # _jump_ns, until the intervals change
        self._arrivals = 0

    def push(self, stamp_ns: int, payload: Any) -> list[Released]:
        """One arriving sample → the samples released now, in stamp order."""
        self._arrivals += 1
        if self._newest_ns is None:
            self._newest_ns = stamp_ns
        if self._jumped:
            return self._after_jump(stamp_ns, payload)
        if abs(stamp_ns - self._newest_ns) > self._jump_ns:
            self._jumped.append((stamp_ns, payload))
            return []
        return self._accept(stamp_ns, payload)

    def flush(self) -> list[Released]:
        """Release everything held in the window (the end of a recording, a stream that stopped);
        samples across an unconfirmed jump stay held."""
        out = [Released(s, p, g, r) for s, _, p, g, r in self._pending]
        if out:
            self._released_ns = out[-1].stamp_ns
        self._pending.clear()
        return out

    @property
    def dropped(self) -> int:
        """Samples dropped so far: duplicates, late ones, bad stamps."""
        return sum(self.counts[key] for key in DROPPED)

    def sync_drops(self, counts: dict[str, int]) -> int:
        """Copy the drop counts into a stream's ``counts``; how many samples were dropped since the
        last copy."""
        before = sum(counts.get(key, 0) for key in DROPPED)
        for key in DROPPED:
            counts[key] = self.counts[key]
        return self.dropped - before

    @property
    def holding(self) -> int:
        """Samples held (in the window, or across an unconfirmed jump)."""
        return len(self._pending) + len(self._jumped)

    @property
    def _jump_ns(self) -> int:
        """The jump threshold: ``max_jump`` s or 8 sample intervals once 4 intervals are known; before,
        ``START_JUMP_S`` (a slow stream's first intervals are not jumps, a glitched stamp of seconds is)."""
        if self._jump_threshold is None:
            if len(self._intervals) < 4:
                self._jump_threshold = max(self._max_jump_ns, round(START_JUMP_S * NS_PER_S))
            else:
                self._jump_threshold = max(self._max_jump_ns,
                                           8 * sorted(self._intervals)[len(self._intervals) // 2])
        return self._jump_threshold

    def _accept(self, stamp_ns: int, payload: Any, gap_s: float = 0.0,
                restart_s: float = 0.0) -> list[Released]:
        jump = bool(gap_s or restart_s)
        if not jump:
            if stamp_ns == self._released_ns or any(e[0] == stamp_ns for e in self._pending):
                self.counts["duplicates"] += 1
                self.last_dropped = "a sample stamped like one before it (sent twice)"
                return []
            if self._released_ns is not None and stamp_ns < self._released_ns:
                self.counts["late"] += 1
                late_ms = (self._released_ns - stamp_ns) / NS_PER_S * 1e3
                self.last_dropped = (f"a sample {late_ms:.0f} ms older than one already processed (later "
                                     f"than the {self.window * 1e3:g} ms reorder window)")
                return []
        out = self.flush() if jump else []
        if jump:
            self._released_ns = None
            self._newest_ns = stamp_ns
        else:
            self._newest_ns = max(self._newest_ns, stamp_ns)
        bisect.insort(self._pending, (stamp_ns, self._arrivals, payload, gap_s, restart_s))
        cut = self._newest_ns - self._window_ns
        while self._pending and self._pending[0][0] <= cut:
            s, _, p, g, r = self._pending.pop(0)
            if self._released_ns is not None and not (g or r):
                self._intervals.append(s - self._released_ns)
                self._jump_threshold = None
            out.append(Released(s, p, g, r))
            self._released_ns = s
        return out

    def _after_jump(self, stamp_ns: int, payload: Any) -> list[Released]:
        threshold = self._jump_ns
        first_ns, last_ns = self._jumped[0][0], self._jumped[-1][0]
        if abs(stamp_ns - self._newest_ns) <= threshold:  # the stream went on where it was
            dropped, self._jumped = len(self._jumped), []
            self.counts["bad_stamps"] += dropped
            off = (first_ns - self._newest_ns) / NS_PER_S
            self.last_dropped = (f"{dropped} sample(s) stamped {abs(off):.3f} s "
                                 f"{'ahead of' if off > 0 else 'behind'} the stream (a clock glitch)")
            return self._accept(stamp_ns, payload)
        if not 0 < stamp_ns - last_ns <= threshold:  # does not follow the jumped ones either
            self.counts["bad_stamps"] += len(self._jumped)
            self.last_dropped = "samples whose stamps jump around (a clock glitch)"
            self._jumped = [(stamp_ns, payload)]
            return []
        self._jumped.append((stamp_ns, payload))
        if len(self._jumped) < self.confirm:
            return []
        jumped, self._jumped = self._jumped, []
        step = (first_ns - self._newest_ns) / NS_PER_S
        self.counts["gaps" if step > 0 else "restarts"] += 1
        out = self._accept(*jumped[0], gap_s=max(step, 0.0), restart_s=max(-step, 0.0))
        for s, p in jumped[1:]:
            out += self._accept(s, p)
        return out
