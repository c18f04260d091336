"""Whether each sensor's stamps still line up with the other sensors' (EXT; the issue's "time jumps").

The joint-angle stream pairs the segments' samples by their stamps. A sensor whose clock steps (a driver
or sensor restart, a glitch) while its samples keep arriving goes on with stamps that are off the
others' by the step: every pairing of it is then with another instant of the other sensors. On the
simulated demo with the left thigh's stamps 1 s behind from 65 s, the left knee read up to 117° off for
the rest of the walk, unmarked, and was cued (a stamp 1 s ahead: 15-35° off after its re-acquisition).

So each sample's stamp is compared with when it was received (``received_ns``: the node's ROS clock
live, the recording's ``/clock`` in a replay at any speed, the log time offline): ``stamp - received``
is the sensor's clock offset plus its delay. A delay only lowers it, so the largest over the last
``WINDOW_S`` of samples is the segment's clock offset. A segment whose offset differs from the median of
the segments' by more than ``MISALIGNED_S`` for ``HOLD_S`` is misaligned: its samples are treated as
doubtful (their joints get no cues) until it lines up again. (Samples released together, the start-up's
or those held across a dropout, look off for a moment, until the others' come; the jump that made the
offset marks its own first seconds: the orientation filter re-acquires the attitude, and samples marked
so are not judged here.) A segment that is catching up is not judged either, and its offset is left out
of the median while it is: a sample that came in less than ``CATCH_UP_RATIO`` of its stamp step after
the one before (stamps in sequence) and raised the segment's offset starts it (a burst: the start-up's
samples released together, or a backlog of one topic drained by a busy node; on a loaded 2-core machine
the live graph flagged four sensors "off" by up to 0.6 s in its start-up release), and it lasts until
the offset has not risen for ``SETTLE_S``. A radio's packets are no burst: each one's samples arrive
together but leave the offset where the packet before left it. A clock that steps keeps its pace and is
judged at once. A segment silent for ``STALE_S`` no longer counts. With an even number
of segments half of which stepped, no side is the majority: both are marked. A whole recording replayed
again, or a replay at another speed, moves every segment's offset alike and is not a misalignment.
"""

from __future__ import annotations

from collections import deque
from statistics import median

from gait_biofeedback.core.stamps import NS_PER_S

WINDOW_S = 0.3  # s of a segment's samples whose largest offset is its clock offset
MISALIGNED_S = 0.1  # s off the other segments' median: 10 samples at 100 Hz, far above a link's jitter
STALE_S = 1.0  # s without a sample: the segment's offset no longer counts
HOLD_S = 0.05  # s (received) that the offset must last: samples released together line up within 20 ms
CATCH_UP_RATIO = 0.5  # a sample received this share of its stamp step after the one before, or sooner ...
MAX_SPACING_S = 0.1  # ... its stamp step (s) at most this (longer: a gap or a jump, not a burst) ...
RISE_S = 0.001  # ... that raised its segment's offset by more than this starts a catch-up ...
SETTLE_S = 0.1  # ... which ends once the offset has not risen for this long (received time)


def said(segment: str, off_s: float) -> str:
    """A misalignment in words, with what to do."""
    return (f"{segment}'s stamps are {off_s:+.2f} s off the other sensors' (its clock jumped, or its driver "
            "restarted): its joints are marked doubtful (shown, no cues) until they line up again; restart "
            "that sensor's driver")


class StampAlignment:
    """Clock offset of each segment against the others (module docstring). :attr:`misaligned`: segment
    → how far (s, + ahead) its stamps are off the others' now; :attr:`first` / :attr:`last`: segment →
    (stamp ns, s off) of its first / latest misaligned sample, for the record."""

    def __init__(self) -> None:
        self._window: dict[str, deque[tuple[int, int]]] = {}  # (received, offset), offsets decreasing
        self._clock: dict[str, int] = {}  # segment → its largest offset over the window, ns
        self._since: dict[str, int] = {}  # segment → when (received) it was first seen off, ns
        self._received: dict[str, int] = {}  # segment → its newest sample's received time, ns
        self._stamp: dict[str, int] = {}  # segment → its newest stamp, ns
        self._catching_up: dict[str, int] = {}  # segment catching up → when (received) its offset last rose
        self.misaligned: dict[str, float] = {}
        self.first: dict[str, tuple[int, float]] = {}
        self.last: dict[str, tuple[int, float]] = {}

    def add(self, segment: str, stamp_ns: int, received_ns: int) -> bool:
        """One sample; whether its segment is misaligned now."""
        window = self._window.setdefault(segment, deque())
        offset = stamp_ns - received_ns
        catching_up = self._is_catching_up(segment, stamp_ns, received_ns, offset)
        while window and window[-1][1] <= offset:  # a sliding maximum: the smaller ones never count again
            window.pop()
        window.append((received_ns, offset))
        while window[0][0] < received_ns - WINDOW_S * NS_PER_S:
            window.popleft()
        self._clock[segment] = window[0][1]
        self._received[segment] = received_ns
        if catching_up:
            return segment in self.misaligned
        recent = received_ns - STALE_S * NS_PER_S
        live = [c for seg, c in self._clock.items()
                if self._received[seg] >= recent and seg not in self._catching_up]
        if len(live) < 3:  # two segments cannot say which one is off
            return False
        off = (self._clock[segment] - median(live)) / NS_PER_S
        if abs(off) > MISALIGNED_S:
            since = self._since.setdefault(segment, received_ns)
            if received_ns - since < HOLD_S * NS_PER_S:
                return segment in self.misaligned
            self.misaligned[segment] = off
            self.first.setdefault(segment, (stamp_ns, off))
            self.last[segment] = (stamp_ns, off)
            return True
        self.misaligned.pop(segment, None)
        self._since.pop(segment, None)
        return False

    def _is_catching_up(self, segment: str, stamp_ns: int, received_ns: int, offset: int) -> bool:
        """Whether the segment is catching up on a burst now (module docstring)."""
        previous_stamp = self._stamp.get(segment)
        self._stamp[segment] = stamp_ns
        rose = segment in self._clock and offset > self._clock[segment] + RISE_S * NS_PER_S
        if previous_stamp is not None and rose:  # _received still holds the segment's previous sample's
            step = stamp_ns - previous_stamp
            burst = (0 < step <= MAX_SPACING_S * NS_PER_S
                     and received_ns - self._received[segment] < CATCH_UP_RATIO * step)
            if burst or segment in self._catching_up:
                self._catching_up[segment] = received_ns
                return True
        if segment in self._catching_up and received_ns - self._catching_up[segment] < SETTLE_S * NS_PER_S:
            return True
        self._catching_up.pop(segment, None)
        return False

    def misaligned_now(self, now_ns: int) -> dict[str, float]:
        """:attr:`misaligned` without the segments silent for ``STALE_S`` (a sensor that stopped is said
        as missing, not as off)."""
        return {seg: off for seg, off in self.misaligned.items()
                if self._received.get(seg, now_ns) >= now_ns - STALE_S * NS_PER_S}
